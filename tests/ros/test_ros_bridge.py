#!/usr/bin/python3
"""End-to-end test of the ROS 1 bridge (clients/ros/wm_ros_bridge.py), real components only: a roscore on a free
port, a wmd on a free port, the bridge started through its launch file (clients/ros/launch/bridge.launch), and a
bag converted from a real CARMEN log (tests/data/carmen/intel-corrected-excerpt.log.gz) played with
`rosbag play --clock`. The bridge works on a map of wmd's own (its map parameter), and the default map must hear
nothing. wmd is killed (SIGKILL) in the middle of the bag and started again on the same port and database.

    test_ros_bridge.py [--wmd PATH] [--keep DIR] [unittest options]

wmd: --wmd, else $WM_WMD_PATH, else $WM_BUILD_DIR/bin/wmd, else <repo>/build/bin/wmd. --keep DIR keeps the bag,
the database and every process's output there. Exits 77 (CTest's SKIP_RETURN_CODE) when ROS is not installed.

What it checks, against what wmd itself answers afterwards:
  - /map (and /map_ds_belief, /map_ds_plausibility, /map_ds_conflict) equal GET /api/v1/grid cell for cell
    (round(100 p), unknown -1), with the same size, resolution and origin, at wmd's final grid revision;
  - the MarkerArray holds every element and every plan edge of GET /api/v1/map as one line, in the web viewer's
    colours, and nothing else;
  - the scans whose tf was left out of the bag are the bridge's skipped count; wmd holds total - skipped - dropped
    scans, the bridge dropped none across the restart, and the sensor poses wmd got are the log's laser poses;
  - every decision wmd made after the bridge connected is logged once, as wmd recorded it.
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import json
import math
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import urllib.error
import urllib.request
from pathlib import Path

SKIP = 77
REPO = Path(__file__).resolve().parents[2]
LOG = REPO / "tests/data/carmen/intel-corrected-excerpt.log.gz"
SKIP_TF_EVERY = 7          # scans 6, 13, 20, 27, 34 have no tf: 5 of the excerpt's 35
PLAY_RATE = 10             # the excerpt's 98 s of log in ~10 s
SOURCE = "intel"
MAP = "floor-1"           # the bridge's map (its ~map parameter); the default map must hear nothing
LAYERS = ("bayes", "ds_belief", "ds_plausibility", "ds_conflict")
TOPICS = {"bayes": "/map", "ds_belief": "/map_ds_belief", "ds_plausibility": "/map_ds_plausibility",
          "ds_conflict": "/map_ds_conflict"}
TF_MAX_GAP = 0.5
# Generous, for a loaded machine: only the last scan, after which no tf ever comes, waits that long; the others
# are given up as soon as the tf stream has moved past them.
TF_WAIT = 2.0
# Kill wmd once the bag has played this many scans (and wmd took some), keep it down this long (wall): ~6 scans
# of the bag arrive meanwhile. Keyed to the bag's progress, so that a slow machine still kills it mid-bag.
KILL_AFTER_RECEIVED = 10
DOWN_S = 2.0
# A small floor plan away from the log's area, so that the markers carry plan edges of two categories too.
PLAN = {"name": "ros-test", "units": "m", "objects": [
    {"id": "wall-a", "kind": "wall", "attributes": ["solid"], "pose": {"x": 60, "y": 60, "theta": 0},
     "segments": [[[0, 0], [6, 0], [6, 4]]]},
    {"id": "table-1", "kind": "table", "attributes": ["not_deformable"], "pose": {"x": 62, "y": 62, "theta": 0.3},
     "polygon": [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]},
    {"id": "box-1", "kind": "box", "attributes": ["movable"], "pose": {"x": 65, "y": 61, "theta": 0},
     "polygon": [[0, 0], [0.5, 0], [0.5, 0.5]]}]}


def ros_missing() -> str | None:
    for tool in ("/usr/bin/roscore", "/usr/bin/roslaunch", "/usr/bin/rosbag"):
        if not os.access(tool, os.X_OK):
            return f"{tool} not found"
    try:
        for module in ("rospy", "rosbag", "rosgraph", "tf2_ros", "nav_msgs.msg", "sensor_msgs.msg", "tf2_msgs.msg",
                       "visualization_msgs.msg"):
            importlib.import_module(module)
    except ImportError as error:
        return f"{error} (under {sys.executable})"
    return None


def on_map(path: str) -> str:
    """A route of the bridge's map: /api/v1/X -> /api/v1/maps/MAP/X."""
    return "/api/v1/maps/" + MAP + path[len("/api/v1"):]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(predicate, timeout_s: float, what: str, period_s: float = 0.05):
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(period_s)


def occupancy(value) -> int:
    """The conversion the bridge promises: round(100 p) half up, -1 for unknown."""
    return -1 if value is None else min(100, max(0, math.floor(value * 100.0 + 0.5)))


def web_colours() -> dict[str, dict[str, str]]:
    """kColors.objects and kColors.elements of the web viewer (clients/web/js/map_view.js)."""
    text = (REPO / "clients/web/js/map_view.js").read_text()
    found = {}
    for group in ("objects", "elements"):
        body = re.search(group + r":\s*\{([^}]*)\}", text).group(1)
        found[group] = dict(re.findall(r"(\w+):\s*'(#[0-9a-fA-F]{6})'", body))
    return found


class Wmd:
    def __init__(self, binary: Path, workdir: Path, port: int):
        self.binary, self.workdir, self.port = binary, workdir, port
        self.url = f"http://127.0.0.1:{port}"
        self.process: subprocess.Popen | None = None
        self.starts = 0
        self.files: list = []

    def start(self) -> None:
        self.starts += 1
        log = open(self.workdir / f"wmd-{self.starts}.log", "w")
        self.files.append(log)
        self.process = subprocess.Popen(
            [str(self.binary), "--db", str(self.workdir / "wm.db"), "--port", str(self.port),
             "--rules", str(REPO / "rules/prolog"), "--no-shm", "--web", ""],
            stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        wait_until(lambda: self._healthy(), 30, "wmd to answer GET /api/v1/health")

    def _healthy(self) -> bool:
        if self.process.poll() is not None:
            raise AssertionError(f"wmd exited with {self.process.returncode}: "
                                 f"{(self.workdir / f'wmd-{self.starts}.log').read_text()[-2000:]}")
        try:
            return self.get("/api/v1/health")["status"] == "ok"
        except OSError:
            return False

    def kill(self) -> None:
        if self.process and self.process.poll() is None:
            self.process.kill()
            self.process.wait()

    def stop(self) -> None:
        if self.process and self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.kill()

    def request(self, method: str, path: str, body=None):
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(self.url + path, data=data, method=method,
                                         headers={"Content-Type": "application/json"} if data else {})
        with urllib.request.urlopen(request, timeout=30) as answer:
            return json.loads(answer.read())

    def get(self, path: str):
        return self.request("GET", path)


class Scenario:
    """Runs everything once; the test methods check what it recorded."""

    def __init__(self, wmd_binary: Path, workdir: Path):
        self.workdir = workdir
        self.processes: list[subprocess.Popen] = []
        self.files: list = []
        self.ros_port = free_port()
        self.env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{self.ros_port}", ROS_HOSTNAME="127.0.0.1",
                        ROS_HOME=str(workdir / "ros_home"), ROS_LOG_DIR=str(workdir / "ros_log"),
                        ROS_PACKAGE_PATH=str(REPO / "clients/ros"), PYTHONUNBUFFERED="1")
        self.env.pop("ROS_IP", None)
        os.environ.update({k: self.env[k] for k in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_HOME", "ROS_LOG_DIR")})
        self.wmd = Wmd(wmd_binary, workdir, free_port())
        self.status: dict = {}
        self.status_lock = threading.Lock()
        self.max_buffered = 0

    # -- processes --

    def spawn(self, name: str, argv: list[str]) -> subprocess.Popen:
        out = open(self.workdir / f"{name}.out", "w")
        self.files.append(out)
        process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT, env=self.env,
                                   start_new_session=True)
        self.processes.append(process)
        return process

    def stop_group(self, process: subprocess.Popen, sig=signal.SIGINT, timeout_s: float = 20) -> None:
        if process.poll() is None:
            os.killpg(process.pid, sig)  # the group of a child we started (roscore's rosmaster and rosout)
            try:
                process.wait(timeout_s)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()

    def cleanup(self) -> None:
        self.wmd.stop()
        for process in reversed(self.processes):
            self.stop_group(process)
        for f in self.files + self.wmd.files:
            f.close()

    # -- ROS side of the test --

    def on_status(self, message) -> None:
        status = json.loads(message.data)
        with self.status_lock:
            self.status = status
            self.max_buffered = max(self.max_buffered, status["buffered"])

    def bridge_status(self) -> dict:
        with self.status_lock:
            return dict(self.status)

    def latest(self, topic: str, message_type, timeout_s: float = 20):
        """The message latched on topic, through a new subscription (so it is the newest one published)."""
        import rospy
        got, event = [], threading.Event()

        def callback(message):
            got.append(message)
            event.set()

        subscriber = rospy.Subscriber(topic, message_type, callback, queue_size=1)
        try:
            if not event.wait(timeout_s):
                raise AssertionError(f"nothing latched on {topic} within {timeout_s} s")
        finally:
            subscriber.unregister()
        return got[-1]

    # -- the run --

    def run(self) -> None:
        import rosgraph
        import rospy
        from nav_msgs.msg import OccupancyGrid
        from std_msgs.msg import String
        from visualization_msgs.msg import MarkerArray

        sys.path.insert(0, str(Path(__file__).resolve().parent))
        import carmen_to_bag

        started = time.monotonic()
        self.bag = self.workdir / "intel-excerpt.bag"
        self.manifest = carmen_to_bag.convert(str(LOG), str(self.bag), SKIP_TF_EVERY)

        self.roscore = self.spawn("roscore", ["/usr/bin/roscore", "-p", str(self.ros_port)])
        wait_until(lambda: rosgraph.is_master_online(self.env["ROS_MASTER_URI"]), 30, "roscore")
        rospy.init_node("wm_bridge_test", anonymous=True, disable_signals=True)
        rospy.set_param("/use_sim_time", True)  # the bridge runs on the bag's clock, as a replay would
        rospy.Subscriber("/wm_ros_bridge/status", String, self.on_status)

        self.wmd.start()
        # The bridge works on a map of its own (its map parameter): every request goes there, none to the default.
        self.wmd.request("POST", "/api/v1/maps", {"id": MAP})
        self.wmd.request("PUT", on_map("/api/v1/floorplan"), PLAN)
        self.instance_before = self.wmd.get(on_map("/api/v1/map"))["server_instance"]
        self.decisions_before = self.wmd.get(on_map("/api/v1/health"))["last_decision_seq"]

        self.bridge = self.spawn("bridge", [
            "/usr/bin/roslaunch", "--wait", "worldmodel_ros", "bridge.launch", f"server:={self.wmd.url}",
            f"observer:={SOURCE}", f"map:={MAP}", f"tf_max_gap:={TF_MAX_GAP}", f"tf_wait:={TF_WAIT}",
            "poll_period:=0.2", "grid_max_rate:=2"])
        wait_until(lambda: self.bridge_status().get("server_instance") == self.instance_before, 30,
                   "the bridge to reach wmd")

        # -d: time for the bridge to subscribe to the bag's topics before the first message.
        self.player = self.spawn("rosbag_play", ["/usr/bin/rosbag", "play", "--clock", "-q", "-r", str(PLAY_RATE),
                                                 "-d", "1", str(self.bag)])
        wait_until(lambda: (lambda s: s.get("scans_received", 0) >= KILL_AFTER_RECEIVED
                            and s.get("scans_posted", 0) >= 3)(self.bridge_status()), 60,
                   f"{KILL_AFTER_RECEIVED} scans received, 3 posted")
        self.wmd.kill()
        self.at_kill = self.bridge_status()
        time.sleep(DOWN_S)
        self.before_restart = self.bridge_status()
        self.wmd.start()
        self.instance_after = self.wmd.get(on_map("/api/v1/map"))["server_instance"]
        if self.player.wait(90) != 0:
            raise AssertionError(f"rosbag play exited with {self.player.returncode}")

        # Settled: every scan of the bag taken by the bridge, nothing waiting for tf or for wmd ...
        total = self.manifest["total"]
        wait_until(lambda: (lambda s: s.get("scans_received") == total and s.get("waiting_for_tf") == 0
                            and s.get("buffered") == 0)(self.bridge_status()), 60,
                   f"the bridge to take all {total} scans and post them")
        # ... and the bridge publishing what wmd holds now, which no longer moves.
        def caught_up():
            revision = self.wmd.get(on_map("/api/v1/grid/tiles"))["revision"]
            version = self.wmd.get(on_map("/api/v1/map"))["version"]
            seq = self.wmd.get(on_map("/api/v1/health"))["last_decision_seq"]
            s = self.bridge_status()
            if (s.get("grid_revisions") == {layer: revision for layer in LAYERS} and s.get("map_version") == version
                    and s.get("decision_seq") == seq and s.get("server_instance") == self.instance_after):
                return revision, version, seq
            return None
        self.revision, self.version, self.last_seq = wait_until(caught_up, 60, "the bridge to publish wmd's state")

        self.grids = {layer: self.latest(TOPICS[layer], OccupancyGrid) for layer in LAYERS}
        self.markers = self.latest("/worldmodel/markers", MarkerArray)
        self.wmd_grids = {layer: self.wmd.get(on_map(f"/api/v1/grid?layer={layer}&format=json"))
                          for layer in LAYERS}
        self.wmd_map = self.wmd.get(on_map("/api/v1/map"))
        self.wmd_tiles = self.wmd.get(on_map("/api/v1/grid/tiles"))
        self.wmd_robot = self.wmd.get(on_map(f"/api/v1/robots/{SOURCE}"))
        self.wmd_decisions = self.wmd.get(
            on_map(f"/api/v1/decisions?since={self.decisions_before}&limit=10000"))
        self.final_status = self.bridge_status()
        self.default_map = self.wmd.get("/api/v1/map")
        self.default_tiles = self.wmd.get("/api/v1/grid/tiles")

        self.stop_group(self.bridge)  # SIGINT: the bridge drains and prints its final counters
        self.bridge_output = (self.workdir / "bridge.out").read_text()
        self.runtime_s = time.monotonic() - started


class RosBridgeTest(unittest.TestCase):
    scenario: Scenario
    wmd_binary: Path
    keep: str | None = None

    @classmethod
    def setUpClass(cls):
        workdir = Path(cls.keep) if cls.keep else Path(tempfile.mkdtemp(prefix="wm-ros-test-"))
        workdir.mkdir(parents=True, exist_ok=True)
        cls.scenario = Scenario(cls.wmd_binary, workdir)
        atexit.register(cls.scenario.cleanup)
        try:
            cls.scenario.run()
        except BaseException:
            for name in ("bridge.out", "rosbag_play.out", "wmd-1.log", "wmd-2.log", "roscore.out"):
                path = workdir / name
                if path.exists():
                    print(f"---- {name} (last 3000 characters)\n{path.read_text()[-3000:]}", file=sys.stderr)
            raise
        finally:
            cls.scenario.cleanup()
            if not cls.keep:
                shutil.rmtree(workdir, ignore_errors=True)
        s = cls.scenario
        print(f"\nscans in bag {s.manifest['total']}, tf left out {s.manifest['tf_left_out']}, "
              f"skipped {s.final_status['scans_skipped_no_tf']}, dropped {s.final_status['scans_dropped']}, "
              f"wmd scans {s.revision}, buffered at most {s.max_buffered} while wmd was down "
              f"(received {s.at_kill['scans_received']} -> {s.before_restart['scans_received']} during the "
              f"{DOWN_S} s), post retries {s.final_status['post_retries']}, elements {len(s.wmd_map['elements'])}, "
              f"decisions {s.last_seq - s.decisions_before}, runtime {s.runtime_s:.1f} s", file=sys.stderr)

    def test_grid_layers_equal_wmd_cell_for_cell(self):
        s = self.scenario
        for layer in LAYERS:
            with self.subTest(layer=layer):
                grid, message = s.wmd_grids[layer], s.grids[layer]
                self.assertEqual(grid["revision"], s.revision)
                self.assertEqual(message.header.frame_id, "map")
                self.assertEqual((message.info.width, message.info.height), (grid["width"], grid["height"]))
                as_float32 = struct.unpack("f", struct.pack("f", grid["resolution"]))[0]  # the message's field type
                self.assertEqual(message.info.resolution, as_float32)
                self.assertEqual((message.info.origin.position.x, message.info.origin.position.y),
                                 tuple(grid["origin"]))
                expected = [occupancy(v) for v in grid["data"]]
                actual = list(message.data)
                self.assertEqual(len(actual), grid["width"] * grid["height"])
                mismatches = [i for i, (a, e) in enumerate(zip(actual, expected)) if a != e]
                self.assertEqual(mismatches[:10], [], f"{len(mismatches)} cells differ")
        # Not an empty map: the log's walls are occupied, the rooms free, the rest unknown.
        bayes = list(s.grids["bayes"].data)
        self.assertGreater(sum(1 for v in bayes if v >= 65), 500)
        self.assertGreater(sum(1 for v in bayes if 0 <= v <= 20), 5000)
        self.assertGreater(bayes.count(-1), 0)

    def test_markers_are_the_map(self):
        s = self.scenario
        colours = web_colours()
        expected: dict[str, list] = {}
        for element in s.wmd_map["elements"]:
            category = element["source"] if element["source"] in ("scan", "grid", "client") else "other"
            expected.setdefault(f"elements/{category}", []).append((tuple(element["p0"]), tuple(element["p1"])))
        for obj in s.wmd_map["objects"]:
            category = next((a for a in ("solid", "not_deformable") if a in obj["attributes"]), "other")
            for edge in obj["edges"]:
                expected.setdefault(f"plan/{category}", []).append((tuple(edge["p0"]), tuple(edge["p1"])))
        self.assertGreater(len(expected.get("elements/scan", [])), 10, "the scans made line elements")
        self.assertEqual(sorted(k for k in expected if k.startswith("plan/")),
                         ["plan/not_deformable", "plan/other", "plan/solid"])

        markers = s.markers.markers
        self.assertEqual(markers[0].action, 3)  # DELETEALL first: categories that emptied disappear
        actual = {}
        for marker in markers[1:]:
            self.assertEqual(marker.type, 5)  # LINE_LIST
            self.assertEqual(marker.header.frame_id, "map")
            self.assertNotIn(marker.ns, actual)
            points = [(p.x, p.y) for p in marker.points]
            self.assertEqual(len(points) % 2, 0)
            actual[marker.ns] = list(zip(points[0::2], points[1::2]))
            group, category = marker.ns.split("/")
            want = colours["objects" if group == "plan" else "elements"][category]
            got = "#%02x%02x%02x" % tuple(round(c * 255) for c in (marker.color.r, marker.color.g, marker.color.b))
            self.assertEqual(got, want.lower(), marker.ns)
        self.assertEqual(sorted(actual), sorted(expected))
        for ns in expected:
            self.assertEqual(len(actual[ns]), len(expected[ns]), ns)
            self.assertEqual(sorted(actual[ns]), sorted(expected[ns]), ns)
        self.assertEqual(sum(len(v) for k, v in actual.items() if k.startswith("elements/")),
                         len(s.wmd_map["elements"]))
        self.assertEqual(sum(len(v) for k, v in actual.items() if k.startswith("plan/")),
                         sum(len(o["edges"]) for o in s.wmd_map["objects"]))

    def test_scans_without_tf_are_skipped_and_counted(self):
        s = self.scenario
        left_out = [scan for scan in s.manifest["scans"] if scan["tf_left_out"]]
        self.assertEqual(len(left_out), 5)
        # The premise: tf2 alone would interpolate the ones in the middle; no tf sample is within the gap limit.
        self.assertTrue(all(scan["nearest_tf_s"] > TF_MAX_GAP for scan in left_out))
        self.assertEqual(s.final_status["scans_skipped_no_tf"], len(left_out))
        self.assertEqual(s.final_status["scans_received"], s.manifest["total"])
        self.assertEqual(s.final_status["scans_placed"], s.manifest["total"] - len(left_out))

    def test_restart_loses_only_what_the_bridge_dropped(self):
        s = self.scenario
        self.assertNotEqual(s.instance_before, s.instance_after, "wmd was restarted")
        self.assertGreater(s.before_restart["scans_received"], s.at_kill["scans_received"],
                           "scans arrived while wmd was down")
        self.assertGreater(s.max_buffered, 0)
        self.assertGreater(s.final_status["post_retries"], 0)
        status = s.final_status
        self.assertEqual(status["scans_dropped"], 0)
        self.assertEqual(status["scans_rejected"], 0)
        # Every scan of the bag is in wmd, skipped for want of tf, or counted as dropped.
        self.assertEqual(s.revision + status["scans_dropped"] + status["scans_skipped_no_tf"], s.manifest["total"])
        self.assertEqual(s.wmd_tiles["revision"], s.revision)
        self.assertEqual(s.wmd_robot["scans"], {"laser": s.revision})
        self.assertEqual(status["scans_posted"], s.revision)
        # The bridge's own books balance: every scan it received is posted, refused, skipped or dropped.
        self.assertEqual(status["scans_received"], status["scans_posted"] + status["scans_rejected"]
                         + status["scans_skipped_no_tf"] + status["scans_dropped"])

    def test_scans_were_placed_where_the_log_says(self):
        s = self.scenario
        placed = [scan["laser_pose"] for scan in s.manifest["scans"] if not scan["tf_left_out"]]
        pose = s.wmd_robot["pose"]
        self.assertEqual(pose["source"], "scan:laser")
        for got, want in zip((pose["x"], pose["y"], pose["theta"]), placed[-1]):
            self.assertAlmostEqual(got, want, places=6)
        # The track after the restart holds the scans posted since; each is one of the log's laser poses.
        self.assertGreater(len(s.wmd_robot["track"]), 3)
        for x, y, theta, _ in s.wmd_robot["track"]:
            nearest = min(math.hypot(x - p[0], y - p[1]) + abs(math.remainder(theta - p[2], math.tau))
                          for p in placed)
            self.assertLess(nearest, 1e-6)

    def test_decisions_logged_once_each(self):
        s = self.scenario
        logged = re.findall(r"decision (\d+): (\S+) (\S+) \(rule (\S+), ", s.bridge_output)
        recorded = s.wmd_decisions["decisions"]
        self.assertGreater(len(recorded), 10)
        self.assertEqual(recorded[-1]["seq"], s.last_seq)
        self.assertEqual([int(seq) for seq, *_ in logged], [d["seq"] for d in recorded])
        for (seq, action, target, rule), d in zip(logged, recorded):
            self.assertEqual((action, target, rule), (d["action"], d["element"] or d["object"] or "-", d["rule"]))

    def test_the_default_map_heard_nothing(self):
        s = self.scenario
        self.assertGreater(len(s.wmd_map["elements"]), 0)
        self.assertEqual((len(s.default_map["elements"]), s.default_tiles["revision"]), (0, 0))

    def test_final_counters_printed_at_exit(self):
        s = self.scenario
        match = re.search(r"wm_ros_bridge: final (\{.*\})", s.bridge_output)
        self.assertIsNotNone(match, "the bridge printed its counters at exit")
        final = json.loads(match.group(1))
        for name in ("scans_received", "scans_placed", "scans_skipped_no_tf", "scans_posted", "scans_dropped",
                     "scans_rejected"):
            self.assertEqual(final[name], s.final_status[name], name)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--wmd", help="wmd binary")
    parser.add_argument("--keep", help="keep the run's files in this directory")
    args, rest = parser.parse_known_args()
    missing = ros_missing()
    if missing:
        print(f"SKIP: ROS 1 is not installed ({missing}); scripts/setup.sh ros installs it", flush=True)
        return SKIP
    build_dir = Path(os.environ.get("WM_BUILD_DIR") or REPO / "build")
    wmd = args.wmd or os.environ.get("WM_WMD_PATH") or str(build_dir / "bin/wmd")
    if not os.access(wmd, os.X_OK):
        print(f"FAIL: no wmd at {wmd} (--wmd, WM_WMD_PATH or WM_BUILD_DIR)", file=sys.stderr)
        return 1
    RosBridgeTest.wmd_binary = Path(wmd)
    RosBridgeTest.keep = args.keep
    # rospy leaves sockets for the garbage collector: its ResourceWarnings are noise here.
    result = unittest.main(argv=[sys.argv[0]] + rest, exit=False, warnings="ignore").result
    return 0 if result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
