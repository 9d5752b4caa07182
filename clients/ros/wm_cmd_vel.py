#!/usr/bin/python3
"""Forwards a ROS 1 ``geometry_msgs/Twist`` topic (``cmd_vel``) to wm-servosila, so that teleop_twist_keyboard,
move_base or any other velocity source drives a Servosila robot.

Each Twist becomes one UDP datagram ``"v w\\n"`` (``linear.x`` m/s, ``angular.z`` rad/s counter-clockwise) to the
bridge's ``--command-udp`` port. Nothing is repeated here: the bridge stops the robot when no command came for its
``--command-timeout`` (0.5 s), so a publisher that stops, hangs or dies stops the robot. Velocity sources must
publish continuously (move_base does, at its controller frequency; teleop_twist_keyboard publishes on every key
press and key repeat). Limits are the bridge's (it clamps); here a non-finite component is sent as such and the
bridge makes it a stop.

Parameters (private): ``~bridge`` (``127.0.0.1:47000``), ``~topic`` (``cmd_vel``). The counts of forwarded and
failed sends go to rosout at exit.
"""
import math
import socket
import sys
from typing import Tuple


def twist_line(linear_x: float, angular_z: float) -> bytes:
    """The bridge's command text for a Twist's ``linear.x`` and ``angular.z``: ``repr`` keeps nan/inf visible."""
    def text(v: float) -> str:
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(float(v))
    return f"{text(linear_x)} {text(angular_z)}\n".encode("ascii")


def parse_address(text: str) -> Tuple[str, int]:
    """``HOST:PORT`` or ``[IPV6]:PORT``; the host without brackets, as sendto wants it."""
    host, _, port = text.rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"~bridge: expected HOST:PORT, got {text!r}")
    return host, int(port)


def main() -> int:
    import rospy
    from geometry_msgs.msg import Twist

    rospy.init_node("wm_cmd_vel")
    address = parse_address(rospy.get_param("~bridge", "127.0.0.1:47000"))
    topic = rospy.get_param("~topic", "cmd_vel")
    sock = socket.socket(socket.AF_INET6 if ":" in address[0] else socket.AF_INET, socket.SOCK_DGRAM)
    counts = {"forwarded": 0, "send_errors": 0}

    def on_twist(message: Twist) -> None:
        try:
            sock.sendto(twist_line(message.linear.x, message.angular.z), address)
            counts["forwarded"] += 1
        except OSError as error:
            counts["send_errors"] += 1
            rospy.logwarn_throttle(5.0, f"wm_cmd_vel: cannot send to {address[0]}:{address[1]}: {error}")

    rospy.Subscriber(topic, Twist, on_twist, queue_size=1, tcp_nodelay=True)
    rospy.loginfo(f"wm_cmd_vel: {rospy.resolve_name(topic)} -> udp {address[0]}:{address[1]}")
    rospy.spin()
    rospy.loginfo(f"wm_cmd_vel: forwarded {counts['forwarded']}, send errors {counts['send_errors']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
