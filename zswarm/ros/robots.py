"""The robots file: which agent drives which ROS 2 robot, and how its topics are reached (every field:
``examples/robots.toml``, docs/robots.md). Every mistake is one :class:`~zswarm.errors.UsageError`
line naming the file and the field."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from zswarm.errors import UsageError
from zswarm.files import read_toml
from zswarm.control.body import wrap
from zswarm.ros.wire import Route

ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TWIST = "geometry_msgs/msg/Twist"
TOP_KEYS = {"route", "distro", "domain_id", "bridge_namespace", "robot"}
ROBOT_KEYS = {"id", "namespace", "odom_origin", "max_linear", "max_angular", "pose_topic"}


@dataclass(frozen=True)
class Robot:
    """One robot: the agent that drives it, its namespace, where its odom frame lies in the world
    (x, y, yaw), its speed limits, and the topic its pose comes from (odom unless ``pose_topic``)."""

    id: int
    namespace: str
    odom_origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_linear: float = 1.0
    max_angular: float = 4.0
    pose_topic: str = ""

    def topic(self, name: str) -> str:
        return f"{self.namespace.rstrip('/')}/{name}"

    @property
    def odom(self) -> str:
        return self.pose_topic or self.topic("odom")

    @property
    def pose_type(self) -> str:
        return POSE_STAMPED if self.pose_topic else ODOMETRY

    @property
    def cmd_vel(self) -> str:
        return self.topic("cmd_vel")

    def to_world(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        """A pose in the robot's odom frame, in the world's."""
        ox, oy, oyaw = self.odom_origin
        c, s = math.cos(oyaw), math.sin(oyaw)
        return ox + c * x - s * y, oy + s * x + c * y, float(wrap(yaw + oyaw))

    def to_odom(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        """A world pose in the robot's odom frame (the inverse of :meth:`to_world`)."""
        ox, oy, oyaw = self.odom_origin
        c, s = math.cos(oyaw), math.sin(oyaw)
        dx, dy = x - ox, y - oy
        return c * dx + s * dy, -s * dx + c * dy, float(wrap(yaw - oyaw))


@dataclass(frozen=True)
class RobotsFile:
    """A robots file: the route its robots are reached by, and the robots by agent id."""

    route: Route
    robots: tuple[Robot, ...]

    def robot(self, agent: int) -> Robot | None:
        return next((r for r in self.robots if r.id == agent), None)


def _number(where: str, name: str, value: Any, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not lo < value <= hi or math.isnan(value):
        raise UsageError(f"{where}: {name} must be a number in ({lo:g}, {hi:g}] (got {value!r})")
    return float(value)


def _robot(where: str, entry: Any) -> Robot:
    if not isinstance(entry, dict):
        raise UsageError(f"{where}: each [[robot]] must be a table")
    unknown = set(entry) - ROBOT_KEYS
    if unknown:
        raise UsageError(f"{where}: unknown field {sorted(unknown)[0]!r} (known: {', '.join(sorted(ROBOT_KEYS))})")
    rid, ns = entry.get("id"), entry.get("namespace")
    if isinstance(rid, bool) or not isinstance(rid, int) or rid < 0:
        raise UsageError(f"{where}: id must be an agent id >= 0 (got {rid!r})")
    if not isinstance(ns, str) or not ns.startswith("/") or " " in ns:
        raise UsageError(f"{where}: namespace must be a ROS namespace such as \"/robot{rid}\" (got {ns!r})")
    origin = entry.get("odom_origin", [0.0, 0.0, 0.0])
    if (not isinstance(origin, list) or len(origin) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in origin)):
        raise UsageError(f"{where}: odom_origin must be [x, y, yaw] (got {origin!r})")
    pose_topic = entry.get("pose_topic", "")
    if not isinstance(pose_topic, str) or (pose_topic and not pose_topic.startswith("/")):
        raise UsageError(f"{where}: pose_topic must be a ROS topic name such as \"/robot{rid}/pose\" (got {pose_topic!r})")
    return Robot(rid, ns, tuple(float(v) for v in origin),
                 _number(where, "max_linear", entry.get("max_linear", 1.0), 0.0, 100.0),
                 _number(where, "max_angular", entry.get("max_angular", 4.0), 0.0, 100.0), pose_topic)


def robots_for_run(path: Path, scenario: str, dimensions: int, clock: str, time_scale: float) -> RobotsFile:
    """A robots file the run can use: readable and valid, and a run ROS 2 ground robots can drive in
    (2-D, free clock, real time). The one home of this rule: the launcher checks it before any process
    starts, and an agent started by hand checks it again before it opens a session."""
    robots = load_robots(path)
    if dimensions != 2:
        raise UsageError(f"--robots drives ROS 2 ground robots: {scenario} is 3-D")
    if clock != "free" or time_scale != 1.0:
        raise UsageError("--robots needs the free clock at --time-scale 1: a robot moves in real time")
    return robots


def load_robots(path: Path) -> RobotsFile:
    """Read and check a robots file."""
    where = str(path)
    data = read_toml(path, "robots file")
    unknown = set(data) - TOP_KEYS
    if unknown:
        raise UsageError(f"{where}: unknown field {sorted(unknown)[0]!r} (known: {', '.join(sorted(TOP_KEYS))})")
    ns = data.get("bridge_namespace", "")
    if not isinstance(ns, str):
        raise UsageError(f"{where}: bridge_namespace must be a string")
    try:
        route = Route(data.get("route", "rmw_zenoh"), data.get("distro", "jazzy"), data.get("domain_id", 0), ns)
    except UsageError as exc:
        raise UsageError(f"{where}: {exc}") from None
    entries = data.get("robot")
    if not isinstance(entries, list) or not entries:
        raise UsageError(f"{where}: no [[robot]] entries (each maps an agent id to a robot's namespace)")
    robots = tuple(_robot(where, e) for e in entries)
    for field in ("id", "namespace"):
        seen = [getattr(r, field) for r in robots]
        twice = next((v for v in seen if seen.count(v) > 1), None)
        if twice is not None:
            raise UsageError(f"{where}: two robots have {field} {twice!r}")
    return RobotsFile(route, robots)
