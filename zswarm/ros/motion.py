"""The three ROS 2 messages a robot and its agent exchange, as plain numbers: the robot's pose (from
nav_msgs/msg/Odometry or geometry_msgs/msg/PoseStamped) and its command (geometry_msgs/msg/Twist).
The messages themselves are rosbags' (:mod:`zswarm.ros.wire`)."""

from __future__ import annotations

import math
from typing import NamedTuple

from zswarm.ros.robots import ODOMETRY, TWIST
from zswarm.ros.wire import Route, WireError


class Odom(NamedTuple):
    """A robot's pose in its odom frame, its forward speed and turn rate, and the message's stamp (s)."""

    x: float
    y: float
    yaw: float
    u: float = 0.0
    omega: float = 0.0
    stamp: float = 0.0


def yaw_of(q) -> float:
    """The yaw (rotation about z) of a quaternion message."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def quaternion(types, yaw: float | None):
    """geometry_msgs/msg/Quaternion of a rotation by ``yaw`` about z (None: the identity)."""
    half = 0.0 if yaw is None else yaw / 2.0
    return types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def _time(types, seconds: float):
    sec = math.floor(seconds)
    return types["builtin_interfaces/msg/Time"](sec=int(sec), nanosec=int((seconds - sec) * 1e9))


def odometry(route: Route, odom: Odom, frame: str, child: str) -> bytes:
    """nav_msgs/msg/Odometry of a robot at ``odom`` (its covariances zero)."""
    import numpy as np

    t = route.types()
    header = t["std_msgs/msg/Header"](stamp=_time(t, odom.stamp), frame_id=frame)
    point = t["geometry_msgs/msg/Point"](x=odom.x, y=odom.y, z=0.0)
    pose = t["geometry_msgs/msg/PoseWithCovariance"](pose=t["geometry_msgs/msg/Pose"](position=point,
                                                                                     orientation=quaternion(t, odom.yaw)),
                                                     covariance=np.zeros(36))
    twist = t["geometry_msgs/msg/TwistWithCovariance"](twist=_twist(t, odom.u, odom.omega), covariance=np.zeros(36))
    return route.encode(ODOMETRY, t[ODOMETRY](header=header, child_frame_id=child, pose=pose, twist=twist))


def _twist(t, u: float, omega: float):
    v3 = t["geometry_msgs/msg/Vector3"]
    return t[TWIST](linear=v3(x=float(u), y=0.0, z=0.0), angular=v3(x=0.0, y=0.0, z=float(omega)))


def twist(route: Route, u: float, omega: float) -> bytes:
    """geometry_msgs/msg/Twist: forward speed ``u`` (linear.x) and turn rate ``omega`` (angular.z)."""
    return route.encode(TWIST, _twist(route.types(), u, omega))


def read_twist(route: Route, payload: bytes) -> tuple[float, float]:
    """(linear.x, angular.z) of a Twist; :class:`WireError` if it is not one, or not finite."""
    m = route.decode(TWIST, payload)
    u, omega = float(m.linear.x), float(m.angular.z)
    if not (math.isfinite(u) and math.isfinite(omega)):
        raise WireError("cdr", "a Twist with a non-finite speed")
    return u, omega


def read_pose(route: Route, msgtype: str, payload: bytes) -> Odom:
    """A robot's pose from its Odometry (with its speeds) or PoseStamped; :class:`WireError` else."""
    m = route.decode(msgtype, payload)
    pose = m.pose.pose if msgtype == ODOMETRY else m.pose
    odom = Odom(float(pose.position.x), float(pose.position.y), yaw_of(pose.orientation),
                float(m.twist.twist.linear.x) if msgtype == ODOMETRY else 0.0,
                float(m.twist.twist.angular.z) if msgtype == ODOMETRY else 0.0,
                m.header.stamp.sec + m.header.stamp.nanosec * 1e-9)
    if not all(math.isfinite(v) for v in odom):
        raise WireError("cdr", f"a {msgtype} with a non-finite pose")
    return odom
