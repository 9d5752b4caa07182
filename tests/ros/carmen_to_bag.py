#!/usr/bin/env python3
"""Converts a CARMEN laser log (FLASER lines, plain or gzip) to a ROS 1 bag for the bridge test.

    carmen_to_bag.py LOG OUT.bag [--skip-tf-every N] [--manifest OUT.json]

What goes into the bag, as a robot's driver and localiser would publish it:
  /scan       sensor_msgs/LaserScan, frame `laser`, one per FLASER line, stamped with the line's ipc_timestamp
  /tf         tf2_msgs/TFMessage: map -> base_link (the log's corrected robot pose) at each scan's stamp,
              except for every N-th scan (N = --skip-tf-every; scans N-1, 2N-1, ... counted from 0), which the
              bridge must then be unable to place
  /tf_static  base_link -> laser (the log's robot_frontlaser_offset ahead along x), latched

The log's beams follow the project's CARMEN reader (logs/carmen_log_reader.h): n readings over a 180°
fan from -90° (even n: steps of pi/n; odd n: pi/(n - 1)); FLASER gives no maximum range, so range_max is 50 m
(the reader's default: the 81.83 m "no return" codes of the Intel log are beyond it) and range_min 0.02 m.

Stamps: real logs' ipc timestamps are not monotonic (the Intel excerpt has one that goes back 0.11 s) and an
excerpt cut from two places has a 13-minute hole; a step that is not in (0, 10] s becomes 1 s, so the bag plays
in order and without a pause. The manifest (JSON) lists every scan: its stamp, whether its tf was left out, the
laser pose in the map, and the nearest tf stamp, for the test to check against.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import sys

import rosbag
import rospy
from geometry_msgs.msg import TransformStamped
from sensor_msgs.msg import LaserScan
from tf2_msgs.msg import TFMessage

RANGE_MAX_M = 50.0
RANGE_MIN_M = 0.02
MAX_STEP_S = 10.0


def read_carmen(path: str) -> tuple[list[dict], float]:
    """FLASER scans in file order ({ranges, x, y, theta, t}) and the front laser's offset [m]."""
    with open(path, "rb") as f:
        raw = f.read()
    text = gzip.decompress(raw).decode() if raw[:2] == b"\x1f\x8b" else raw.decode()
    scans, offset = [], 0.0
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split()
        if len(fields) >= 3 and fields[0] == "PARAM" and fields[1] == "robot_frontlaser_offset":
            offset = float(fields[2])
        elif fields and fields[0] == "FLASER":
            n = int(fields[1])
            if len(fields) != n + 11:
                raise ValueError(f"{path}:{number}: FLASER with {n} readings has {len(fields)} fields")
            ranges = [float(v) for v in fields[2: 2 + n]]
            x, y, theta = (float(v) for v in fields[2 + n: 5 + n])
            scans.append({"line": number, "ranges": ranges, "x": x, "y": y, "theta": theta,
                          "t": float(fields[8 + n])})
    return scans, offset


def monotonic_stamps(times: list[float]) -> list[float]:
    stamps = []
    for i, t in enumerate(times):
        if i == 0:
            stamps.append(t)
            continue
        step = t - times[i - 1]
        stamps.append(stamps[-1] + (step if 0.0 < step <= MAX_STEP_S else 1.0))
    return stamps


def transform(parent: str, child: str, stamp: rospy.Time, x: float, y: float, theta: float) -> TransformStamped:
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = parent
    t.child_frame_id = child
    t.transform.translation.x = x
    t.transform.translation.y = y
    t.transform.rotation.z = math.sin(theta / 2.0)
    t.transform.rotation.w = math.cos(theta / 2.0)
    return t


def convert(log: str, out: str, skip_every: int) -> dict:
    scans, offset = read_carmen(log)
    if not scans:
        raise ValueError(f"{log}: no FLASER line")
    stamps = monotonic_stamps([s["t"] for s in scans])
    tf_stamps = [st for i, st in enumerate(stamps) if not (skip_every and i % skip_every == skip_every - 1)]
    manifest = {"log": log, "frontlaser_offset": offset, "skip_tf_every": skip_every, "scans": []}
    with rosbag.Bag(out, "w") as bag:
        first = rospy.Time.from_sec(stamps[0])
        static = TFMessage(transforms=[transform("base_link", "laser", first, offset, 0.0, 0.0)])
        bag.write("/tf_static", static, first, connection_header={
            "latching": "1", "callerid": "/carmen_to_bag", "topic": "/tf_static", "type": TFMessage._type,
            "md5sum": TFMessage._md5sum, "message_definition": TFMessage._full_text})
        for i, (scan, st) in enumerate(zip(scans, stamps)):
            stamp = rospy.Time.from_sec(st)
            n = len(scan["ranges"])
            increment = math.pi / n if n % 2 == 0 else math.pi / (n - 1)
            msg = LaserScan(angle_min=-math.pi / 2, angle_increment=increment,
                            angle_max=-math.pi / 2 + (n - 1) * increment, range_min=RANGE_MIN_M,
                            range_max=RANGE_MAX_M, ranges=scan["ranges"])
            msg.header.seq = i
            msg.header.stamp = stamp
            msg.header.frame_id = "laser"
            skipped = bool(skip_every) and i % skip_every == skip_every - 1
            if not skipped:
                bag.write("/tf", TFMessage(transforms=[
                    transform("map", "base_link", stamp, scan["x"], scan["y"], scan["theta"])]), stamp)
            bag.write("/scan", msg, stamp)
            nearest_tf = min(abs(t - st) for t in tf_stamps) if tf_stamps else math.inf
            manifest["scans"].append({
                "index": i, "line": scan["line"], "stamp": st, "tf_left_out": skipped, "nearest_tf_s": nearest_tf,
                # Where the laser is in the map: offset metres ahead of the robot along its heading.
                "laser_pose": [scan["x"] + offset * math.cos(scan["theta"]),
                               scan["y"] + offset * math.sin(scan["theta"]), scan["theta"]]})
    manifest["total"] = len(scans)
    manifest["tf_left_out"] = sum(1 for s in manifest["scans"] if s["tf_left_out"])
    manifest["duration_s"] = stamps[-1] - stamps[0]
    return manifest


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("log", help="CARMEN log (.log or .log.gz)")
    parser.add_argument("bag", help="bag to write")
    parser.add_argument("--skip-tf-every", type=int, default=0, metavar="N",
                        help="leave out the tf of every N-th scan (0: none)")
    parser.add_argument("--manifest", help="write the scans' list (JSON) here")
    args = parser.parse_args()
    manifest = convert(args.log, args.bag, args.skip_tf_every)
    if args.manifest:
        with open(args.manifest, "w") as f:
            json.dump(manifest, f, indent=1)
    print(f"{args.bag}: {manifest['total']} scans over {manifest['duration_s']:.1f} s, "
          f"tf left out for {manifest['tf_left_out']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
