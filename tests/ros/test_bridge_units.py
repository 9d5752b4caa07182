#!/usr/bin/python3
"""Unit tests of the ROS bridge's parts that need no ROS master (clients/ros/wm_ros_bridge.py): the grid value
conversion, the planar pose of a laser (upright and upside down) and the scan body, and the scan sender's
retries, idempotency keys, refusals and overflow against a local HTTP server that plays wmd's answers.
Exits 77 (CTest's SKIP_RETURN_CODE) when ROS is not installed."""

from __future__ import annotations

import http.server
import json
import math
import socket
import sys
import threading
import time
import unittest
from pathlib import Path

SKIP = 77
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "clients/ros"))
try:
    import rospy
    from geometry_msgs.msg import Quaternion, Vector3
    from sensor_msgs.msg import LaserScan
except ImportError as error:
    print(f"SKIP: ROS 1 is not installed ({error} under {sys.executable}); scripts/setup.sh ros installs it",
          flush=True)
    sys.exit(SKIP)
import wm_ros_bridge as bridge  # noqa: E402  (after the check: without ROS this import fails)

SETTINGS = {option.name: option.default for option in bridge.OPTIONS}


def quaternion(roll: float, yaw: float) -> Quaternion:
    """Rotation about z by yaw after a rotation about x by roll (q_yaw * q_roll)."""
    cr, sr, cy, sy = math.cos(roll / 2), math.sin(roll / 2), math.cos(yaw / 2), math.sin(yaw / 2)
    return Quaternion(x=cy * sr, y=sy * sr, z=sy * cr, w=cy * cr)


def rotate(q: Quaternion, v: tuple[float, float, float]) -> tuple[float, float, float]:
    x, y, z, w = q.x, q.y, q.z, q.w
    m = ((1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
         (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
         (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)))
    return tuple(sum(m[r][c] * v[c] for c in range(3)) for r in range(3))


def make_scan(ranges: list[float]) -> LaserScan:
    scan = LaserScan(angle_min=-1.2, angle_increment=0.3, range_min=0.05, range_max=8.0, ranges=ranges)
    scan.angle_max = scan.angle_min + (len(ranges) - 1) * scan.angle_increment
    scan.header.stamp = rospy.Time(12, 500000000)
    scan.header.frame_id = "laser"
    return scan


class ConversionTest(unittest.TestCase):
    def test_occupancy_values_round_half_up_and_unknown(self):
        self.assertEqual(bridge.occupancy_values([None, 0.0, 0.004, 0.125, 0.5, 0.994, 0.996, 1.0]).tolist(),
                         [-1, 0, 0, 13, 50, 99, 100, 100])

    def test_upright_laser(self):
        x, y, theta, mirrored = bridge.planar_pose(Vector3(x=1.5, y=-2.0, z=0.3), quaternion(0.0, 0.7))
        self.assertEqual((x, y, mirrored), (1.5, -2.0, False))
        self.assertAlmostEqual(theta, 0.7, places=12)

    def test_upside_down_laser_beams_point_where_the_robot_sees(self):
        ranges = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 7.5, 7.9]
        scan = make_scan(ranges)
        for yaw in (0.0, 0.7, -2.5):
            q = quaternion(math.pi, yaw)
            pose = bridge.planar_pose(Vector3(), q)
            self.assertTrue(pose[3])
            body = bridge.scan_body(scan, pose, SETTINGS)
            # Where each beam of the body points in the map, and how far it reached ...
            sent = {}
            for j, r in enumerate(body["ranges"]):
                heading = body["pose"]["theta"] + body["angle_min"] + j * body["angle_increment"]
                sent[round(math.remainder(heading, math.tau), 9)] = r
            # ... equals where the laser's beams point when rotated by the transform.
            for i, r in enumerate(ranges):
                a = scan.angle_min + i * scan.angle_increment
                d = rotate(q, (math.cos(a), math.sin(a), 0.0))
                self.assertAlmostEqual(d[2], 0.0, places=9)
                self.assertEqual(sent[round(math.atan2(d[1], d[0]), 9)], r)

    def test_scan_body(self):
        scan = make_scan([1.0, math.nan, math.inf, -math.inf, 2.5])
        body = bridge.scan_body(scan, (1.0, 2.0, 0.1, False), dict(SETTINGS, observer="r1", sigma_range=0.02))
        self.assertEqual(body, {"sensor": "laser", "observer": "r1", "stamp": 12.5,
                                "pose": {"x": 1.0, "y": 2.0, "theta": 0.1}, "angle_min": scan.angle_min,
                                "angle_increment": scan.angle_increment, "ranges": [1.0, None, None, None, 2.5],
                                "range_min": scan.range_min, "range_max": 8.0, "sigma_range": 0.02})
        json.dumps(body, allow_nan=False)
        body = bridge.scan_body(scan, (1.0, 2.0, 0.1, False), dict(SETTINGS, inf_is_valid=True))
        self.assertEqual(body["ranges"], [1.0, None, 8.0, None, 2.5])  # +inf clears up to range_max

    def test_push_bounded_keeps_the_head(self):
        import collections
        queue = collections.deque()
        dropped = [bridge.push_bounded(queue, i, 3) for i in range(6)]
        self.assertEqual((list(queue), dropped), ([0, 4, 5], [False, False, False, True, True, True]))
        queue = collections.deque()
        dropped = [bridge.push_bounded(queue, i, 1) for i in range(3)]
        self.assertEqual((list(queue), dropped), ([0], [False, True, True]))

    def test_the_old_name_source_still_names_the_observer(self):
        settings = dict(SETTINGS)
        self.assertEqual(settings["observer"], "ros-robot")
        cli = bridge.parse_command_line(["--source", "r7"])
        self.assertEqual((cli.source, cli.observer), ("r7", None))
        both = bridge.parse_command_line(["--source", "r7", "--observer", "r8"])
        self.assertEqual((both.source, both.observer), ("r7", "r8"))

    def test_map_paths(self):
        self.assertEqual(bridge.map_path("", "/api/v1/scans"), "/api/v1/scans")
        self.assertEqual(bridge.map_path("floor-2", "/api/v1/scans"), "/api/v1/maps/floor-2/scans")
        self.assertEqual(bridge.map_path("f2", "/api/v1/grid?layer=bayes&format=json"),
                         "/api/v1/maps/f2/grid?layer=bayes&format=json")
        self.assertEqual(bridge.map_path("f2", "/other"), "/other")

    def test_map_ids_follow_wmds_rule(self):
        for good in ("a", "floor-2", "0_x", "z" * 32):
            self.assertTrue(bridge.MAP_ID.fullmatch(good), good)
        for bad in ("", "-a", "_a", "A", "a/b", "a b", "z" * 33, "a.b", "..", "é"):
            self.assertFalse(bridge.MAP_ID.fullmatch(bad), bad)

    def test_a_bad_map_is_refused_at_start(self):
        original = rospy.get_param
        rospy.get_param = lambda name, default=None: default  # no ROS master: the defaults
        try:
            self.assertEqual(bridge.resolve_settings(bridge.parse_command_line(["--map", "floor-2"]))["map"], "floor-2")
            self.assertEqual(bridge.resolve_settings(bridge.parse_command_line([]))["map"], "")
            for bad in ("Floor2", "../x", "-a"):
                with self.assertRaisesRegex(ValueError, "map id"):
                    bridge.resolve_settings(bridge.parse_command_line(["--map=" + bad]))
        finally:
            rospy.get_param = original

    def test_command_line(self):
        cli = bridge.parse_command_line(["--server", "http://h:1", "--log-decisions", "false", "--buffer-size", "7"])
        self.assertEqual((cli.server, cli.log_decisions, cli.buffer_size, cli.token), ("http://h:1", False, 7, None))


class FakeWmd(http.server.ThreadingHTTPServer):
    """Answers POST /api/v1/scans from a script of statuses (then 200), recording each request."""

    def __init__(self, script: list[int]):
        self.script, self.requests, self.lock = list(script), [], threading.Lock()
        super().__init__(("127.0.0.1", 0), FakeHandler)


class FakeHandler(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        body = self.rfile.read(int(self.headers["Content-Length"]))
        with self.server.lock:
            self.server.requests.append((self.path, self.headers.get("Idempotency-Key"),
                                         self.headers.get("Authorization"), body))
            status = self.server.script.pop(0) if self.server.script else 200
        error = {503: "busy", 400: "bad_request"}.get(status)
        answer = json.dumps({"error": error, "detail": "scripted"} if error else {"seq": 1}).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(answer)))
        self.end_headers()
        self.wfile.write(answer)

    def log_message(self, *args):
        pass


class SenderTest(unittest.TestCase):
    def sender(self, server_url: str, **overrides):
        settings = dict(SETTINGS, server=server_url, retry_initial=0.01, retry_max=0.05, drain_timeout=2.0,
                        token="t0k")
        settings.update(overrides)
        counters = bridge.Counters(bridge.COUNTERS)
        return bridge.ScanSender(settings, counters), counters

    def test_retries_keep_the_key_and_refusals_are_counted(self):
        fake = FakeWmd([503, 503, 200, 400])
        threading.Thread(target=fake.serve_forever, daemon=True).start()
        try:
            sender, counters = self.sender(f"http://127.0.0.1:{fake.server_address[1]}")
            sender.start()
            sender.enqueue("k-1", b'{"a": 1}')
            sender.enqueue("k-2", b'{"a": 2}')
            sender.enqueue("k-3", b'{"a": 3}')
            sender.stop()
        finally:
            fake.shutdown()
            fake.server_close()
        self.assertEqual([(path, key, auth, body) for path, key, auth, body in fake.requests], [
            ("/api/v1/scans", "k-1", "Bearer t0k", b'{"a": 1}'),
            ("/api/v1/scans", "k-1", "Bearer t0k", b'{"a": 1}'),
            ("/api/v1/scans", "k-1", "Bearer t0k", b'{"a": 1}'),
            ("/api/v1/scans", "k-2", "Bearer t0k", b'{"a": 2}'),  # 400: refused for good, not retried
            ("/api/v1/scans", "k-3", "Bearer t0k", b'{"a": 3}')])
        c = counters.snapshot()
        self.assertEqual((c["scans_posted"], c["post_retries"], c["scans_rejected"], c["scans_dropped"]), (2, 2, 1, 0))

    def test_a_map_sends_every_scan_to_that_map(self):
        fake = FakeWmd([503])
        threading.Thread(target=fake.serve_forever, daemon=True).start()
        try:
            sender, counters = self.sender(f"http://127.0.0.1:{fake.server_address[1]}", map="floor-2")
            sender.start()
            sender.enqueue("k-1", b'{"a": 1}')
            sender.stop()
        finally:
            fake.shutdown()
            fake.server_close()
        self.assertEqual([(path, key) for path, key, _, _ in fake.requests],
                         [("/api/v1/maps/floor-2/scans", "k-1")] * 2)
        self.assertEqual(counters.snapshot()["scans_posted"], 1)

    def test_overflow_and_what_is_left_at_exit_are_dropped(self):
        port = unused_port()  # nothing listens: connection refused
        sender, counters = self.sender(f"http://127.0.0.1:{port}", buffer_size=3, drain_timeout=0.3)
        sender.start()
        for i in range(5):
            sender.enqueue(f"k-{i}", b"{}")
        self.assertEqual(sender.buffered(), 3)
        started = time.monotonic()
        sender.stop()
        self.assertLess(time.monotonic() - started, 2.0)
        c = counters.snapshot()
        self.assertEqual((c["scans_posted"], c["scans_dropped"]), (0, 5))  # 2 overflowed, 3 left at exit
        self.assertGreater(c["post_retries"], 0)


def unused_port() -> int:
    """A port that was free a moment ago and has no listener."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


if __name__ == "__main__":
    unittest.main(warnings="ignore")
