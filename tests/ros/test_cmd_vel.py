#!/usr/bin/env python3
"""End to end: ROS ``cmd_vel`` drives the simulated Servosila robot. A real roscore on a free port,
``wm-servosila-sim``, ``wm-servosila --command-udp`` and ``clients/ros/wm_cmd_vel.py``; the test publishes
``geometry_msgs/Twist`` with rospy, reads the simulator's true pose from its stdout, and checks that the robot moves
the way the Twist says (forward: x grows; positive angular.z: θ grows, counter-clockwise) and that it stops within
the bridge's command timeout (0.5 s) plus one control period (0.2 s) of the last message. 20 stop trials; the worst
and median latency are printed. Exits 77 (skipped) without ROS.
"""
import importlib
import json
import math
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

SKIP = 77
REPO = Path(__file__).resolve().parents[2]
BUILD = Path(os.environ.get("WM_BUILD_DIR", REPO / "build"))
TRIALS = int(os.environ.get("WM_CMD_VEL_TRIALS", "20"))
COMMAND_TIMEOUT_S = 0.5
CONTROL_PERIOD_S = 0.2


def free_port(kind=socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until(predicate, timeout_s: float, what: str, period_s: float = 0.005):
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(period_s)


class Truth:
    """The simulator's truth lines, each stamped with when this process read it."""

    def __init__(self, stream):
        self.lock = threading.Lock()
        self.latest: dict = {}
        self.thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self.thread.start()

    def _read(self, stream) -> None:
        for line in stream:
            if line.startswith("{"):
                value = json.loads(line)
                value["read_at"] = time.monotonic()
                with self.lock:
                    self.latest = value

    def now(self) -> dict:
        with self.lock:
            return dict(self.latest)

    def moving(self) -> bool:
        t = self.now()
        return bool(t) and (t["linear_mps"] != 0.0 or t["angular_radps"] != 0.0)


def main() -> int:
    for tool in ("/usr/bin/roscore",):
        if not os.access(tool, os.X_OK):
            print(f"skipped: {tool} not found")
            return SKIP
    try:
        for module in ("rospy", "rosgraph", "geometry_msgs.msg"):
            importlib.import_module(module)
    except ImportError as error:
        print(f"skipped: {error}")
        return SKIP
    import rosgraph
    import rospy
    from geometry_msgs.msg import Twist

    workdir = Path(tempfile.mkdtemp(prefix="wm-cmd-vel-"))
    ros_port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{ros_port}", ROS_HOSTNAME="127.0.0.1",
               ROS_HOME=str(workdir / "ros_home"), ROS_LOG_DIR=str(workdir / "ros_log"), PYTHONUNBUFFERED="1")
    env.pop("ROS_IP", None)
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_HOME", "ROS_LOG_DIR")})
    processes: list[subprocess.Popen] = []

    def spawn(name: str, argv: list[str], stdout=None) -> subprocess.Popen:
        out = stdout or open(workdir / f"{name}.out", "w")
        p = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=out, stderr=open(workdir / f"{name}.err", "w"),
                             env=env, start_new_session=True, text=True)
        processes.append(p)
        return p

    sim_port = free_port(socket.SOCK_DGRAM)
    command_port = free_port(socket.SOCK_DGRAM)
    try:
        spawn("roscore", ["/usr/bin/roscore", "-p", str(ros_port)])
        # The simulator's own watchdog is long, so that only a stop packet from the bridge stops it.
        sim = spawn("sim", [str(BUILD / "bin/wm-servosila-sim"), "--port", str(sim_port), "--telemetry-period", "0.1",
                            "--watchdog", "10", "--print-period", "0.005"], stdout=subprocess.PIPE)
        truth = Truth(sim.stdout)
        spawn("bridge", [str(BUILD / "bin/wm-servosila"), "--robot", f"127.0.0.1:{sim_port}", "--command-udp",
                         str(command_port), "--command-timeout", str(COMMAND_TIMEOUT_S)])
        wait_until(lambda: rosgraph.is_master_online(env["ROS_MASTER_URI"]), 30, "roscore", 0.1)
        spawn("wm_cmd_vel", [sys.executable, str(REPO / "clients/ros/wm_cmd_vel.py"),
                             f"_bridge:=127.0.0.1:{command_port}", "_topic:=/cmd_vel"])
        rospy.init_node("test_cmd_vel", anonymous=True, disable_signals=True)
        publisher = rospy.Publisher("/cmd_vel", Twist, queue_size=1, tcp_nodelay=True)
        wait_until(lambda: publisher.get_num_connections() > 0, 30, "wm_cmd_vel subscribed", 0.05)

        def drive(v: float, w: float, seconds: float) -> float:
            """Publishes at 10 Hz for `seconds`; the time of the last message."""
            end = time.monotonic() + seconds
            last = time.monotonic()
            while time.monotonic() < end:
                message = Twist()
                message.linear.x = v
                message.angular.z = w
                publisher.publish(message)
                last = time.monotonic()
                time.sleep(0.1)
            return last

        # Forward: x grows, θ stays.
        start = wait_until(truth.now, 10, "simulator truth")
        last = drive(0.3, 0.0, 1.5)
        wait_until(lambda: not truth.moving(), 2, "the stop after forward")
        after = truth.now()
        assert after["x_m"] - start["x_m"] > 0.3, (start, after)
        assert abs(after["theta_rad"] - start["theta_rad"]) < 1e-6, (start, after)
        # Positive angular.z: counter-clockwise, θ grows.
        before = truth.now()
        drive(0.0, 0.6, 1.0)
        wait_until(lambda: not truth.moving(), 2, "the stop after turning")
        turned = math.remainder(truth.now()["theta_rad"] - before["theta_rad"], 2 * math.pi)
        assert turned > 0.3, turned

        # Stop latency: the last Twist → the simulator's truth says stopped.
        latencies = []
        for trial in range(TRIALS):
            last = drive(0.3, 0.0 if trial % 2 else 0.4, 0.6)
            assert truth.moving(), f"trial {trial}: moving while published"
            stopped = wait_until(lambda: None if truth.moving() else truth.now(), 3, f"trial {trial}: stop")
            latencies.append(stopped["read_at"] - last)
            time.sleep(0.2)
        bound = COMMAND_TIMEOUT_S + CONTROL_PERIOD_S
        print(f"cmd_vel stop latency over {TRIALS} trials (last Twist -> simulator stopped): "
              f"median {statistics.median(latencies) * 1000:.0f} ms, worst {max(latencies) * 1000:.0f} ms "
              f"(bound {bound * 1000:.0f} ms)")
        assert max(latencies) < bound, latencies
        print("ok")
        return 0
    finally:
        for p in reversed(processes):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()


if __name__ == "__main__":
    sys.exit(main())
