"""One agent: an asyncio process that senses its neighbours over Zenoh and descends its potential.

It decides from its own state, the poses of the agents within its sensing radius (published into the
spatial cells its sensing disc overlaps), the obstacles within its radius (asked of the world's
queryable, never the whole map) and the prey it observes (:mod:`agents.sensing`). Nothing else
reaches it.

Clocks:
- ``free`` (:mod:`agents.free`, no event loop): a wall-clock timer at 1/period; each tick uses the
  freshest neighbour data younger than the staleness limit. Late ticks are counted and never queued up.
- ``lockstep`` (here, on an asyncio loop): the world's tick k+1 (sent once the world has every pose of step k) makes the agent
  compute step k from the step-k poses of its neighbours, move, and publish its pose of step k+1.
  That is the reference simulator's step, so the trajectories agree.
"""

from __future__ import annotations

import asyncio
import math
import time
from array import array
from typing import Any

import numpy as np

from agents.outreach import Outreach
from agents.sensing import Body, Sensing
from zswarm.control.step import Acted, ControlStep
from zswarm.laws.bound import LawFailed
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge
from zswarm.net.injector import FaultInjector
from zswarm.net.runspec import WORLD_SILENT_S, RunSpec

STATS_PERIOD = 1.0


def starting_body(control: ControlStep, start: tuple[float, ...], facing: tuple[float, ...]) -> Body:
    """The agent's own state at ``start``, at rest (a headed body facing ``facing``, the prey's start)."""
    heading = float(control.start(np.array([[start]], dtype=float), np.asarray(facing, dtype=float)).heading[0, 0])
    z = (float(start[2]), 0.0) if len(start) == 3 else (None, None)
    return Body(float(start[0]), float(start[1]), heading=None if math.isnan(heading) else heading, z=z[0], vz=z[1])


class Agent:
    """Control, the pose it publishes and the lockstep clock. Everything it uses is built before it and
    handed in (:class:`agents.main.Process` wires them, top to bottom): its body, what it senses, what
    it asks of the network, the bridge, the compiled law, and optionally the fault injector on its
    inbound links and the ROS 2 robot that drives its body."""

    def __init__(self, spec: RunSpec, agent_id: int, body: Body, sensing: Sensing, reach: Outreach, bridge: Bridge,
                 control: ControlStep, injector: FaultInjector | None = None, robot: Any = None,
                 staleness: float = 0.5, lockstep_wait: float = 0.25, track: array | None = None) -> None:
        """``control``: its control step (:func:`zswarm.control.step.control_step` for its own id);
        ``track``: where every pose it sends is kept as (stamp, position...) for ``--tracks``."""
        self.spec, self.id, self.body, self.sensing, self.reach, self.bridge = spec, agent_id, body, sensing, reach, bridge
        self.control, self.injector, self.robot, self.track = control, injector, robot, track
        self.law = control.groups[0].law
        self.law_failure: str | None = None  # the law's failure, in one line: the agent brakes and leaves
        self.world_timeout = WORLD_SILENT_S  # it leaves once nothing came from the world for this long
        self.world_lost = False
        self.keys = spec.keys
        self.dt = spec.scenario.dt
        self.v_max = spec.scenario.params.swarm.v_max
        # how far ahead of a unicycle's axle the filter acts (its neighbours' poses carry their headings)
        self.lookahead = spec.scenario.params.body.lookahead
        self.counters = sensing.counters
        self.staleness, self.lockstep_wait = staleness, lockstep_wait
        self.seq = 0
        self.safety_flag = 0  # what the filter did this tick (messages.SAFETY_FLAGS), sent with the pose
        self.pose_cell: tuple[int, ...] | None = None
        self.pose_key = ""  # the key of its pose in that cell
        self.queryable: Any = None
        self.publisher: Any = None
        self.stats_publisher: Any = None  # declared at the first stats message (a put on a key resolves it each time)
        self.member: Any = None  # its member token in the cell it is in (keys.member)
        self.latest_reply: tuple[str, bytes] | None = None
        self.replies_by_step: dict[int, tuple[str, bytes]] = {}
        self.prey_by_step: dict[int, tuple[float, ...]] = {}
        self.stop = asyncio.Event()

    # --- control ---------------------------------------------------------------------------------------

    def move(self, goal: tuple[float, ...], step: int | None = None) -> None:
        """One control step (:meth:`zswarm.control.step.ControlStep.one`) from what it senses: its law's
        command, through the safety filter, and its body's step under it, or, beside a robot, the command
        sent to the robot as a Twist (a silent robot is held stopped, and one silent too long makes the agent leave:
        :meth:`agents.robot_link.RobotLink.check`). ``step``: the lockstep step whose poses it steers on
        (None: free, the newest). A law that raises or answers with something other than a velocity
        leaves the agent braking (:attr:`law_failure` says why, in one line; the clock loops end the
        process on it)."""
        if self.robot is not None and not (self.robot.check(time.time()) and self.follow_robot()):
            return
        filtered = self.control.filter is not None
        late = step is None and filtered and self.late_world()
        neighbours, guarded = self.sensing.sense(step, self.staleness, self.spec.time_scale, self.dt,
                                                 self.lookahead, guard=filtered and not late)
        b = self.body
        try:
            one = self.control.one(b.position, b.velocity, b.heading, neighbours, self.obstacles_near(), goal,
                                   guarded, late)
        except LawFailed as exc:
            self.law_failure = str(exc)
            b.vx = b.vy = 0.0
            b.vz = None if b.z is None else 0.0
            if self.robot is not None:
                self.robot.drive((0.0, 0.0))
            return
        if filtered:
            self.count(one.acted)
        if self.robot is not None:
            self.robot.drive(one.command)
            return
        (b.x, b.y, *z), (b.vx, b.vy, *vz) = one.position, one.velocity
        if z:
            b.z, b.vz = z[0], vz[0]
        b.heading = one.heading

    def follow_robot(self) -> bool:
        """Beside a robot: its body is where the robot's odometry says (False: none heard yet)."""
        pose, b = self.robot.pose, self.body
        if pose is None:
            return False
        b.x, b.y, b.heading = pose.x, pose.y, pose.yaw
        b.vx, b.vy = pose.u * math.cos(pose.yaw), pose.u * math.sin(pose.yaw)
        return True

    def late_world(self) -> bool:
        """The newest prey position it heard is older than the filter's data-age bound: everything it
        hears is that late (a machine or network far behind, a lost router), so a neighbour that came
        close since may not have been heard at all. The filter cannot bound that; the agent brakes."""
        stamp = self.sensing.prey_stamp
        (_, safety), = self.control.filter.groups
        return stamp is not None and (time.time() - stamp) * self.spec.time_scale + self.dt > safety.max_age

    def count(self, done: Acted | None) -> None:
        """What the safety filter did this tick, in its stats (and the flag its pose carries)."""
        c = self.counters
        stalled = done is not None and done.stalled
        if done is not None:
            c.interventions += done.acted
            c.stalled_ticks += stalled
            c.braked_ticks += done.braked
        self.safety_flag = 0 if done is None else done.flag
        c.stalled_run = c.stalled_run + 1 if stalled else 0
        c.stalled_long |= c.stalled_run * self.dt >= 1.0

    def obstacles_near(self) -> list[tuple[float, ...]]:
        """The obstacles its law may use this tick: each within the sensing radius, as (centre..., radius)."""
        obstacles = self.sensing.obstacles
        if not obstacles:
            return obstacles
        here, radius = self.body.position, self.sensing.radius
        dims = len(here)
        return [o for o in obstacles if math.dist(here, o[:dims]) - o[dims] <= radius]

    # --- outbound --------------------------------------------------------------------------------------

    def publish_pose(self, step: int) -> None:
        """Into the cell it is in, through that cell's declared publisher; its queryable there answers
        with the latest pose (and, in lockstep, the pose of a step)."""
        b = self.body
        cell = self.keys.cell(*b.position)
        moved = cell != self.pose_cell
        if moved:
            self.pose_key = self.keys.pose(cell, self.id)
        key = self.pose_key
        self.seq += 1
        stamp = time.time()
        payload = msg.encode_pose(self.id, self.seq, stamp, step, b.x, b.y, b.vx, b.vy, b.heading, b.z, b.vz,
                                  self.safety_flag, self.sensing.node)
        if self.track is not None:
            self.track.extend((stamp, b.x, b.y) if b.z is None else (stamp, b.x, b.y, b.z))
        self.latest_reply = (key, payload)
        if step >= 0:
            self.replies_by_step = {s: r for s, r in self.replies_by_step.items() if s > step - 3}
            self.replies_by_step[step] = (key, payload)
        if moved:
            # the new cell's token before the old one goes: a neighbour never sees it in no cell
            old_member = self.member
            self.member = self.bridge.session.liveliness().declare_token(self.keys.member(cell, self.id))
            for old in (self.queryable, self.publisher, old_member):
                if old is not None:
                    old.undeclare()
            self.queryable = self.bridge.queryable(key, self._answer)
            self.publisher = self.bridge.session.declare_publisher(key, encoding=msg.POSE_ENCODING)
            self.pose_cell = cell
        self.publisher.put(payload)
        self.counters.sent += 1

    def _answer(self, params: dict[str, str]) -> list[tuple[str, bytes]]:
        """Runs on a Zenoh thread: only atomic reads. ``?step=k`` asks for the pose of step k."""
        reply = self.latest_reply
        if "step" in params:
            try:
                reply = self.replies_by_step.get(int(params["step"]))
            except ValueError:
                return []
        return [reply] if reply is not None else []

    def stats(self, final: bool = False) -> bytes:
        faults = self.injector.faults if self.injector is not None else None
        injected = (faults.dropped, faults.passed) if faults is not None else (0, 0)
        return msg.encode(self.counters.stats(self.id, self.spec.period, injected, final))

    def publish_stats_now(self) -> None:
        """The stats message, and a new window for the per-period figures (queue, tick lag)."""
        if self.stats_publisher is None:
            self.stats_publisher = self.bridge.session.declare_publisher(self.keys.stats(self.id), encoding=msg.ENCODING)
        self.stats_publisher.put(self.stats())
        self.counters.new_window()

    async def publish_stats(self) -> None:
        """Lockstep: the stats message every STATS_PERIOD seconds, until stopped."""
        while not self.stop.is_set():
            try:
                await asyncio.wait_for(self.stop.wait(), STATS_PERIOD)
            except asyncio.TimeoutError:
                self.publish_stats_now()

    def world_gone(self, now: float) -> bool:
        """Nothing (prey, ticks) came from the world for ``world_timeout`` seconds since its clock started
        (``now``: ``time.monotonic()``): it ended or died, its final tick unheard here; ``world_lost`` says so."""
        heard = self.sensing.world_heard
        self.world_lost = heard is not None and now - heard >= self.world_timeout
        return self.world_lost

    # --- the two clocks --------------------------------------------------------------------------------

    async def run_lockstep(self) -> None:
        s = self.sensing
        while not self.stop.is_set():
            tick_task = asyncio.ensure_future(s.ticks.get())
            stop_task = asyncio.ensure_future(self.stop.wait())
            done, _ = await asyncio.wait({tick_task, stop_task}, timeout=self.world_timeout,
                                         return_when=asyncio.FIRST_COMPLETED)
            if not done:  # no tick for a while: the world is gone once nothing at all came for that long
                tick_task.cancel()
                stop_task.cancel()
                if self.world_gone(time.monotonic()):
                    return
                continue
            if tick_task not in done:
                tick_task.cancel()
                return
            stop_task.cancel()
            tick = tick_task.result()
            if tick.final:
                self.stop.set()
                return
            self.prey_by_step[tick.step] = tick.position
            self.counters.ticks += 1
            while self.body.step < tick.step:  # tick k: every pose of step k-1 is out; do step k-1
                k = self.body.step
                await self.reach.await_step_poses(k, self.lockstep_wait)
                await self.reach.refresh_obstacles()
                self.move(self.prey_by_step.get(k, tick.position), k)
                self.body.step += 1
                self.prey_by_step.pop(k - 2, None)
            await self.reach.update_cells()
            self.publish_pose(self.body.step)
            if self.law_failure is not None:  # braked and said where: the process ends on it
                return
