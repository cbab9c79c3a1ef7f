"""Stand-in ROS 2 robots: differential-drive robots that speak the wire a real one does, so that a
deployment can be rehearsed and tested without ROS 2.

Each robot integrates unicycle dynamics at ``rate`` Hz (50: a TurtleBot's odometry rate), clips every
command to its forward-speed and turn-rate limits and to its wheels' speed limit, publishes
nav_msgs/msg/Odometry on ``<namespace>/odom`` (with rmw_zenoh's attachment on that route), and takes
geometry_msgs/msg/Twist from ``<namespace>/cmd_vel``. When commands stop for ``cmd_timeout`` seconds it
stops, as a robot's base controller does. A command that does not decode is counted by reason and
dropped; it never stops the simulator.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from dataclasses import dataclass, field

from zswarm.control.body import wrap
from zswarm.ros.motion import Odom, odometry, read_twist
from zswarm.ros.robots import ODOMETRY, TWIST, Robot
from zswarm.ros.wire import Attachment, Route, WireError
from zswarm.stopping import StopSignal

WHEEL_BASE = 0.16  # m, a TurtleBot 3 Burger's
#: A pause of the robots (their process starved of CPU) longer than this is said on stderr.
PAUSE_SAID_S = 0.5


@dataclass
class SimRobot:
    """One stand-in robot: its pose in its odom frame, the last command and when it came, its limits."""

    robot: Robot
    route: Route
    pose: Odom
    cmd_timeout: float = 0.25
    wheel_max: float | None = None  # m/s at each wheel (default: the robot's max_linear)
    command: tuple[float, float, float] = (0.0, 0.0, -math.inf)  # (u, omega, wall time received)
    rejected: dict[str, int] = field(default_factory=dict)
    commands: int = 0
    idle: bool = False  # stopped for want of commands, and said so
    gid: bytes = field(default_factory=lambda: os.urandom(16))
    sequence: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self, payload: bytes, now: float) -> None:
        """A cmd_vel sample (on a Zenoh thread)."""
        try:
            u, omega = read_twist(self.route, payload)
        except WireError as exc:
            with self.lock:
                self.rejected[exc.reason] = self.rejected.get(exc.reason, 0) + 1
            return
        with self.lock:
            self.command = (u, omega, now)
            self.commands += 1

    def inputs(self, now: float) -> tuple[float, float]:
        """The forward speed and turn rate it drives with now: the last command while fresh, clipped to
        its limits and its wheels'; zero once commands stopped."""
        u, omega, at = self.command
        if now - at > self.cmd_timeout:
            if at > -math.inf and not self.idle:  # said once a silence, as a base controller logs it
                self.idle = True
                print(f"robot-sim: {self.robot.namespace} stopped: no command for {self.cmd_timeout:g} s",
                      file=sys.stderr, flush=True)
            return 0.0, 0.0
        self.idle = False
        r = self.robot
        u = max(-r.max_linear, min(r.max_linear, u))
        omega = max(-r.max_angular, min(r.max_angular, omega))
        wheel = self.wheel_max if self.wheel_max is not None else r.max_linear
        fastest = max(abs(u - omega * WHEEL_BASE / 2.0), abs(u + omega * WHEEL_BASE / 2.0))
        if fastest > wheel:  # both wheels slowed by one factor: the path's curvature is kept
            u, omega = u * wheel / fastest, omega * wheel / fastest
        return u, omega

    def step(self, dt: float, now: float) -> Odom:
        u, omega = self.inputs(now)
        p = self.pose
        yaw = p.yaw + omega * dt
        self.pose = Odom(p.x + u * math.cos(p.yaw) * dt, p.y + u * math.sin(p.yaw) * dt,
                         float(wrap(yaw)), u, omega, now)
        return self.pose

    def odometry(self) -> tuple[bytes, bytes | None]:
        """The odometry sample and, on rmw_zenoh, its attachment."""
        name = self.robot.namespace.strip("/")
        payload = odometry(self.route, self.pose, f"{name}/odom", f"{name}/base_footprint")
        self.sequence += 1
        attachment = (Attachment(self.sequence, time.time_ns(), self.gid).encode() if self.route.attached else None)
        return payload, attachment


def start_pose(robot: Robot, world: tuple[float, float], facing: tuple[float, float]) -> Odom:
    """A robot at the world point ``world`` facing ``facing``, in its odom frame."""
    yaw = math.atan2(facing[1] - world[1], facing[0] - world[0])
    x, y, yaw = robot.to_odom(world[0], world[1], yaw)
    return Odom(x, y, yaw, stamp=time.time())


def run(session, route: Route, robots: list[SimRobot], rate: float, stop: StopSignal | threading.Event,
        duration: float | None = None, idle_exit: float | None = None) -> str:
    """Drive ``robots`` on ``session`` at ``rate`` Hz until ``stop`` is set, ``duration`` passes, or (with
    ``idle_exit``) the robots were commanded and then no command came for ``idle_exit`` seconds (the run
    that drove them has ended). Returns why it stopped."""
    declared = []
    publishers = []
    for r in robots:
        publishers.append(session.declare_publisher(route.key(r.robot.odom, ODOMETRY)))
        declared.append(session.declare_subscriber(
            route.key(r.robot.cmd_vel, TWIST),
            lambda sample, r=r: r.take(sample.payload.to_bytes(), time.time())))
    period = 1.0 / rate
    began = next_tick = time.monotonic()
    try:
        while not stop.is_set():
            if duration is not None and time.monotonic() - began >= duration:
                return f"{duration:g} s passed"
            now = time.time()
            if idle_exit is not None:
                last = max(r.command[2] for r in robots)
                if last > -math.inf and now - last > idle_exit:
                    return f"no command for {idle_exit:g} s: the run that drove the robots has ended"
            for r, pub in zip(robots, publishers):
                r.step(period, now)
                payload, attachment = r.odometry()
                pub.put(payload, attachment=attachment)
            ticked = time.monotonic()
            if ticked - next_tick > PAUSE_SAID_S:  # its agents hold their robots until odometry comes back
                print(f"robot-sim: starved of CPU, the robots paused {ticked - next_tick:.2f} s", file=sys.stderr,
                      flush=True)
            # starved of CPU, the robots pause rather than leap: steps made up in a burst would move an
            # agent's pose farther in one of its ticks than it can go, and its neighbours refuse that (jump)
            next_tick = max(next_tick + period, ticked)
            stop.wait(max(next_tick - time.monotonic(), 0.0))
        return "stopped"
    finally:
        for d in (*declared, *publishers):
            d.undeclare()
