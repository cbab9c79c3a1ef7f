"""What one agent senses: the neighbours within its radius, the obstacles near it and the prey.

This is the inbound end of the agent: it takes every sample in (the last link of the chain Zenoh ->
bridge -> fault injector -> here, built before the bridge, :mod:`agents.main`) and says which
neighbours the law may use. It holds no transport: what the agent asks of the network (the cells
to listen to, the obstacle queries, the latency probe's subscription) is :mod:`agents.outreach`.

Neighbours' poses arrive from the spatial cells its sensing disc (grown by 2 v_max dt) overlaps and
pass the shared acceptance rules of :class:`~zswarm.net.poses.PoseTable`. Obstacles come from the
world's answers (:mod:`agents.obstacle_view`). Only agents that hold a liveliness token are used as
neighbours. The transport latency is timed on one of them (:mod:`agents.probe`).
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass

import numpy as np

from agents.counters import Counters
from agents.guard import Near, choose
from agents.membership import Membership
from agents.obstacle_view import ObstacleView
from agents.probe import LatencyProbe
from zswarm.swarm.faults import OBSTACLE_SOURCE, PREY_SOURCE
from zswarm.net import messages as msg
from zswarm.net.bridge import Inbound
from zswarm.net.poses import PoseTable, Rejections, max_step
from zswarm.net.runspec import RunSpec


@dataclass
class Body:
    """The agent's own state: where it is, the velocity it last moved with, its heading (a body with one:
    :mod:`zswarm.control.body`), how many control steps it took; z and vz in a 3-D run (None in 2-D)."""

    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    step: int = 0
    heading: float | None = None
    z: float | None = None
    vz: float | None = None

    @property
    def dims(self) -> int:
        return 2 if self.z is None else 3

    @property
    def position(self) -> tuple[float, ...]:
        return msg.point(self.x, self.y, self.z)

    @property
    def velocity(self) -> tuple[float, ...]:
        return msg.point(self.vx, self.vy, self.vz)

    def distance(self, pose: msg.Pose) -> float:
        """How far a pose is from it (a pose of the other dimension counts as at z = 0: it is refused anyway)."""
        if self.z is None:
            return math.hypot(pose.x - self.x, pose.y - self.y)
        return math.hypot(pose.x - self.x, pose.y - self.y, (pose.z or 0.0) - self.z)


#: A departed neighbour whose newest pose was sent at most this long (s) before its token went has stopped
#: there (its process ended, or its link closed with it); one heard last longer before (it was frozen, or
#: this agent was, or cut off, and the others went on meanwhile) may be anywhere its age allows.
HELD_WITHIN = 2.0


class Sensing:
    """``probe_latency``: poses come from ring channels, which carry no arrival time, so the transport
    latency is timed on one neighbour's poses heard a second time through a subscription stamped on
    arrival (:mod:`agents.probe`); otherwise on every pose."""

    def __init__(self, spec: RunSpec, agent_id: int, body: Body, probe_latency: bool, node: int = 0) -> None:
        """``node``: the index of the router it is connected to (a pose sent from another counts as crossed)."""
        self.spec, self.id, self.body, self.node = spec, agent_id, body, node
        self.flat = body.z is None  # a 2-D run (its dimension is fixed for its life)
        self.latency_from_probe = probe_latency
        self.keys = spec.keys
        p = spec.scenario.params.swarm
        self.radius, self.v_max, self.dt = p.sensing_radius, p.v_max, spec.scenario.dt
        self.subscription_radius = spec.subscription_radius
        accel = spec.scenario.accels()  # bodies with inertia: each id's bound, for its rows (agents.guard)
        self.accels = tuple(accel.tolist()) if np.isfinite(accel).any() else None
        self.neighbours = PoseTable(max_step(spec.scenario), spec.period)
        self.counters = Counters(Rejections(f"agent {agent_id}"))
        self.membership = Membership(self.keys, agent_id)  # who is there: the liveliness and member tokens
        self.last_seq: dict[int, int] = {}
        # a departed neighbour's newest pose: where its body holds until it is heard again (agents.guard);
        # ``held``: those whose newest pose was sent just before their token went (it stopped there)
        self.remains: dict[int, msg.Pose] = {}
        self.held: set[int] = set()
        self.prey: tuple[float, ...] | None = None
        self.prey_stamp: float | None = None  # when the world sent the newest prey position heard
        self.world_heard: float | None = None  # when the newest prey or tick arrived (None: its clock not started)
        self.ticks: asyncio.Queue[msg.Tick] = asyncio.Queue()
        self.pose_arrived = asyncio.Event()  # lockstep waits on it; set per pose only then
        self.wake_on_pose = spec.clock == "lockstep"
        self.final_tick = False
        self.obstacle_view = ObstacleView(self.keys, body, self.radius, self.counters)
        self.latency_probe = LatencyProbe(self.keys, body, self.subscription_radius, self.neighbours,
                                          self.membership.alive, self.counters)

    # --- what the law and the tests read ---------------------------------------------------------------

    @property
    def obstacles(self) -> list[tuple[float, ...]]:
        """The known obstacles as (centre..., radius) tuples (the float law's input)."""
        return self.obstacle_view.obstacles

    @property
    def obstacle_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The known obstacles' centres (M, D) and radii (M,) (the vectorized law's input)."""
        return self.obstacle_view.centers, self.obstacle_view.radii

    @property
    def obstacle_query_at(self) -> tuple[float, ...] | None:
        return self.obstacle_view.query_at

    @property
    def probe(self) -> tuple[int, object] | None:
        return self.latency_probe.probe

    # --- inbound ---------------------------------------------------------------------------------------

    def handle(self, item: Inbound) -> None:
        tag, key, payload, deleted, received = item
        if tag == "pose":  # most of what it hears: a few a tick
            self._pose_sample(key, payload, received)
            return
        if tag == "alive":
            who = self.keys.agent_of(key)
            if who is None:
                return
            self.membership.token(who, deleted, received)
            if not deleted:
                if who in self.neighbours.entries:  # a member again, heard since: guarded by its poses
                    self.remains.pop(who, None)
                    self.held.discard(who)
                return  # back before any pose of it: its body stays guarded where it was
            gone = self.neighbours.forget(who)
            if gone is not None:  # departed: no neighbour of the law's now, but its body is still guarded
                self.counters.departed.setdefault(who, received)
                if gone.latest is not None:
                    self.remains[who] = gone.latest
                    if received - gone.latest.stamp <= HELD_WITHIN:
                        self.held.add(who)
            self.last_seq.pop(who, None)
            return
        if tag == "probe":
            self.latency_probe.heard(payload, received)
            return
        if tag in ("in", "in-now"):
            self.membership.member(key, deleted, live=tag == "in")
            return
        if tag == "in-gone":
            self.membership.member_gone(key, asked=received)
            return
        if tag == "in-unanswered":
            self.membership.unanswered_ask(key)
            return
        if tag == "in-answered":
            self.membership.answered(key)
            return
        self.counters.received += 1
        m = self._decoded(payload)
        if m is None:
            return
        if tag == "prey" and isinstance(m, msg.Prey):
            self.prey, self.prey_stamp, self.world_heard = m.position, m.stamp, time.monotonic()
        elif tag == "tick" and isinstance(m, msg.Tick):
            self.world_heard = time.monotonic()
            self.final_tick = self.final_tick or m.final
            self.ticks.put_nowait(m)
        elif tag == "obstacles" and isinstance(m, msg.Obstacles) and self.obstacle_view.query is not None:
            self.obstacle_view.answered(m)
        else:
            self.counters.rejections.add("kind", f"{type(m).__name__} on {tag} key")

    def _pose_sample(self, key: str, payload: bytes, received: float) -> None:
        """A sample of the cells it listens to, or an answer of one it asked: a neighbour's pose."""
        self.counters.received += 1
        who = self.keys.agent_of(key)
        if who == self.id:
            return  # its own pose, answered by its own queryable when it asked a cell
        m = self._decoded(payload)
        if type(m) is msg.Pose:
            self._on_pose(who, key, m, received)
        elif m is not None:
            self.counters.rejections.add("kind", f"{type(m).__name__} on pose key")

    def _decoded(self, payload: bytes) -> msg.Message | None:
        """The message, or None (counted by reason) if it is malformed or of the other dimension."""
        try:
            m = msg.decode(payload)
        except msg.DecodeError as exc:
            self.counters.rejections.add(exc.reason, str(exc))
            return None
        if isinstance(m, (msg.Pose, msg.Prey, msg.Tick)) and (m.z is None) != self.flat:
            self.counters.rejections.add("dimensions", f"a {len(m.position)}-D {type(m).__name__.lower()} in a "
                                         f"{self.body.dims}-D run (every process of a run needs the same --scenario)")
            return None
        return m

    def fault_source(self, tag: str, key: str, payload: bytes) -> tuple[int, float | None] | None:
        """The link a message arrives on, and (poses) its sender's distance over the sensing radius."""
        if tag == "prey":
            return (PREY_SOURCE, None)
        if key.startswith(self.keys.obstacles):
            return (OBSTACLE_SOURCE, None)
        if tag in ("pose", "reply"):
            who = self.keys.agent_of(key)
            if who is None:
                return None
            try:
                m = msg.decode(payload)
            except msg.DecodeError:
                return (who, None)  # let it through to be rejected and counted
            return (who, self.body.distance(m) / self.radius if isinstance(m, msg.Pose) else None)
        return None

    def _on_pose(self, who: int | None, key: str, pose: msg.Pose, now: float) -> None:
        """``pose`` arrived under ``key``, which names agent ``who``."""
        c = self.counters
        if who != pose.id:
            c.rejections.add("schema", f"pose of {pose.id} under key {key}")
            return
        nb = self.neighbours.entries.get(who)
        self.last_seq[pose.id] = c.count_sequence(pose, nb, self.last_seq.get(pose.id), self.body.distance, self.radius)
        c.heard[who] = c.heard.get(who, 0) + 1
        c.poses += 1
        if pose.node != self.node:
            c.crossed += 1
        if not self.latency_from_probe:
            c.add(c.latency, (now - pose.stamp) * 1000.0)
        reason = self.neighbours.accept(who, pose, now, self.membership.vouched, self.membership.announced.get)
        if reason is not None:
            c.rejections.add(reason, f"agent {who} jumped implausibly far")
            return
        if nb is None and who in c.departed:
            c.returned.setdefault(who, now)
        if who in self.remains:  # heard again: its body is where its newest pose says, moving
            self.held.discard(who)
            if who in self.membership.alive:  # its token is back: guarded by its poses
                del self.remains[who]
            else:
                self.remains[who] = pose
        if self.wake_on_pose:
            self.pose_arrived.set()

    def sense(self, step: int | None, staleness: float, time_scale: float = 1.0, period: float = 0.0,
              lookahead: float = 0.0, guard: bool = True) -> tuple[list[Near], list]:
        """What the law and the safety filter may use now (:func:`agents.guard.choose`)."""
        return choose(self, step, staleness, time_scale, period, lookahead, guard)
