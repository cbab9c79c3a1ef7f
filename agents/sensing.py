"""What one agent senses: the neighbours within its radius, the obstacles near it and the prey.

This is the inbound end of the agent: it takes every sample in (the last link of the chain Zenoh ->
bridge -> fault injector -> here, built before the bridge, :mod:`agents.main`) and says which
neighbours the law may use. It holds no transport: what the agent asks of the network (the cells
to listen to, the obstacle queries, the latency probe's subscription) is :mod:`agents.reach`.

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
from agents.obstacle_view import ObstacleView
from agents.probe import LatencyProbe
from zswarm.control.body import tracked_point
from zswarm.swarm.faults import OBSTACLE_SOURCE, PREY_SOURCE
from zswarm.net import messages as msg
from zswarm.net.bridge import Inbound
from zswarm.net.poses import Entry, PoseTable, Rejections, vouched_by
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


#: How long the safety filter waits for the liveliness token of a sender whose poses it hears (tokens
#: can come seconds after the poses on a loaded machine) before a silent one stops counting.
TOKEN_GRACE = 5.0


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
        self.neighbours = PoseTable(3.0 * self.v_max * self.dt, spec.period)  # 3x slack on a tick's reach
        self.counters = Counters(Rejections(f"agent {agent_id}"))
        self.alive: set[int] = set()  # ids with a liveliness token
        self.announced: dict[int, float] = {}  # id -> when its liveliness token came (whom to believe first)
        self.last_seq: dict[int, int] = {}
        self.members: dict[int, set[tuple[int, ...]]] = {}  # id -> the cells it listens to that hold its token
        self.member_news: set[tuple[int, tuple[int, ...]]] = set()  # (id, cell) that changed live since subscribed
        self.member_live_at: dict[tuple[int, tuple[int, ...]], float] = {}  # (id, cell) -> its last live change
        # ids the safety filter guards only because their member token is in a cell it listens to: that
        # token is asked about again (agents.reach.Reach.check_members)
        self.doubted: set[int] = set()
        self.listening: set[tuple[int, ...]] = set()  # the cells it listens to (agents.cell_view)
        self.prey: tuple[float, ...] | None = None
        self.prey_stamp: float | None = None  # when the world sent the newest prey position heard
        self.ticks: asyncio.Queue[msg.Tick] = asyncio.Queue()
        self.pose_arrived = asyncio.Event()  # lockstep waits on it; set per pose only then
        self.wake_on_pose = spec.clock == "lockstep"
        self.final_tick = False
        self.obstacle_view = ObstacleView(self.keys, body, self.radius, self.counters)
        self.latency_probe = LatencyProbe(self.keys, body, self.subscription_radius, self.neighbours,
                                          self.alive, self.counters)

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
            if not deleted:
                self.alive.add(who)
                self.announced.setdefault(who, received)
                return
            self.alive.discard(who)
            self.announced.pop(who, None)
            if self.neighbours.forget(who) is not None:  # departed: forget it at once
                self.counters.departed.setdefault(who, received)
            self.last_seq.pop(who, None)
            return
        if tag == "probe":
            self.latency_probe.heard(payload, received)
            return
        if tag in ("in", "in-now"):
            self._member(key, deleted, live=tag == "in")
            return
        if tag == "in-gone":
            self._member_gone(key, asked=received)
            return
        self.counters.received += 1
        m = self._decoded(payload)
        if m is None:
            return
        if tag == "prey" and isinstance(m, msg.Prey):
            self.prey, self.prey_stamp = m.position, m.stamp
        elif tag == "tick" and isinstance(m, msg.Tick):
            self.final_tick = self.final_tick or m.final
            self.ticks.put_nowait(m)
        elif tag == "obstacles" and isinstance(m, msg.Obstacles) and self.obstacle_view.query is not None:
            self.obstacle_view.answered(m)
        else:
            self.counters.rejections.add("kind", f"{type(m).__name__} on {tag} key")

    def _member(self, key: str, deleted: bool, live: bool = True) -> None:
        """A member token came into (or left) one of the cells it listens to (``live``), or was there
        when it asked (an answer that can come after a live change of the same token: it counts only
        if none came)."""
        parsed = self.keys.member_of(key)
        if parsed is None or parsed[1] == self.id:
            return
        cell, who = parsed
        if cell not in self.listening:
            return  # an answer about a cell it has left since it asked
        if live:
            self.member_news.add((who, cell))
            self.member_live_at[(who, cell)] = time.time()
        elif (who, cell) in self.member_news:
            return
        if not deleted:
            self.members.setdefault(who, set()).add(cell)
        else:
            self._not_in(who, {cell})

    def _member_gone(self, key: str, asked: float) -> None:
        """The member token ``key`` was asked about at ``asked`` and nobody holds it: it is no longer in
        that cell, unless a live change of it came since. (A token's removal once never reached an agent
        that had taken the token in from the answer to its ask on entering the cell; the agent then
        guarded the silent sender, and braked beside where it was last heard, for as long as it listened
        to that cell: docs/safety.md.)"""
        parsed = self.keys.member_of(key)
        if parsed is None:
            return
        cell, who = parsed
        if self.member_live_at.get((who, cell), -math.inf) < asked:
            self._not_in(who, {cell})

    def listen_to(self, new: list[tuple[int, ...]], left: list[tuple[int, ...]]) -> None:
        """It listens to the cells ``new`` now, and no longer to ``left``: what their tokens said no
        longer holds."""
        self.listening.update(new)
        if not left:
            return
        gone = set(left)
        self.listening -= gone
        self.member_news = {(who, cell) for who, cell in self.member_news if cell not in gone}
        self.member_live_at = {k: t for k, t in self.member_live_at.items() if k[1] not in gone}
        for who in list(self.members):
            self._not_in(who, gone)

    def _not_in(self, who: int, cells: set[tuple[int, ...]]) -> None:
        """Agent ``who``'s token is in none of ``cells`` (it is forgotten when it is in no cell it listens to)."""
        held = self.members.get(who)
        if held is not None:
            held -= cells
            if not held:
                del self.members[who]

    def vouched(self, pose: msg.Pose) -> bool:
        """The sender's member token is in the cell of ``pose`` (:func:`zswarm.net.poses.vouched_by`)."""
        return vouched_by(self.members.get(pose.id), self.keys.cell(*pose.position))

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

    def _count_sequence(self, pose: msg.Pose, nb: Entry | None) -> None:
        """Observed loss from sequence numbers: a gap of g counts g - 1 lost when the sender was within
        the sensing radius both before and after it (then every pose it sent reached the agent's cells;
        otherwise it may simply have been out of range); a late arrival that filled a gap is taken back.
        ``nb``: what it held of the sender before this pose."""
        last = self.last_seq.get(pose.id)
        if last is not None and nb is not None:
            c, r, distance = self.counters, self.radius, self.body.distance
            if distance(pose) <= r and distance(nb.latest) <= r:
                if pose.seq > last:
                    gap = pose.seq - last - 1
                    if gap <= 50:
                        c.seq_lost += gap
                    c.seq_received += 1
                elif pose.seq < last and c.seq_lost > 0:
                    c.seq_lost -= 1
                    c.seq_received += 1
        self.last_seq[pose.id] = max(pose.seq, last or 0)

    def _on_pose(self, who: int | None, key: str, pose: msg.Pose, now: float) -> None:
        """``pose`` arrived under ``key``, which names agent ``who``."""
        c = self.counters
        if who != pose.id:
            c.rejections.add("schema", f"pose of {pose.id} under key {key}")
            return
        nb = self.neighbours.entries.get(who)
        self._count_sequence(pose, nb)
        c.heard[who] = c.heard.get(who, 0) + 1
        c.poses += 1
        if pose.node != self.node:
            c.crossed += 1
        if not self.latency_from_probe:
            c.add(c.latency, (now - pose.stamp) * 1000.0)
        reason = self.neighbours.accept(who, pose, now, self.vouched, self.announced.get)
        if reason is not None:
            c.rejections.add(reason, f"agent {who} jumped implausibly far")
            return
        if nb is None and who in c.departed:
            c.returned.setdefault(who, now)
        if self.wake_on_pose:
            self.pose_arrived.set()

    # --- what the agent senses -------------------------------------------------------------------------

    def sense(self, step: int | None, staleness: float, time_scale: float = 1.0, period: float = 0.0,
              lookahead: float = 0.0, guard: bool = True) -> tuple[list[msg.Pose], list[tuple[tuple[float, ...], float]]]:
        """What the law and the safety filter may use now, from one pass over the neighbours it holds
        (an agent does this every tick): ``(poses, guarded)``.

        *poses* (the law's neighbours): of the agents that hold a liveliness token, the step-k pose
        (lockstep, ``step`` k) or the newest, if received within ``staleness`` seconds (free, ``step``
        None). The age of each pose within the sensing radius is recorded here, at the moment it is used.

        *guarded* (the safety filter's rows, empty unless ``guard``): (where the filter acts on it, age
        in simulated seconds) of every neighbour not seen departing, with or without its token. A
        neighbour whose token has not come yet counts (its poses prove it is there; under load a token
        can come seconds after them), unless its token has not come in :data:`TOKEN_GRACE` seconds
        since its first pose and nothing came from it for ``staleness`` seconds: a sender that never
        announced itself and fell silent is no member of the swarm (a hostile peer's made-up agent once
        held an agent braking beside it for the rest of a run). Of those, the ones whose newest pose may
        be within the sensing radius by now (no farther beyond it than v_max times its age), less the
        ones that have gone quiet and can have left (:meth:`_guarded`).

        Lockstep: the step-k poses, exact for step k (age 0). Free: the newest pose, its age from its
        stamp scaled by ``time_scale``, plus one control period ``period`` (a neighbour on its own timer
        may have stepped once more than the age says: ticks that catch up on a late one come closer
        together). ``lookahead``: a unicycle's tracked point ahead of its axle, from the heading."""
        now, b, entries = time.time(), self.body, self.neighbours.entries
        radius, v, alive, departed = self.radius, self.v_max, self.alive, self.counters.departed
        c = self.counters
        positions: list[msg.Pose] = []
        heard = []
        # over what is heard: the least time since a neighbour was heard, the least age, the least delay
        quiet_min = age_min = lag_min = math.inf
        for who, nb in entries.items():
            pose = nb.latest if step is None else nb.by_step.get(step)
            if pose is None:
                continue
            quiet = now - nb.received
            member = who in alive
            if not member and not (guard and who not in departed
                                   and (now - nb.first <= TOKEN_GRACE or quiet <= staleness)):
                continue
            d = b.distance(pose)
            if member and (step is not None or quiet <= staleness):
                if d <= radius:
                    c.add(c.ages, (now - pose.stamp) * 1000.0)
                positions.append(pose)
            if guard:
                age = 0.0 if step is not None else max(now - pose.stamp, 0.0) * time_scale + period
                if d - v * age <= radius:
                    lag = nb.received - pose.stamp
                    heard.append((pose, age, quiet, d, lag))
                    quiet_min, age_min, lag_min = min(quiet_min, quiet), min(age_min, age), min(lag_min, lag)
        if not heard:
            return positions, []
        return positions, self._guarded(heard, (quiet_min, age_min, lag_min), step, staleness, lookahead)

    def _guarded(self, heard: list, least: tuple[float, float, float], step: int | None, staleness: float,
                 lookahead: float) -> list[tuple[tuple[float, ...], float]]:
        """The safety filter's rows from ``heard`` (pose, age, seconds since it was heard, distance,
        delay it came through): the neighbours that may be within its radius (:meth:`sense`); ``least``:
        the least time since heard, age and delay over them.

        One from which nothing came for ``staleness`` wall seconds longer than from the one heard last
        has gone *quiet*: it has left the cells this agent listens to, or its poses are being lost. One
        whose member token is in one of those cells is there (tokens travel on Zenoh's control plane,
        which pose loss does not touch): its silence is loss, and it stays guarded against. Otherwise it
        is let go only if it can have left: if its newest pose plus what it can have moved while the
        others were still heard (its age beyond the freshest neighbour's: had it stayed, its poses would
        have come through the same delay as theirs) reaches past the subscription disc (the cells cover
        at least that disc about this agent). One deep inside cannot have left: its silence is loss, and
        it stays guarded against where it may be (``docs/safety.md``). That premise holds only for a
        neighbour whose poses came through no slower a path than the others': one whose newest pose
        arrived later after it was sent than the promptest neighbour's by some extra delay is given that
        extra before its silence counts (a router that reads some senders seconds late made them fall
        silent while they were there, and neighbours walked into them). ``lookahead``: a unicycle's
        tracked point ahead of its axle, from the heading."""
        v, cells = self.v_max, self.subscription_radius
        left = least[0] + staleness
        fresh = least[1]  # the delay every pose heard now has come through
        path = least[2]  # the shortest delay a newest pose came through
        out = []
        for pose, age, quiet, d, lag in heard:
            # its silence counts only beyond its own path's extra delay: a sender whose poses queue
            # (a router that reads it late) falls silent while it is still there
            if step is None and quiet - max(lag - path, 0.0) > left and d + v * (age - fresh) > cells:
                if pose.id not in self.members:
                    continue
                self.doubted.add(pose.id)  # guarded on its member token alone: that token is asked about
            look = lookahead if pose.heading is not None else 0.0  # only a unicycle's pose carries a heading
            out.append((tracked_point(pose.position, pose.heading, lookahead), age, look))
        return out
