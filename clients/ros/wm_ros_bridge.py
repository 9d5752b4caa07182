#!/usr/bin/python3
"""wm_ros_bridge: a ROS 1 node between a robot's ROS stack and the worldmodel server (wmd).

Robot -> wmd: every sensor_msgs/LaserScan on the scan topic is placed in the map frame through tf2 at the
scan's stamp and posted to POST /api/v1/scans, each with its own Idempotency-Key, through a bounded buffer
that rides out wmd restarts with retries and back-off.

wmd -> ROS: the Bayes grid as a latched nav_msgs/OccupancyGrid on /map, the Dempster-Shafer layers on
/map_ds_belief, /map_ds_plausibility and /map_ds_conflict, the vector map and the floor plan as a latched
visualization_msgs/MarkerArray, every decision as a rosout line, and the bridge's counters as JSON on
~status.

With ~map set, every request goes to that map of wmd (/api/v1/maps/MAP/...): one bridge per floor or site.

Every setting is a private ROS parameter (~name) or a command-line flag (--name, which wins); see --help.
The counters (scans placed, skipped for want of tf, dropped, ...) are published on ~status, logged every
status_log_period seconds and printed at exit.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import http.client
import json
import math
import re
import sys
import threading
import time
import urllib.parse
import uuid
from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import Point
from nav_msgs.msg import OccupancyGrid
from rospy.numpy_msg import numpy_msg
from sensor_msgs.msg import LaserScan
from std_msgs.msg import ColorRGBA, String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

NODE_NAME = "wm_ros_bridge"
GRID_LAYERS = ("bayes", "ds_belief", "ds_plausibility", "ds_conflict")

# The web viewer's colours (clients/web/js/map_view.js, kColors), so rviz and the browser agree: plan objects by
# attribute, observed elements by origin.
OBJECT_COLOURS = {"solid": "#2451a6", "not_deformable": "#1e9e4a", "other": "#c08a00"}
ELEMENT_COLOURS = {"scan": "#ec6a00", "grid": "#9c36b5", "client": "#8d5524", "other": "#6b6b6b"}


# ---- settings ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Option:
    name: str
    kind: type  # str, int, float or bool
    default: Any
    help: str


OBSERVER_DEFAULT = "ros-robot"
# wmd's rule for a map id (it goes into URLs and file names).
MAP_ID = re.compile(r"[a-z0-9][a-z0-9_-]{0,31}")

OPTIONS = (
    Option("server", str, "http://127.0.0.1:8080", "wmd's base URL"),
    Option("token", str, "", "wmd's --token: sent as 'Authorization: Bearer TOKEN' (empty: none)"),
    Option("map", str, "", "wmd's map the robot works on: requests go to /api/v1/maps/MAP/... "
                            "(1-32 of a-z 0-9 _ -, not starting with _ or -; empty: the default map's routes)"),
    Option("scan_topic", str, "scan", "sensor_msgs/LaserScan topic to post"),
    Option("map_frame", str, "map", "tf frame of wmd's world: scans are placed in it, grids and markers are in it"),
    Option("observer", str, OBSERVER_DEFAULT, "robot id sent as the scans' observer (1-128 of A-Z a-z 0-9 . _ : -)"),
    Option("source", str, "", "the old name of observer, still read (both given and different: refused)"),
    Option("tf_wait", float, 0.5, "wall seconds a scan waits for its transform before it is skipped"),
    Option("tf_max_gap", float, 0.5,
           "a scan is placed only if every moving transform on its chain has a /tf sample within this many "
           "seconds of the stamp, so a pose is never interpolated across a hole in the tf stream (0: off)"),
    Option("tf_cache", float, 30.0, "seconds of tf history kept"),
    Option("tf_queue_size", int, 200, "scans waiting for their transform; beyond it the oldest is dropped"),
    Option("buffer_size", int, 1000, "placed scans waiting for wmd; beyond it the oldest is dropped (counted)"),
    Option("retry_initial", float, 0.1, "first back-off after a failed post [s]; doubles on each failure"),
    Option("retry_max", float, 5.0, "longest back-off between retries [s]"),
    Option("http_timeout", float, 10.0, "timeout of one HTTP request [s]"),
    Option("drain_timeout", float, 5.0, "at exit, seconds spent posting what is still buffered"),
    Option("poll_period", float, 0.5, "how often the grid revision, the map and the decisions are polled [s]"),
    Option("grid_max_rate", float, 1.0, "most grid republications per second (the grid JSON is large)"),
    Option("grid_layers", str, ",".join(GRID_LAYERS), "grid layers to publish, comma-separated (empty: none)"),
    Option("map_topic", str, "map", "topic of the Bayes layer"),
    Option("ds_topic_prefix", str, "map_", "the Dempster-Shafer layers go to PREFIX + layer name (map_ds_belief)"),
    Option("markers_topic", str, "worldmodel/markers", "MarkerArray topic of the vector map and the floor plan"),
    Option("marker_width", float, 0.05, "line width of the markers [m]"),
    Option("status_topic", str, "~status", "std_msgs/String topic with the counters as JSON (latched)"),
    Option("status_log_period", float, 30.0, "how often the counters are logged [s] (0: only at exit)"),
    Option("log_decisions", bool, True, "log every decision of wmd's rules as a rosout line"),
    Option("decisions_from_start", bool, False,
           "log the decisions wmd made before the bridge first reached it too (default: only new ones)"),
    Option("inf_is_valid", bool, False,
           "send +inf ranges (REP 117: no return) as range_max, which clears free space; else as null (ignored)"),
    Option("sigma_range", float, 0.0, "range standard deviation sent with each scan [m] (0: wmd's default)"),
    Option("sigma_range_per_m", float, 0.0, "growth of that deviation per metre of range (0: not sent)"),
    Option("usable_range", float, 0.0, "returns beyond it only clear space [m] (0: wmd's --usable-range)"),
)


def _parse_bool(text: str) -> bool:
    lowered = str(text).strip().lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"not a boolean: {text!r}")


def parse_command_line(argv: list[str]) -> argparse.Namespace:
    """Parses the flags; runs before rospy.init_node so that --help needs no ROS master."""
    parser = argparse.ArgumentParser(
        prog="wm_ros_bridge.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Each flag is also the private ROS parameter ~NAME (underscores); a flag given here wins.")
    for option in OPTIONS:
        parser.add_argument("--" + option.name.replace("_", "-"), dest=option.name, default=None,
                            type=_parse_bool if option.kind is bool else option.kind,
                            metavar=option.kind.__name__.upper(), help=f"{option.help} (default: {option.default})")
    return parser.parse_args(argv)


def resolve_settings(cli: argparse.Namespace) -> dict[str, Any]:
    """Flag, else ~parameter, else the default; converted to the option's type."""
    settings = {}
    for option in OPTIONS:
        value = getattr(cli, option.name)
        if value is None:
            value = rospy.get_param("~" + option.name, option.default)
            value = _parse_bool(value) if option.kind is bool else option.kind(value)
        settings[option.name] = value
    if settings["source"]:
        if settings["observer"] not in (OBSERVER_DEFAULT, settings["source"]):
            raise ValueError(f"observer {settings['observer']!r} and its old name source {settings['source']!r} "
                             "differ: give one")
        settings["observer"] = settings["source"]
    if settings["map"] and not MAP_ID.fullmatch(settings["map"]):
        raise ValueError(f"map {settings['map']!r}: a map id is 1-32 of a-z, 0-9, '_' and '-', not starting "
                         "with '_' or '-'")
    for name in ("tf_queue_size", "buffer_size", "poll_period", "grid_max_rate", "http_timeout", "retry_initial"):
        if not settings[name] > 0:
            raise ValueError(f"{name} must be positive, not {settings[name]}")
    return settings


# ---- small helpers -----------------------------------------------------------------------------------------


class Throttle:
    """Wall-clock throttling for repeated warnings (rospy's own throttles run on ROS time, which stands still
    when a bag's --clock stops)."""

    def __init__(self, period_s: float):
        self.period_s = period_s
        self.last = -math.inf

    def ready(self) -> bool:
        now = time.monotonic()
        if now - self.last >= self.period_s:
            self.last = now
            return True
        return False


class Counters:
    """Thread-safe named counters."""

    def __init__(self, names: tuple[str, ...]):
        self._lock = threading.Lock()
        self._values = {name: 0 for name in names}

    def add(self, name: str, n: int = 1) -> None:
        with self._lock:
            self._values[name] += n

    def snapshot(self) -> dict[str, int]:
        with self._lock:
            return dict(self._values)


def colour(hex_rgb: str) -> ColorRGBA:
    return ColorRGBA(r=int(hex_rgb[1:3], 16) / 255.0, g=int(hex_rgb[3:5], 16) / 255.0,
                     b=int(hex_rgb[5:7], 16) / 255.0, a=1.0)


def occupancy_values(cells: list) -> np.ndarray:
    """wmd's grid values (probabilities or masses in [0, 1], None = unknown) as OccupancyGrid data (int8):
    round(100 * v), half up, and -1 for unknown."""
    values = np.array(cells, dtype=np.float64)  # None becomes NaN
    out = np.full(values.shape, -1, dtype=np.int8)
    known = ~np.isnan(values)
    out[known] = np.clip(np.floor(values[known] * 100.0 + 0.5), 0, 100).astype(np.int8)
    return out


def push_bounded(queue: collections.deque, item: Any, capacity: int) -> bool:
    """Appends item; when the queue is full, drops the oldest item but the head (its worker is busy with it, and
    it may yet succeed), or the new item when nothing else can go. True when something was dropped."""
    if len(queue) < capacity:
        queue.append(item)
        return False
    if len(queue) >= 2:
        del queue[1]
        queue.append(item)
    return True


def strip_slash(frame: str) -> str:
    return frame[1:] if frame.startswith("/") else frame


# ---- HTTP --------------------------------------------------------------------------------------------------


class Unreachable(Exception):
    """wmd did not answer: connection refused or reset, timeout."""


class HttpError(Exception):
    def __init__(self, status: int, body: bytes):
        self.status = status
        try:
            parsed = json.loads(body)
            self.code, self.detail = parsed.get("error", ""), parsed.get("detail", "")
        except (ValueError, AttributeError):
            self.code, self.detail = "", body[:200].decode("utf-8", "replace")
        super().__init__(f"HTTP {status} {self.code}: {self.detail}")


def map_path(map_id: str, path: str) -> str:
    """`path` (a route of one map, /api/v1/...) on the map `map_id`: /api/v1/maps/MAP/...; empty: unchanged (the
    default map's routes)."""
    prefix = "/api/v1/"
    if not map_id or not path.startswith(prefix):
        return path
    return f"/api/v1/maps/{map_id}/{path[len(prefix):]}"


class WmdClient:
    """One keep-alive connection to wmd, on one map. Not thread-safe: each thread has its own."""

    def __init__(self, base_url: str, token: str, timeout_s: float, map_id: str = ""):
        url = urllib.parse.urlsplit(base_url)
        if url.scheme not in ("http", "https") or not url.hostname:
            raise ValueError(f"server: not an http(s) URL: {base_url!r}")
        self._https = url.scheme == "https"
        self._host = url.hostname
        self._port = url.port
        self._prefix = url.path.rstrip("/")
        self._timeout_s = timeout_s
        self._map_id = map_id
        self._headers = {"Authorization": f"Bearer {token}"} if token else {}
        self._conn: Optional[http.client.HTTPConnection] = None

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def request(self, method: str, path: str, body: Optional[bytes] = None,
                headers: Optional[dict[str, str]] = None) -> tuple[int, dict[str, str], bytes]:
        all_headers = dict(self._headers)
        if body is not None:
            all_headers["Content-Type"] = "application/json"
        all_headers.update(headers or {})
        path = map_path(self._map_id, path)
        # A kept-alive connection the server closed meanwhile fails on first use: that one gets a fresh
        # connection at once (safe for posts too, they carry an Idempotency-Key); a fresh one failing means wmd
        # is not there.
        for attempt in range(2):
            reused = self._conn is not None
            if self._conn is None:
                cls = http.client.HTTPSConnection if self._https else http.client.HTTPConnection
                self._conn = cls(self._host, self._port, timeout=self._timeout_s)
            try:
                self._conn.request(method, self._prefix + path, body=body, headers=all_headers)
                response = self._conn.getresponse()
                data = response.read()
                answer_headers = {k.lower(): v for k, v in response.getheaders()}
                if response.will_close:
                    self.close()
                return response.status, answer_headers, data
            except (OSError, http.client.HTTPException) as error:
                self.close()
                if attempt == 0 and reused:
                    continue
                raise Unreachable(f"{method} {path}: {error}") from error
        raise AssertionError("unreachable")

    def get_json(self, path: str) -> dict:
        status, _, data = self.request("GET", path)
        if status != 200:
            raise HttpError(status, data)
        return json.loads(data)


# ---- robot -> wmd: placing scans -----------------------------------------------------------------------------


def planar_pose(translation, rotation) -> tuple[float, float, float, bool]:
    """(x, y, theta, mirrored) of a laser from its transform into the map: theta is the heading of its x axis in
    the map plane; mirrored when it is mounted upside down (its z axis pointing down), so that it sweeps
    clockwise in the map."""
    q = rotation
    theta = math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
    mirrored = 1.0 - 2.0 * (q.x * q.x + q.y * q.y) < 0.0
    return translation.x, translation.y, theta, mirrored


def scan_body(scan: LaserScan, pose: tuple[float, float, float, bool], settings: dict) -> dict:
    """The JSON body of POST /api/v1/scans for a LaserScan taken at pose (planar_pose)."""
    x, y, theta, mirrored = pose
    # REP 117: +inf is "no return within range_max" (free space up to it, if the driver means it: inf_is_valid,
    # as costmap_2d names it), -inf "too close", NaN "no measurement"; JSON has no infinities.
    inf_value = float(scan.range_max) if settings["inf_is_valid"] else None
    ranges = [r if math.isfinite(r) else (inf_value if r == math.inf else None) for r in scan.ranges]
    angle_min = float(scan.angle_min)
    if mirrored:  # beam i at heading theta - a_i: the same fan, listed from the other end
        ranges.reverse()
        angle_min = -(angle_min + (len(ranges) - 1) * float(scan.angle_increment))
    body = {"sensor": "laser", "observer": settings["observer"], "stamp": scan.header.stamp.to_sec(),
            "pose": {"x": x, "y": y, "theta": theta}, "angle_min": angle_min,
            "angle_increment": float(scan.angle_increment), "ranges": ranges,
            "range_min": float(scan.range_min), "range_max": float(scan.range_max)}
    for name in ("sigma_range", "sigma_range_per_m", "usable_range"):
        if settings[name] > 0:
            body[name] = settings[name]
    return body


class TfFeed:
    """Feeds /tf and /tf_static into a tf2 buffer (what tf2_ros.TransformListener does) and also remembers, per
    moving frame, its parent and the stamps of its samples: tf2 interpolates across any hole in the stream,
    and a scan between two localiser updates seconds apart would be put where the robot never was."""

    def __init__(self, cache_s: float):
        self.buffer = tf2_ros.Buffer(cache_time=rospy.Duration(cache_s))
        self._cache_s = cache_s
        self._lock = threading.Lock()
        self._parents: dict[str, str] = {}
        self._static: set[str] = set()
        self._stamps: dict[str, list[float]] = {}
        self._last_now = rospy.Time.now()
        self._subscribers = [rospy.Subscriber("/tf", TFMessage, self._on_tf, callback_args=False),
                             rospy.Subscriber("/tf_static", TFMessage, self._on_tf, callback_args=True)]

    def close(self) -> None:
        for subscriber in self._subscribers:
            subscriber.unregister()

    def _on_tf(self, message: TFMessage, static: bool) -> None:
        who = message._connection_header.get("callerid", "default_authority")
        with self._lock:
            # A bag started again moves ROS time back: forget everything, as tf2_ros.TransformListener does.
            now = rospy.Time.now()
            if now < self._last_now:
                self.buffer.clear()
                self._parents.clear()
                self._static.clear()
                self._stamps.clear()
            self._last_now = now
            for transform in message.transforms:
                child = strip_slash(transform.child_frame_id)
                self._parents[child] = strip_slash(transform.header.frame_id)
                if static:
                    self.buffer.set_transform_static(transform, who)
                    self._static.add(child)
                    continue
                self.buffer.set_transform(transform, who)
                self._static.discard(child)
                stamps = self._stamps.setdefault(child, [])
                bisect.insort(stamps, transform.header.stamp.to_sec())
                if stamps[-1] - stamps[0] > self._cache_s:
                    del stamps[: bisect.bisect_left(stamps, stamps[-1] - self._cache_s)]

    def _path_to_root(self, frame: str) -> list[str]:
        path = [frame]
        while path[-1] in self._parents and len(path) < 100:
            path.append(self._parents[path[-1]])
        return path

    def gap_problem(self, source: str, target: str, stamp: float, max_gap_s: float) -> tuple[Optional[str], bool]:
        """(None, _) when every moving link between the two frames has a sample within max_gap_s of stamp, else
        what is missing and whether that is final: the link's stream went on past stamp + max_gap_s, and tf
        comes in stamp order, so the hole will stay."""
        with self._lock:
            up_source, up_target = self._path_to_root(source), self._path_to_root(target)
            common = next((f for f in up_source if f in up_target), None)
            if common is None:
                return f"no tf chain from {source} to {target} seen yet", False
            links = up_source[: up_source.index(common)] + up_target[: up_target.index(common)]
            for child in links:
                if child in self._static:
                    continue
                stamps = self._stamps.get(child, [])
                i = bisect.bisect_left(stamps, stamp)
                nearest = min((abs(stamps[j] - stamp) for j in (i - 1, i) if 0 <= j < len(stamps)), default=math.inf)
                if nearest > max_gap_s:
                    return (f"nearest {self._parents.get(child)}->{child} sample is {nearest:.3f} s from the stamp",
                            bool(stamps) and stamps[-1] > stamp + max_gap_s)
            return None, False


@dataclass
class PendingScan:
    scan: LaserScan
    received: float  # time.monotonic() when it arrived


class ScanPlacer:
    """Places each scan at its stamp, in arrival order, waiting up to tf_wait wall seconds for the transform
    (tf often arrives just after the scan it places); scans it cannot place are counted and skipped."""

    def __init__(self, settings: dict, tf: TfFeed, counters: Counters, deliver: Callable[[str, bytes], None]):
        self._s = settings
        self._tf = tf
        self._counters = counters
        self._deliver = deliver
        self._pending: collections.deque[PendingScan] = collections.deque()
        self._cond = threading.Condition()
        self._stopping = False
        self._run_id = uuid.uuid4().hex[:12]  # keys of this run never collide with another run's
        self._count = 0
        self._skip_log = Throttle(5.0)
        self._thread = threading.Thread(target=self._run, name="scan-placer", daemon=True)
        # A deep queue: the callback only appends, and rospy drops silently what overflows its own queue.
        self._subscriber = rospy.Subscriber(settings["scan_topic"], LaserScan, self._on_scan, queue_size=1000)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._subscriber.unregister()
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
        self._thread.join()

    def waiting(self) -> int:
        with self._cond:
            return len(self._pending)

    def _on_scan(self, scan: LaserScan) -> None:
        self._counters.add("scans_received")
        with self._cond:
            if push_bounded(self._pending, PendingScan(scan, time.monotonic()), self._s["tf_queue_size"]):
                self._counters.add("scans_dropped")
            self._cond.notify()

    def _run(self) -> None:
        while True:
            with self._cond:
                while not self._pending and not self._stopping:
                    self._cond.wait()
                if not self._pending:
                    return
                head, stopping = self._pending[0], self._stopping
            pose, why, final = self._sensor_pose(head.scan)
            # At exit nothing more will come: what tf cannot place now is skipped without waiting.
            if (pose is None and not final and not stopping
                    and time.monotonic() - head.received < self._s["tf_wait"]):
                time.sleep(0.005)
                continue
            with self._cond:
                self._pending.popleft()  # the head: push_bounded never drops it
            if pose is None:
                self._counters.add("scans_skipped_no_tf")
                if self._skip_log.ready():
                    rospy.logwarn("%s: skipped a scan stamped %.3f that tf cannot place: %s", NODE_NAME,
                                  head.scan.header.stamp.to_sec(), why)
                continue
            self._count += 1
            key = f"{self._run_id}-{self._s['observer']}-{self._count}"
            self._deliver(key, json.dumps(scan_body(head.scan, pose, self._s), allow_nan=False).encode())
            self._counters.add("scans_placed")

    def _sensor_pose(self, scan: LaserScan) -> tuple[Optional[tuple[float, float, float, bool]], str, bool]:
        """(x, y, theta, mirrored) of the laser in the map frame at the scan's stamp, or None, why, and whether
        waiting longer cannot help."""
        frame = strip_slash(scan.header.frame_id)
        if not frame:
            return None, "empty frame_id", True
        if scan.header.stamp.is_zero():  # to tf2, time 0 means "the latest", wherever the robot was then
            return None, "no stamp", True
        try:
            t = self._tf.buffer.lookup_transform(self._s["map_frame"], frame, scan.header.stamp)
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException,
                tf2_ros.InvalidArgumentException) as error:
            return None, (str(error).splitlines() or [type(error).__name__])[0], False
        if self._s["tf_max_gap"] > 0:
            problem, final = self._tf.gap_problem(frame, self._s["map_frame"], scan.header.stamp.to_sec(),
                                                  self._s["tf_max_gap"])
            if problem:
                return None, problem, final
        return planar_pose(t.transform.translation, t.transform.rotation), "", False


class ScanSender:
    """Posts placed scans in order through a bounded buffer. wmd down (refused, reset, timeout, 5xx, 503 busy)
    means retry the same scan with the same Idempotency-Key after a doubling back-off, so nothing is applied
    twice; the buffer's overflow (oldest first) is what is lost, and it is counted."""

    RETRYABLE = {408, 429, 500, 502, 503, 504}

    def __init__(self, settings: dict, counters: Counters):
        self._s = settings
        self._counters = counters
        self._client = WmdClient(settings["server"], settings["token"], settings["http_timeout"], settings["map"])
        self._queue: collections.deque[tuple[str, bytes]] = collections.deque()
        self._cond = threading.Condition()
        self._stop_at: Optional[float] = None  # monotonic deadline once asked to stop
        self._down_since: Optional[float] = None
        self._down_log = Throttle(10.0)
        self._thread = threading.Thread(target=self._run, name="scan-sender", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def buffered(self) -> int:
        with self._cond:
            return len(self._queue)

    def enqueue(self, key: str, body: bytes) -> None:
        with self._cond:
            if push_bounded(self._queue, (key, body), self._s["buffer_size"]):
                self._counters.add("scans_dropped")
            self._cond.notify()

    def stop(self) -> None:
        """Posts what is buffered for at most drain_timeout seconds; the rest is counted as dropped."""
        with self._cond:
            self._stop_at = time.monotonic() + self._s["drain_timeout"]
            self._cond.notify_all()
        self._thread.join()
        self._client.close()

    def _stopped(self) -> bool:
        return self._stop_at is not None and (not self._queue or time.monotonic() >= self._stop_at)

    def _run(self) -> None:
        backoff = self._s["retry_initial"]
        while True:
            with self._cond:
                while not self._queue and self._stop_at is None:
                    self._cond.wait()
                if self._stopped():
                    if self._queue:
                        rospy.logwarn("%s: %d buffered scans not posted at exit", NODE_NAME, len(self._queue))
                    self._counters.add("scans_dropped", len(self._queue))
                    self._queue.clear()
                    return
                key, body = self._queue[0]
            outcome = self._post(key, body)
            if outcome == "retry":
                self._counters.add("post_retries")
                with self._cond:  # the back-off, cut short by the end of the drain at exit
                    limit = backoff if self._stop_at is None else min(backoff, self._stop_at - time.monotonic())
                    if limit > 0:
                        self._cond.wait(timeout=limit)
                backoff = min(backoff * 2.0, self._s["retry_max"])
                continue
            backoff = self._s["retry_initial"]
            with self._cond:
                self._queue.popleft()  # the head: push_bounded never drops it

    def _post(self, key: str, body: bytes) -> str:
        try:
            status, headers, data = self._client.request("POST", "/api/v1/scans", body, {"Idempotency-Key": key})
        except Unreachable as error:
            self._note_down(str(error))
            return "retry"
        if status in self.RETRYABLE:
            self._note_down(f"HTTP {status}")
            return "retry"
        if self._down_since is not None:
            rospy.loginfo("%s: wmd answers again after %.1f s", NODE_NAME, time.monotonic() - self._down_since)
            self._down_since = None
        if status == 200:
            self._counters.add("scans_posted")
            if headers.get("idempotent-replayed") == "true":
                self._counters.add("scans_replayed")  # applied before; the answer was lost on the way
            return "done"
        # Anything else (400, 401, 409, 413, ...) will not get better by trying again.
        self._counters.add("scans_rejected")
        rospy.logerr("%s: wmd refused a scan: %s", NODE_NAME, HttpError(status, data))
        return "done"

    def _note_down(self, why: str) -> None:
        if self._down_since is None:
            self._down_since = time.monotonic()
        if self._down_log.ready():
            rospy.logwarn("%s: wmd unavailable (%s); %d scans buffered, retrying", NODE_NAME, why, self.buffered())


# ---- wmd -> ROS: grids, markers, decisions -----------------------------------------------------------------


class WorldPublisher:
    """Polls wmd and republishes what moved: the grid layers when the grid revision moved (at most
    grid_max_rate a second), the markers when the map version moved (through ?since= deltas), and new
    decisions. A new server_instance (wmd restarted, maybe on another database) re-reads everything."""

    def __init__(self, settings: dict, counters: Counters):
        self._s = settings
        self._counters = counters
        self._client = WmdClient(settings["server"], settings["token"], settings["http_timeout"], settings["map"])
        self._stop = threading.Event()
        self._lock = threading.Lock()  # guards the state that status() reads
        self._layers = [layer.strip() for layer in settings["grid_layers"].split(",") if layer.strip()]
        for layer in self._layers:
            if layer not in GRID_LAYERS:
                raise ValueError(f"grid_layers: unknown layer {layer!r} (known: {', '.join(GRID_LAYERS)})")
        # numpy_msg: the grid's int8 array is serialised as one block (a 1280 x 1280 layer: 1 ms, not 60 ms); the
        # message on the wire is the plain OccupancyGrid.
        self._grid_type = numpy_msg(OccupancyGrid)
        self._grid_pubs = {
            layer: rospy.Publisher(settings["map_topic"] if layer == "bayes" else settings["ds_topic_prefix"] + layer,
                                   self._grid_type, queue_size=1, latch=True) for layer in self._layers}
        self._markers_pub = rospy.Publisher(settings["markers_topic"], MarkerArray, queue_size=1, latch=True)
        self._instance: Optional[str] = None
        self._reachable = False
        self._grid_revisions: dict[str, int] = {}
        self._last_grid_publish = -math.inf
        self._map_version: Optional[int] = None
        self._elements: dict[str, dict] = {}
        self._objects: dict[str, dict] = {}
        self._decision_seq: Optional[int] = None
        self._down_log = Throttle(10.0)
        self._thread = threading.Thread(target=self._run, name="world-publisher", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self._client.close()

    def status(self) -> dict:
        with self._lock:
            return {"wmd_reachable": self._reachable, "server_instance": self._instance,
                    "grid_revisions": dict(self._grid_revisions), "map_version": self._map_version,
                    "elements": len(self._elements), "objects": len(self._objects),
                    "edges": sum(len(o.get("edges", [])) for o in self._objects.values()),
                    "decision_seq": self._decision_seq}

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._poll_once()
                with self._lock:
                    self._reachable = True
            except (Unreachable, HttpError, ValueError) as error:
                with self._lock:
                    self._reachable = False
                if self._down_log.ready():
                    rospy.logwarn("%s: polling wmd failed: %s", NODE_NAME, error)
            self._stop.wait(self._s["poll_period"])

    def _poll_once(self) -> None:
        tiles = self._client.get_json("/api/v1/grid/tiles")
        if tiles.get("server_instance") != self._instance:
            self._new_instance(tiles.get("server_instance"))
        revision = tiles.get("revision", 0)
        if (self._layers and revision > 0 and revision != min(self._grid_revisions.values(), default=-1)
                and time.monotonic() - self._last_grid_publish >= 1.0 / self._s["grid_max_rate"]):
            self._publish_grids()
        self._poll_map()
        if self._s["log_decisions"]:
            self._poll_decisions()

    def _new_instance(self, instance: Optional[str]) -> None:
        health = self._client.get_json("/api/v1/health")
        last_seq = int(health.get("last_decision_seq", 0))
        with self._lock:
            if self._instance is not None:
                rospy.loginfo("%s: wmd restarted (instance %s -> %s): re-reading grid and map", NODE_NAME,
                              self._instance, instance)
            first_contact = self._instance is None and self._decision_seq is None
            self._instance = instance
            self._grid_revisions = {}
            self._map_version = None
            if first_contact:
                self._decision_seq = 0 if self._s["decisions_from_start"] else last_seq
            elif self._decision_seq is not None and last_seq < self._decision_seq:
                self._decision_seq = 0  # another database: its decisions are all new to us

    def _publish_grids(self) -> None:
        revisions = {}
        for layer in self._layers:
            try:
                grid = self._client.get_json(f"/api/v1/grid?layer={layer}&format=json")
            except HttpError as error:
                if error.status == 404:  # empty_grid: nothing observed yet
                    return
                raise
            message = self._grid_type()
            message.header.frame_id = self._s["map_frame"]
            message.header.stamp = rospy.Time.now()
            message.info.map_load_time = message.header.stamp
            message.info.resolution = float(grid["resolution"])
            message.info.width = int(grid["width"])
            message.info.height = int(grid["height"])
            # Row-major from the lower-left cell, like OccupancyGrid: the origin is that cell's corner.
            message.info.origin.position.x = float(grid["origin"][0])
            message.info.origin.position.y = float(grid["origin"][1])
            message.info.origin.orientation.w = 1.0
            message.data = occupancy_values(grid["data"])
            self._grid_pubs[layer].publish(message)
            revisions[layer] = int(grid["revision"])
        self._last_grid_publish = time.monotonic()
        with self._lock:
            self._grid_revisions = revisions
        self._counters.add("grids_published")

    def _poll_map(self) -> None:
        full = self._map_version is None
        if not full:
            try:
                answer = self._client.get_json(f"/api/v1/map?since={self._map_version}")
            except HttpError as error:
                if error.status not in (400, 410):  # 410: removals forgotten; 400: version from another run
                    raise
                full = True
            else:
                if answer.get("server_instance") != self._instance:
                    full = True
        if full:
            answer = self._client.get_json("/api/v1/map")
        if answer.get("server_instance") != self._instance:
            return  # wmd restarted between two requests: the next poll starts over
        changed = full or answer.get("version") != self._map_version
        with self._lock:
            if full:
                self._elements, self._objects = {}, {}
            for element_id in answer.get("removed", {}).get("elements", []):
                self._elements.pop(element_id, None)
            for object_id in answer.get("removed", {}).get("objects", []):
                self._objects.pop(object_id, None)
            self._elements.update((e["id"], e) for e in answer.get("elements", []))
            self._objects.update((o["id"], o) for o in answer.get("objects", []))
            self._map_version = answer.get("version")
        if changed:
            self._markers_pub.publish(self._markers())
            self._counters.add("markers_published")

    def _markers(self) -> MarkerArray:
        """One LINE_LIST per drawing category, after a DELETEALL so that categories that emptied disappear."""
        lines: dict[tuple[str, str], list] = collections.defaultdict(list)
        with self._lock:
            for obj in self._objects.values():
                attributes = obj.get("attributes", [])
                category = next((a for a in ("solid", "not_deformable") if a in attributes), "other")
                for edge in obj.get("edges", []):
                    lines[("plan", category)].append((edge["p0"], edge["p1"]))
            for element in self._elements.values():
                origin = element.get("origin", element.get("source"))  # "source": its name before wmd said "origin"
                category = origin if origin in ELEMENT_COLOURS else "other"
                lines[("elements", category)].append((element["p0"], element["p1"]))
        stamp = rospy.Time.now()
        markers = MarkerArray()
        clear = Marker(action=Marker.DELETEALL)
        clear.header.frame_id = self._s["map_frame"]
        markers.markers.append(clear)
        for marker_id, ((group, category), segments) in enumerate(sorted(lines.items())):
            marker = Marker(type=Marker.LINE_LIST, action=Marker.ADD, ns=f"{group}/{category}", id=marker_id)
            marker.header.frame_id = self._s["map_frame"]
            marker.header.stamp = stamp
            marker.pose.orientation.w = 1.0
            marker.scale.x = self._s["marker_width"]
            marker.color = colour((OBJECT_COLOURS if group == "plan" else ELEMENT_COLOURS)[category])
            for p0, p1 in segments:
                marker.points.append(Point(x=p0[0], y=p0[1], z=0.0))
                marker.points.append(Point(x=p1[0], y=p1[1], z=0.0))
            markers.markers.append(marker)
        return markers

    def _poll_decisions(self) -> None:
        while True:
            answer = self._client.get_json(f"/api/v1/decisions?since={self._decision_seq}&limit=1000")
            for d in answer.get("decisions", []):
                target = d.get("element") or d.get("object") or "-"
                rospy.loginfo("decision %d: %s %s (rule %s, %s)", d["seq"], d.get("action"), target, d.get("rule"),
                              d.get("observer") or d.get("source") or "-")
                self._counters.add("decisions_logged")
            with self._lock:
                self._decision_seq = max(self._decision_seq, int(answer.get("next", self._decision_seq)))
            if len(answer.get("decisions", [])) < 1000:
                return


# ---- the node ----------------------------------------------------------------------------------------------


COUNTERS = ("scans_received", "scans_placed", "scans_skipped_no_tf", "scans_posted", "scans_replayed",
            "scans_rejected", "scans_dropped", "post_retries", "grids_published", "markers_published",
            "decisions_logged")


class Bridge:
    def __init__(self, settings: dict):
        self._s = settings
        self.counters = Counters(COUNTERS)
        self._tf = TfFeed(settings["tf_cache"])
        self._sender = ScanSender(settings, self.counters)
        self._placer = ScanPlacer(settings, self._tf, self.counters, self._sender.enqueue)
        self._world = WorldPublisher(settings, self.counters)
        self._status_pub = rospy.Publisher(settings["status_topic"], String, queue_size=1, latch=True)
        self._stop = threading.Event()
        self._status_thread = threading.Thread(target=self._status_loop, name="status", daemon=True)

    def start(self) -> None:
        self._sender.start()
        self._placer.start()
        self._world.start()
        self._status_thread.start()
        rospy.loginfo("%s: %s -> %s as source %r, scans placed in frame %s", NODE_NAME, self._s["scan_topic"],
                      self._s["server"], self._s["observer"], self._s["map_frame"])

    def status(self) -> dict:
        status = self.counters.snapshot()
        status.update(waiting_for_tf=self._placer.waiting(), buffered=self._sender.buffered())
        status.update(self._world.status())
        return status

    def _status_loop(self) -> None:
        last_text, last_log = None, time.monotonic()
        while not self._stop.wait(0.5):
            text = json.dumps(self.status(), sort_keys=True)
            if text != last_text and not rospy.is_shutdown():
                self._status_pub.publish(String(data=text))
                last_text = text
            period = self._s["status_log_period"]
            if period > 0 and time.monotonic() - last_log >= period:
                rospy.loginfo("%s: status %s", NODE_NAME, text)
                last_log = time.monotonic()

    def stop(self) -> dict:
        """Stops taking scans, posts what is buffered (drain_timeout), and returns the final counters."""
        self._placer.stop()
        self._sender.stop()
        self._stop.set()
        self._status_thread.join()
        self._world.stop()
        self._tf.close()
        return self.status()


def main(argv: Optional[list[str]] = None) -> int:
    args = rospy.myargv(sys.argv if argv is None else argv)[1:]  # drops ROS remappings (__name:=, topic:=)
    cli = parse_command_line(args)
    rospy.init_node(NODE_NAME)
    try:
        settings = resolve_settings(cli)
        bridge = Bridge(settings)
    except ValueError as error:
        rospy.logfatal("%s: %s", NODE_NAME, error)
        return 2
    bridge.start()
    rospy.spin()
    final = bridge.stop()
    # rosout is gone once ROS shuts down: the summary goes to stdout, where roslaunch's output="screen" and
    # log files take it.
    print(f"{NODE_NAME}: final {json.dumps(final, sort_keys=True)}", flush=True)
    print(f"{NODE_NAME}: scans received {final['scans_received']}, posted {final['scans_posted']}, "
          f"skipped (no tf) {final['scans_skipped_no_tf']}, dropped {final['scans_dropped']}, "
          f"rejected {final['scans_rejected']}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
