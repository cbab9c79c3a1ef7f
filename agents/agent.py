"""One agent: an asyncio process that senses its neighbours over Zenoh and descends its potential.

It decides from its own state, the poses of the agents within its sensing radius (published into the
spatial cells its sensing disc overlaps), the obstacles within its radius (asked of the world's
queryable, never the whole map) and the prey it observes. Nothing else reaches it.

Clocks:
- ``free``: a wall-clock timer at 1/period; each tick uses the freshest neighbour data younger than the
  staleness limit. Late ticks are counted and never queued up.
- ``lockstep``: the world's tick k+1 (sent once the world has every pose of step k) makes the agent
  compute step k from the step-k poses of its neighbours, move, and publish its pose of step k+1.
  That is the reference simulator's step, so the trajectories agree.
"""

from __future__ import annotations

import asyncio
import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from zswarm import messages as msg
from zswarm.faults import OBSTACLE_SOURCE, PREY_SOURCE
from zswarm.potentials import Controller, make_controller, sense_one
from zswarm.runspec import RunSpec
from zswarm.transport import Bridge, cells_in_disc

STATS_PERIOD = 1.0


@dataclass
class Neighbour:
    latest: msg.Pose
    received: float  # local wall time of receipt
    by_step: dict[int, msg.Pose] = field(default_factory=dict)


@dataclass
class Counters:
    sent: int = 0
    received: int = 0
    rejected: dict[str, int] = field(default_factory=dict)
    ticks: int = 0
    late_ticks: int = 0
    ages: dict[int, int] = field(default_factory=dict)
    latency: dict[int, int] = field(default_factory=dict)
    obstacle_queries_failed: int = 0
    heard: set[int] = field(default_factory=set)
    seq_received: int = 0
    seq_lost: int = 0
    departed: dict[int, float] = field(default_factory=dict)
    returned: dict[int, float] = field(default_factory=dict)
    # since the last stats message: the longest inbound queue seen at a tick, and the latest tick start
    window_queue_max: int = 0
    window_lag_ms: float = 0.0

    def reject(self, reason: str, agent: int, detail: str) -> None:
        if reason not in self.rejected:  # log once per reason
            print(f"agent {agent}: rejected a message ({detail}); further '{reason}' rejections are "
                  f"only counted", file=sys.stderr, flush=True)
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    @staticmethod
    def add(hist: dict[int, int], ms: float) -> None:
        b = msg.to_bin(ms)
        hist[b] = hist.get(b, 0) + 1


class Agent:
    def __init__(self, spec: RunSpec, agent_id: int, bridge: Bridge, start: np.ndarray,
                 staleness: float = 0.5, lockstep_wait: float = 0.25) -> None:
        self.spec, self.id, self.bridge = spec, agent_id, bridge
        self.keys = spec.keys
        p = spec.scenario.params
        self.radius, self.v_max, self.dt = p.swarm.sensing_radius, p.swarm.v_max, spec.scenario.dt
        self.controller: Controller = make_controller(p.potential, spec.combination, spec.scenario.formation)
        self.position = np.array(start, dtype=float)
        self.velocity = np.zeros(2)
        self.step = 0
        self.seq = 0
        self.staleness, self.lockstep_wait = staleness, lockstep_wait
        # cells within R + 2 v_max dt: whoever can enter the sensing disc next step is already heard
        self.subscription_radius = self.radius + 2.0 * self.v_max * self.dt
        self.max_step = 3.0 * self.v_max * self.dt  # farther per tick is an impossible jump (3x slack)
        self.neighbours: dict[int, Neighbour] = {}
        self.prey: np.ndarray | None = None
        self.prey_by_step: dict[int, np.ndarray] = {}
        self.obstacle_centers = np.zeros((0, 2))
        self.obstacle_radii = np.zeros(0)
        self.obstacle_query_at: np.ndarray | None = None
        self.cells: dict[tuple[int, int], object] = {}
        self.cell_since: dict[tuple[int, int], int] = {}  # step at which each cell was subscribed
        self.pose_cell: tuple[int, int] | None = None
        self.queryable = None
        self.latest_reply: tuple[str, bytes] | None = None
        self.replies_by_step: dict[int, tuple[str, bytes]] = {}
        self.counters = Counters()
        self.ticks: asyncio.Queue[msg.Tick] = asyncio.Queue()
        self.pose_arrived = asyncio.Event()
        self.stop = asyncio.Event()
        self.injector = None  # a FaultInjector when faults are injected
        self.last_seq: dict[int, int] = {}
        self.alive: set[int] = set()  # ids with a liveliness token: only those are used as neighbours

    # --- inbound ---------------------------------------------------------------------------------------

    def handle(self, item: tuple[str, str, bytes, bool]) -> None:
        tag, key, payload, deleted = item
        if tag == "alive":
            who = self.keys.agent_of(key)
            if who is not None and not deleted:
                self.alive.add(who)
            if deleted and who is not None:
                self.alive.discard(who)
                if self.neighbours.pop(who, None) is not None:  # departed: forget it at once
                    self.counters.departed.setdefault(who, time.time())
                self.last_seq.pop(who, None)
            return
        self.counters.received += 1
        try:
            m = msg.decode(payload)
        except msg.DecodeError as exc:
            self.counters.reject(exc.reason, self.id, str(exc))
            return
        if tag == "pose" and isinstance(m, msg.Pose):
            self._on_pose(key, m)
        elif tag == "prey" and isinstance(m, msg.Prey):
            self.prey = np.array([m.x, m.y])
        elif tag == "tick" and isinstance(m, msg.Tick):
            self.ticks.put_nowait(m)
        else:
            self.counters.reject("kind", self.id, f"{type(m).__name__} on {tag} key")

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
            ratio = math.hypot(m.x - self.position[0], m.y - self.position[1]) / self.radius \
                if isinstance(m, msg.Pose) else None
            return (who, ratio)
        return None

    def _count_sequence(self, pose: msg.Pose) -> None:
        """Observed loss from sequence numbers: a gap of g counts g - 1 lost when the sender was within
        the sensing radius both before and after it (then every pose it sent reached the agent's cells;
        otherwise it may simply have been out of range); a late arrival that filled a gap is taken back."""
        last = self.last_seq.get(pose.id)
        c = self.counters
        nb = self.neighbours.get(pose.id)
        within = nb is not None and all(
            math.hypot(p.x - self.position[0], p.y - self.position[1]) <= self.radius for p in (nb.latest, pose))
        if last is not None and within:
            if pose.seq > last:
                gap = pose.seq - last - 1
                if gap <= 50:
                    c.seq_lost += gap
                c.seq_received += 1
            elif pose.seq < last and c.seq_lost > 0:
                c.seq_lost -= 1
                c.seq_received += 1
        self.last_seq[pose.id] = max(pose.seq, last or 0)

    def _on_pose(self, key: str, pose: msg.Pose) -> None:
        if self.keys.agent_of(key) != pose.id:
            self.counters.reject("schema", self.id, f"pose of {pose.id} under key {key}")
            return
        if pose.id == self.id:
            return
        now = time.time()
        self._count_sequence(pose)
        self.counters.heard.add(pose.id)
        self.counters.add(self.counters.latency, (now - pose.stamp) * 1000.0)
        nb = self.neighbours.get(pose.id)
        elapsed = (now - nb.received) / self.spec.period + 2.0 if nb is not None and pose.step < 0 else None
        if nb is not None and pose.seq > nb.latest.seq and msg.implausible_jump(nb.latest, pose, self.max_step,
                                                                                 elapsed):
            self.counters.reject("jump", self.id, f"agent {pose.id} jumped implausibly far")
            return
        if nb is None:
            nb = self.neighbours[pose.id] = Neighbour(pose, now)
            if pose.id in self.counters.departed:
                self.counters.returned.setdefault(pose.id, now)
        elif msg.supersedes(nb.latest, pose):
            nb.latest, nb.received = pose, now
        if pose.step >= 0:
            nb.by_step[pose.step] = pose
            for old in [s for s in nb.by_step if s < pose.step - 3]:
                del nb.by_step[old]
        self.pose_arrived.set()

    # --- what the agent senses -------------------------------------------------------------------------

    async def refresh_obstacles(self, timeout: float = 2.0) -> bool:
        """Ask the world for the obstacles within 2R; re-ask after moving R from the last question."""
        if self.obstacle_query_at is not None and np.linalg.norm(self.position - self.obstacle_query_at) < self.radius:
            return True
        x, y = map(float, self.position)
        try:
            replies = await self.bridge.get(self.keys.obstacle_query(x, y, 2.0 * self.radius), timeout)
        except Exception:
            replies = []
        for _, payload in replies:
            try:
                m = msg.decode(payload)
            except msg.DecodeError as exc:
                self.counters.reject(exc.reason, self.id, str(exc))
                continue
            if isinstance(m, msg.Obstacles):
                self.obstacle_centers = np.array(m.centers, dtype=float).reshape(-1, 2)
                self.obstacle_radii = np.array(m.radii, dtype=float)
                self.obstacle_query_at = self.position.copy()
                return True
        self.counters.obstacle_queries_failed += 1
        return False  # keep what it knew (world away)

    async def update_cells(self) -> None:
        """Subscribe to the cells the sensing disc overlaps; ask new cells for their agents at once."""
        x, y = map(float, self.position)
        wanted = cells_in_disc(self.keys, x, y, self.subscription_radius)
        for cell in [c for c in self.cells if c not in wanted]:
            self.cells.pop(cell).undeclare()
            self.cell_since.pop(cell, None)
        new = [c for c in wanted if c not in self.cells]
        for cell in new:
            self.cells[cell] = self.bridge.subscribe(self.keys.cell_poses(cell), "pose")
            self.cell_since[cell] = self.step
        for cell in new:
            for key, payload in await self.bridge.get(self.keys.cell_poses(cell), timeout=1.0):
                self.handle(("pose", key, payload, False))

    def sensed_neighbours(self, step: int | None) -> np.ndarray:
        """Positions of the neighbours it may use now: step-k poses (lockstep) or fresh ones (free), of
        agents that hold a liveliness token (a pose under an id nobody announced is not a neighbour).

        The age of each pose within the sensing radius is recorded here, at the moment it is used.
        """
        now = time.time()
        out = []
        for who, nb in self.neighbours.items():
            if who not in self.alive:
                continue
            pose = nb.by_step.get(step) if step is not None else nb.latest
            if pose is None or (step is None and now - nb.received > self.staleness):
                continue
            if math.hypot(pose.x - self.position[0], pose.y - self.position[1]) <= self.radius:
                self.counters.add(self.counters.ages, (now - pose.stamp) * 1000.0)
            out.append((pose.x, pose.y))
        return np.array(out, dtype=float).reshape(-1, 2)

    def control(self, goal: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
        sensed = sense_one(self.position, self.obstacle_centers, self.obstacle_radii, neighbours, self.radius)
        return self.controller.velocity(self.position, goal, sensed, self.v_max)

    # --- outbound --------------------------------------------------------------------------------------

    def publish_pose(self, step: int) -> None:
        cell = self.keys.cell(*map(float, self.position))
        key = self.keys.pose(cell, self.id)
        self.seq += 1
        payload = msg.encode(msg.Pose(self.id, self.seq, time.time(), step, float(self.position[0]),
                                      float(self.position[1]), float(self.velocity[0]),
                                      float(self.velocity[1])))
        self.latest_reply = (key, payload)
        if step >= 0:
            self.replies_by_step = {s: r for s, r in self.replies_by_step.items() if s > step - 3}
            self.replies_by_step[step] = (key, payload)
        if cell != self.pose_cell:
            if self.queryable is not None:
                self.queryable.undeclare()
            self.queryable = self.bridge.queryable(key, self._answer)
            self.pose_cell = cell
        self.bridge.session.put(key, payload)
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
        c = self.counters
        return msg.encode(msg.Stats(self.id, c.sent, c.received, dict(c.rejected), c.late_ticks, c.ticks,
                                    dict(c.ages), dict(c.latency), final,
                                    {"obstacle_queries_failed": float(c.obstacle_queries_failed),
                                     "seq_received": float(c.seq_received), "seq_lost": float(c.seq_lost),
                                     "injected_drops": float(self.injector.faults.dropped if self.injector else 0),
                                     "injected_passed": float(self.injector.faults.passed if self.injector else 0),
                                     "queue_max": float(c.window_queue_max), "tick_lag_max_ms": c.window_lag_ms},
                                    tuple(sorted(c.heard))[:msg.MAX_HEARD], dict(c.departed), dict(c.returned)))

    async def publish_stats(self) -> None:
        while not self.stop.is_set():
            try:
                await asyncio.wait_for(self.stop.wait(), STATS_PERIOD)
            except asyncio.TimeoutError:
                self.bridge.session.put(self.keys.stats(self.id), self.stats())
                self.counters.window_queue_max, self.counters.window_lag_ms = 0, 0.0

    # --- the two clocks --------------------------------------------------------------------------------

    async def run_free(self) -> None:
        period = self.spec.period
        loop = asyncio.get_running_loop()
        next_tick = loop.time()
        while not self.stop.is_set():
            now = loop.time()
            c = self.counters
            c.window_queue_max = max(c.window_queue_max, self.bridge.queue.qsize())
            c.window_lag_ms = max(c.window_lag_ms, 1000.0 * (now - next_tick))
            if now - next_tick > 0.5 * period:
                self.counters.late_ticks += 1
                next_tick = max(next_tick, now)  # skip, never queue up a backlog
            self.counters.ticks += 1
            await self.refresh_obstacles()
            if self.prey is not None:
                self.velocity = self.control(self.prey, self.sensed_neighbours(None))
                self.position = self.position + self.dt * self.velocity
            self.step += 1
            await self.update_cells()
            self.publish_pose(-1)
            next_tick += period
            try:
                await asyncio.wait_for(self.stop.wait(), max(next_tick - loop.time(), 0.0))
            except asyncio.TimeoutError:
                pass

    async def _await_step_poses(self, step: int) -> None:
        """Make sure it has the step pose of every agent that can be within its radius now.

        It subscribes to the cells within R + 2 v_max dt, so every agent that can be within R at
        step k was heard at step k-1. It waits (briefly) for those; for any still missing, and for
        cells it subscribed to during this step (a subscription may reach the router after a
        neighbour published), it asks the cells where they can be for their pose of this step.
        """
        reach = self.subscription_radius
        expected = [nb for nb in self.neighbours.values()
                    if step not in nb.by_step and (step - 1 in nb.by_step or nb.latest.step >= step - 1)
                    and math.hypot(nb.latest.x - self.position[0], nb.latest.y - self.position[1]) <= reach]
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.lockstep_wait
        while expected and loop.time() < deadline:
            self.pose_arrived.clear()
            try:
                await asyncio.wait_for(self.pose_arrived.wait(), deadline - loop.time())
            except asyncio.TimeoutError:
                break
            expected = [nb for nb in expected if step not in nb.by_step]
        cells = {c for c, since in self.cell_since.items() if since >= step}
        for nb in expected:
            cells |= cells_in_disc(self.keys, nb.latest.x, nb.latest.y, 2.0 * self.v_max * self.dt)
        replies = await asyncio.gather(*(self.bridge.get(f"{self.keys.cell_poses(c)}?step={step}", timeout=1.0)
                                         for c in cells))
        for key, payload in (r for batch in replies for r in batch):
            self.handle(("pose", key, payload, False))

    async def run_lockstep(self) -> None:
        while not self.stop.is_set():
            tick_task = asyncio.ensure_future(self.ticks.get())
            stop_task = asyncio.ensure_future(self.stop.wait())
            done, _ = await asyncio.wait({tick_task, stop_task}, return_when=asyncio.FIRST_COMPLETED)
            if tick_task not in done:
                tick_task.cancel()
                return
            stop_task.cancel()
            tick = tick_task.result()
            if tick.final:
                self.stop.set()
                return
            self.prey_by_step[tick.step] = np.array([tick.x, tick.y])
            self.counters.ticks += 1
            while self.step < tick.step:  # tick k: every pose of step k-1 is out; do step k-1
                k = self.step
                await self._await_step_poses(k)
                await self.refresh_obstacles()
                goal = self.prey_by_step.get(k, np.array([tick.x, tick.y]))
                self.velocity = self.control(goal, self.sensed_neighbours(k))
                self.position = self.position + self.dt * self.velocity
                self.step += 1
                self.prey_by_step.pop(k - 2, None)
            await self.update_cells()
            self.publish_pose(self.step)
