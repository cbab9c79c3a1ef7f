"""An agent beside a ROS 2 robot: the robot is its body. Its pose from the robot's odometry, its command
as ``cmd_vel`` worked out as the unicycle body does (:func:`zswarm.control.body.unicycle_inputs`); a
robot whose odometry stops is held, and one whose agent stops is left stopped (docs/robots.md)."""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

from zswarm.errors import Failure
from zswarm.control import body as bodies
from zswarm.net.runspec import LEASE_S
from zswarm.ros import graph
from zswarm.ros.motion import Odom, read_pose, twist
from zswarm.ros.robots import TWIST, Robot
from zswarm.ros.wire import Attachment, Route, WireError


class RobotLink:
    """The driver of an agent's body when that body is a robot, owned by the agent alone. It publishes
    on ``session``; its odometry reaches :meth:`take` through the agent's inbound chain, from the
    subscription to :attr:`odom_key` that the agent's process declares (:mod:`agents.main`)."""

    def __init__(self, robot: Robot, route: Route, session, v_max: float, lookahead: float, rejections,
                 odom_timeout: float = 1.0, agent_id: int = 0, odom_lost: float = LEASE_S) -> None:
        self.robot, self.route, self.session, self.rejections = robot, route, session, rejections
        self.odom_timeout, self.odom_lost = odom_timeout, odom_lost
        self.held_since: float | None = None  # wall time of the last odometry before a silence it is held for
        self.regained = 0  # silences its odometry came back from
        self.spec = bodies.BodySpec("unicycle", min(robot.max_linear, v_max), robot.max_angular, lookahead)
        self.odom_key = route.key(robot.odom, robot.pose_type)
        self.publisher = session.declare_publisher(route.key(robot.cmd_vel, TWIST))
        self.pose: Odom | None = None  # in the world frame
        self.heard_at = -math.inf  # wall time of the last odometry taken in
        self.gid, self.sequence = os.urandom(16), 0
        self.sent = 0
        self.tokens = self._announce(agent_id) if route.attached else []

    def _announce(self, agent_id: int) -> list:
        """rmw_zenoh's liveliness tokens (:mod:`zswarm.ros.graph`): node ``zswarm_agent_<id>`` in the
        robot's namespace, publishing cmd_vel and subscribed to the robot's pose, for the ROS tools."""
        session, robot, route = self.session, self.robot, self.route
        zid, name, ns = str(session.info.zid()), f"zswarm_agent_{agent_id}", robot.namespace
        keys = [graph.node_token(route, zid, 0, ns, name),
                graph.topic_token(route, zid, 0, 1, "MP", ns, name, robot.cmd_vel, TWIST),
                graph.topic_token(route, zid, 0, 2, "MS", ns, name, robot.odom, robot.pose_type)]
        return [session.liveliness().declare_token(key) for key in keys]

    def take(self, payload: bytes, received: float) -> None:
        """An odometry (or PoseStamped) sample, delivered by the bridge."""
        try:
            odom = read_pose(self.route, self.robot.pose_type, payload)
        except WireError as exc:
            self.rejections.add(f"ros-{exc.reason}", f"from {self.robot.odom}: {exc}")
            return
        x, y, yaw = self.robot.to_world(odom.x, odom.y, odom.yaw)
        self.pose = Odom(x, y, yaw, odom.u, odom.omega, odom.stamp)
        self.heard_at = received

    def check(self, now: float) -> bool:
        """Whether the robot may be driven: its odometry is fresh. One silent for ``odom_timeout`` seconds
        is held (a zero Twist; False) until its odometry comes back, each said once on stderr; one silent
        for ``odom_lost`` seconds is stopped and its agent leaves (:class:`Failure`)."""
        if self.pose is None:  # none heard yet: the agent waits for the first
            return True
        silent, name = now - self.heard_at, self.robot.namespace
        if silent > self.odom_lost:
            self.stop()
            raise Failure(f"robot {name} sent no odometry for {self.odom_lost:g} s: "
                          f"sent it a zero Twist and left the swarm")
        if silent > self.odom_timeout:
            if self.held_since is None:
                self.held_since = self.heard_at
                print(f"robot {name}: no odometry for {self.odom_timeout:g} s: stopped it, waiting "
                      f"(its agent leaves after {self.odom_lost:g} s)", file=sys.stderr, flush=True)
            self.stop()
            return False
        if self.held_since is not None:
            print(f"robot {name}: odometry back after {self.heard_at - self.held_since:.2f} s: driving it again",
                  file=sys.stderr, flush=True)
            self.held_since = None
            self.regained += 1
        return True

    def drive(self, v_d: tuple[float, ...]) -> tuple[float, float]:
        """Send the Twist that tracks the desired velocity ``v_d`` from the robot's heading."""
        u, omega = bodies.unicycle_inputs(self.spec, np.array(self.pose.yaw), np.array(v_d, dtype=float))
        return self.send(float(u), float(omega))

    def send(self, u: float, omega: float) -> tuple[float, float]:
        u = max(-self.spec.v_max, min(self.spec.v_max, u))
        omega = max(-self.robot.max_angular, min(self.robot.max_angular, omega))
        self.sequence += 1
        attachment = Attachment(self.sequence, time.time_ns(), self.gid).encode() if self.route.attached else None
        self.publisher.put(twist(self.route, u, omega), attachment=attachment)
        self.sent += 1
        return u, omega

    def stop(self) -> None:
        """A zero Twist (the robot stands still until the next command)."""
        try:
            self.send(0.0, 0.0)
        except Exception:  # a closing session: the robot's own command timeout stops it
            pass

    def close(self) -> None:
        self.stop()
        for token in self.tokens:
            token.undeclare()
        self.publisher.undeclare()
