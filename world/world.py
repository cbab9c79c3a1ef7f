"""The world: hosts the obstacles and the prey, and observes (never steers) the swarm.

It answers obstacle queries with only the obstacles within the asked radius
(:class:`~world.obstacles.ObstacleService`), moves and publishes the prey, and subscribes to every
pose only to measure and record: the observer of :mod:`zswarm.swarm.observer` (the simulator's and
replay's too), the :class:`~world.recorder.WorldRecorder`, and a summary JSON at the end.

Clocks:
- ``free``: the prey is published at the agents' rate; simulated time follows the wall clock, so a
  slow world tick stretches the prey's step instead of slowing its time down.
- ``lockstep``: tick k is sent once every live agent's pose of step k-1 is in (or a timeout passed).
"""

from __future__ import annotations

import asyncio
import math
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import zenoh

from world.intake import PoseIntake, Snapshot
from world.obstacles import ObstacleService
from world.recorder import Resumed, WorldRecorder
from world.report import StatsBook, transport_summary
from zswarm.net.config import connected
from zswarm.laws.registry import bind
from zswarm.design.guidelines import verdict
from zswarm.swarm import prey as prey_motion
from zswarm.swarm.observer import SwarmObserver
from zswarm.swarm.timed_contacts import TimedContacts
from zswarm.net import histogram
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge, Inbound
from zswarm.net.keys import in_reach_counts
from zswarm.net.poses import Rejections
from zswarm.net.runspec import RunSpec
from zswarm.net.watch import how_gone

STALL = 1.0  # seconds behind its clock at which the world logs a stall event
#: lockstep: the longest a clock held for a fault's staging waits (``--hold-at``)
HOLD_MAX_S = 5.0


TICK_QOS = {"congestion_control": zenoh.CongestionControl.BLOCK, "priority": zenoh.Priority.INTERACTIVE_HIGH,
            "express": True}
RESENT_QOS = {"express": True}  # a repeated final tick: at once, and dropped where a link is full
#: A token that went this long before the world found its own link gone went with that link: a router
#: that stops closes its clients' links one after another, the world's among them.
LINKS_CLOSE_WITHIN_S = 0.5


@dataclass
class Census:
    """Who is alive (holds a liveliness token), and when agents came and went."""

    alive: set[int] = field(default_factory=set)
    cut_off: set[int] = field(default_factory=set)  # gone while the world had no router: their tokens went with it
    arrivals: list[dict[str, Any]] = field(default_factory=list)
    # each with "how": "left", "crashed", "unreachable" (it came back: :meth:`World.tell_unreachable`) or
    # "world cut off" (the world's link went, and the tokens with it)
    departures: list[dict[str, Any]] = field(default_factory=list)
    pending: dict[int, dict[str, Any]] = field(default_factory=dict)  # gone, not yet told apart
    stopped_at_end: list[int] = field(default_factory=list)  # agents that stopped because the run ended
    all_alive_after: float | None = None  # wall seconds from the world's start


@dataclass
class CellTraffic:
    """How many other agents publish into the cells each agent listens to (sampled once a second from
    the poses the world holds): what a lossless transport hands an agent per round. The agents' own
    count of poses taken in is measured against it."""

    total: float = 0.0  # sum over samples of the mean over agents
    samples: int = 0
    last: float = -math.inf  # wall time of the last sample

    def sample(self, pos: np.ndarray, radius: float, cell_size: float, every: float = 1.0) -> None:
        now = time.time()
        if now - self.last < every or len(pos) < 2:
            return
        self.total += float(in_reach_counts(pos, radius, cell_size).mean())
        self.samples += 1
        self.last = now

    def per_s(self, period: float) -> float | None:
        """Poses in reach per agent per second, at one pose per agent per ``period``."""
        return self.total / self.samples / period if self.samples else None


@dataclass
class Clock:
    """Where the world is in the run: its tick count (the recording's ``step`` timeline) and simulated
    time (k dt in lockstep, wall time x time scale in free mode)."""

    step: int = 0
    t: float = 0.0
    late_ticks: int = 0  # free: ticks that started more than half a period late
    missed_poses: int = 0  # lockstep: poses still missing when a step timed out


class World:
    """The world's state and clocks. It publishes on ``session``; what it hears reaches :meth:`handle`
    through the bridge built after it (:mod:`world.main`), which the free clock drains once per tick."""

    def __init__(self, spec: RunSpec, session: zenoh.Session, recorder: WorldRecorder, argv: list[str],
                 batched: bool = False, end_after_capture: float | None = None) -> None:
        """``batched``: free clock only: the bridge hands it a tick's poses at once (:meth:`take_poses`;
        :mod:`world.intake`); otherwise one at a time (:meth:`handle`). ``end_after_capture``: end the run
        that many simulated seconds after the prey is caught (None: run the whole duration)."""
        self.spec, self.session, self.keys, self.recorder = spec, session, spec.keys, recorder
        self.end_after_capture, self.caught_at = end_after_capture, None
        self.scenario = spec.scenario
        self.argv = argv
        self.observer = SwarmObserver(self.scenario, spec.combination)
        self.dims = self.scenario.dimensions
        self.obstacles = ObstacleService(*self.scenario.obstacle_arrays(), self.keys.obstacles, self.dims)
        self.rejected = Rejections("world", self.event)
        self.census = Census()
        self.said_cut_off = False  # its session lost its router, said once
        self.ending = False  # set when the world announces the final tick: agents going now are not departures
        self.clock = Clock()
        self.stats = StatsBook(self.keys.agent_of, self.rejected)
        self.prey = np.array(self.scenario.prey_start, dtype=float)
        self.received = self.sent = 0
        self.network_logged = self.network_agents_logged = 0.0  # wall times the network panel was last logged
        self.network_received = 0
        self.stalled = False  # the free clock is more than STALL behind
        self.traffic = CellTraffic()
        self.pose_arrived = asyncio.Event()  # lockstep waits on it; set per pose only then
        self.wake_on_pose = spec.clock == "lockstep"
        self.stop = asyncio.Event()
        self.go = asyncio.Event()  # lockstep: the fault its clock was held for is staged (SIGUSR1)
        self.started_wall = time.time()
        self.resumed: Resumed | None = None
        self.last_seen: tuple[float, np.ndarray, np.ndarray] | None = None  # (t, ids, positions) observed last
        self.snapshot_spread = 0.0  # free clock: the widest spread of send times in one observed snapshot
        # free clock: collisions judged at one instant (a snapshot mixes poses sent at different times)
        self.timed = (TimedContacts(2.0 * self.scenario.params.swarm.robot_radius)
                      if spec.clock == "free" else None)
        self.judged_wall = 0.0  # when the judge last ran (wall time)
        self.intake = PoseIntake(spec, self.rejected, self.timed, batched)
        self.design: dict[str, Any] | None = None  # the set's design verdict (:meth:`judge_design`)
        self.law = bind(self.scenario, spec.combination, probe=False).describe()  # what the agents run
        self.design_judge: threading.Thread | None = None

    def judge_design(self, given: dict[str, Any] | None = None) -> None:
        """Judge the run's set against the guidelines (its summary's ``design``) on a thread of its own,
        while the world waits for its agents: at N >= 300 the swarm check takes seconds, which the end of
        the run no longer waits for. ``given``: the verdict the launcher reached for the same set."""
        if given is not None:
            self.design = given
            return
        def judge() -> None:
            self.design = verdict(self.scenario.params, self.scenario.dt, self.spec.safety)
        self.design_judge = threading.Thread(target=judge, name="design", daemon=True)
        self.design_judge.start()

    # --- start ----------------------------------------------------------------------------------------

    def open(self, resume: bool) -> None:
        """Recover a dead predecessor's run (``resume``), then open this world's recording."""
        if resume:
            self.resumed = self.recorder.recover(self.spec.run, self.observer)
        if self.resumed is not None and self.resumed.step >= 0:
            self.clock.step, self.clock.t = self.resumed.step + 1, self.resumed.t
            if self.resumed.prey is not None:
                self.prey = self.resumed.prey
        self.recorder.open(self.spec.run, self.config(), self.obstacles.centers, self.obstacles.radii,
                           self.observer.thresholds(), self.scenario.params.swarm.sensing_radius,
                           arena=self.scenario.arena(), dimensions=self.dims)
        if self.resumed is not None:
            self.event(f"world restarted: segment {self.resumed.segment} continues after step "
                       f"{self.resumed.step} (t = {self.resumed.t:.2f} s)")

    def config(self) -> dict[str, Any]:
        """What the run was asked to do, as the recording stores it."""
        from zswarm.provenance import versions

        return {**self.spec.describe(), "law": self.law, "versions": versions(), "argv": self.argv,
                "segment": self.recorder.segment, "end_after_capture": self.end_after_capture,
                "resumed_from": None if self.resumed is None else self.resumed.to_dict()}

    # --- what the world hears -------------------------------------------------------------------------

    def handle(self, item: Inbound) -> None:
        tag, key, payload, deleted, received = item
        if tag == "alive":
            self._on_liveliness(self.keys.agent_of(key), deleted)
            return
        if tag == "in":
            self.intake.member(key, deleted)
            return
        self.received += 1
        if tag == "stats":
            reporter = self.stats.add(key, payload)
            if reporter is not None:  # the agent puts it until told it is here (mid-run too: its law failed)
                self.report_taken(reporter)
            return
        try:
            m = msg.decode(payload)
        except msg.DecodeError as exc:
            self.rejected.add(exc.reason, f"on {key}: {exc}")
            return
        if tag == "pose" and isinstance(m, msg.Pose):
            if m.dims != self.dims:
                self.rejected.add("dimensions", f"agent {m.id} sends {m.dims}-D poses into this {self.dims}-D run "
                                  "(start every process of a run with the same --scenario)")
                return
            if self.intake.one(key, m, payload, received) and self.wake_on_pose:
                self.pose_arrived.set()
        else:
            self.rejected.add("kind")

    def take_poses(self, keys: list[str], payloads: list[bytes], received: float) -> None:
        """Free clock: a tick's pose samples at once (the bridge's batch for the ``pose`` channel;
        :meth:`world.intake.PoseIntake.batch`); what the batch would refuse goes through :meth:`handle`."""
        taken = self.intake.batch(keys, payloads, received,
                                  lambda key, payload: self.handle(("pose", key, payload, False, received)))
        self.received += taken  # (not "+=" of the call: handle counts what it is given as the call runs)

    def _on_liveliness(self, who: int | None, deleted: bool) -> None:
        if who is None:
            return
        c = self.census
        event = {"id": who, "t": round(self.clock.t, 6), "wall": round(time.time() - self.started_wall, 3)}
        if deleted:
            c.alive.discard(who)
            self.intake.announced.pop(who, None)
            self.intake.forget(who)
            if self.timed is not None:
                self.timed.leave(who)
            if self.ending:  # the run is over and the agents stop: not a departure
                if who not in c.stopped_at_end:  # a token seen going twice (it came back between) counts once
                    c.stopped_at_end.append(who)
            else:
                if not connected(self.session):  # the token went with the world's own link, and so did
                    now = time.monotonic()  # those that went just before (a stopping router closes its links in turn)
                    for other, gone in c.pending.items():
                        if now - gone["seen"] < LINKS_CLOSE_WITHIN_S:
                            c.cut_off.add(other)
                            gone["world_cut_off"] = True
                    c.cut_off.add(who)
                    event["world_cut_off"] = True
                if c.cut_off and not self.said_cut_off:
                    self.said_cut_off = True
                    self.event(f"world: cut off from its router at t = {self.clock.t:.2f} s: the agents' tokens "
                               "went with the link, and their departures are the world's, not theirs")
                    print(f"world: cut off from its router at t = {self.clock.t:.2f} s", file=sys.stderr, flush=True)
                c.pending[who] = {**event, "seen": time.monotonic()}
                self.settle_departures()
        else:
            c.cut_off.discard(who)
            if who in c.pending:  # back before its departure was told apart: tell it now
                self.settle_departures(force=True, only=who)
            if self.clock.step > 0 and who not in c.alive:  # after the start: a restart, or a late joiner
                returning = any(d["id"] == who for d in c.departures)
                self.event(f"agent {who} {'returned' if returning else 'joined'}")
            c.alive.add(who)
            self.intake.announced.setdefault(who, time.time())
            c.arrivals.append(event)
            if c.all_alive_after is None and len(c.alive) >= self.scenario.n_agents:
                c.all_alive_after = time.time() - self.started_wall

    def settle_departures(self, force: bool = False, only: int | None = None) -> None:
        """Tell each gone agent's departure apart (:func:`zswarm.net.watch.how_gone`): it *left* or it
        *crashed*; ``force`` settles the undecided as crashed (the run ends, or the agent is back)."""
        c, now = self.census, time.monotonic()
        for who, event in list(c.pending.items()):
            if only is not None and who != only:
                continue
            how = "world cut off" if event.get("world_cut_off") else \
                how_gone(self.stats.final(who), now - event["seen"], settle=force)
            if how == "going":
                continue
            del c.pending[who]
            c.departures.append({k: v for k, v in event.items() if k not in ("seen", "world_cut_off")} | {"how": how})
            self.event(f"agent {who} {how} at t = {event['t']:.2f} s" + {
                "left": "", "world cut off": " (its token went with the world's link)"}.get(
                how, " (no final report: killed or failed)"))

    def tell_unreachable(self) -> None:
        """A departure taken for a crash, whose agent's final report came from a process that started
        before it went, was no crash: that process lived on, frozen or cut off from its router for longer
        than its link's lease (Zenoh's, 10 s), and came back (docs/experiments.md)."""
        for d in self.census.departures:
            st = self.stats.get(d["id"]) if d["how"] == "crashed" else None
            if st is not None and st.final and st.born is not None and st.born < self.started_wall + d["wall"] - 1.0:
                d["how"] = "unreachable"
                self.event(f"agent {d['id']} was unreachable from t = {d['t']:.2f} s, not crashed: the process "
                           "that reported at the end had started before (frozen, or cut off from its router)")

    def answer_positions(self, _params: dict[str, str]) -> list[tuple[str, bytes]]:
        """The queryable ``keys.positions`` (on a Zenoh thread): where each live agent was last observed,
        for the driver that places agents on nodes (``zswarm run --migrate-every``); never for an agent."""
        seen = self.last_seen
        if seen is None:
            return []
        t, ids, pos = seen
        return [(self.keys.positions, msg.encode_positions(t, ids, pos))]

    def event(self, text: str) -> None:
        self.recorder.log_event(self.clock.step, self.clock.t, text)

    # --- one observed step ----------------------------------------------------------------------------

    def observe(self, snap: Snapshot) -> dict[str, float] | None:
        """Measure and record the swarm as it is now (the live agents' poses)."""
        if self.census.pending:
            self.settle_departures()
        ids, pos, vel = snap.ids, snap.pos, snap.vel
        if len(ids) == 0:
            return None
        metrics = self.observer.observe(self.clock.t, ids, pos, vel, self.prey)
        self.last_seen = (self.clock.t, ids, pos)  # fresh arrays, replaced whole: read on a Zenoh thread
        self.traffic.sample(pos, self.spec.subscription_radius, self.keys.cell_size)
        safety = (snap.safety, self.scenario.params.swarm.robot_radius) if self.spec.safety != "off" else None
        stamps = snap.stamps if self.spec.clock == "free" else None
        if stamps is not None:  # how far apart in time the poses it judges together were sent
            self.snapshot_spread = max(self.snapshot_spread, float(stamps.max() - stamps.min()))
        self.recorder.log_step(self.clock.step, self.clock.t, ids, pos, vel, self.prey,
                               {**metrics, "agents_alive": float(len(self.census.alive))}, snap.heading, safety,
                               stamps)
        self._log_network()
        return metrics

    def judge_contacts(self, every: float = 0.25, force: bool = False) -> None:
        """Free clock: judge the instants every agent's poses are in (:mod:`zswarm.swarm.timed_contacts`),
        every ``every`` seconds (each call walks every instant since the last, so calling less often
        loses nothing; a call costs about 3.5 ms at N = 1000); each collision found there is an event of
        the recording."""
        now = time.time()
        if self.timed is None or (not force and now - self.judged_wall < every):
            return
        self.judged_wall = now
        for onset in self.timed.judge(now):
            self.event(f"collision at one instant: agents {onset.i} and {onset.j} {onset.distance:.3f} apart "
                       f"(poses sent {onset.stamp - self.started_wall:.2f} s after the world started)")

    def _log_network(self, every: float = 1.0, agents_every: float = 5.0) -> None:
        """The network panel: the world's own counters each second, and the latency and data age the
        agents measured every few seconds (decoding every agent's stats costs, at N = 100)."""
        now = time.time()
        if now - self.network_logged < every or not self.recorder.recording:
            return
        span = now - self.network_logged if self.network_logged else every
        figures = {"poses_per_s": (self.received - self.network_received) / span,
                   "rejected": float(sum(self.rejected.counts.values())), "late_ticks": float(self.clock.late_ticks),
                   "agents_alive": float(len(self.census.alive))}
        if now - self.network_agents_logged >= agents_every:
            stats = self.stats.all()
            lat, ages = histogram.merge([s.latency_hist for s in stats]), histogram.merge([s.age_hist for s in stats])
            figures.update(latency_p50_ms=histogram.percentile(lat, 0.5), latency_p99_ms=histogram.percentile(lat, 0.99),
                           age_p50_ms=histogram.percentile(ages, 0.5), age_p99_ms=histogram.percentile(ages, 0.99))
            self.network_agents_logged = now
        self.recorder.log_network(self.clock.step, self.clock.t, figures)
        self.network_logged, self.network_received = now, self.received

    def next_prey(self, snap: Snapshot, dt: float) -> np.ndarray:
        """Where the prey is ``dt`` after now, fleeing the agents at ``snap``."""
        return prey_motion.step(self.scenario.prey, self.prey, dt, snap.pos.reshape(-1, self.dims))

    def publish(self, key: str, message: msg.Message, again: bool = False) -> None:
        """A tick is the clock every agent follows, and the final one is how they learn the run is
        over: ticks go ahead of data (a higher priority) and wait for room on a congested link rather
        than being dropped there. ``again``: a final tick repeated for the agents that have not reported
        (each of which is leaving: a repeat waits for no room, or it would stall the routers). The prey
        is data, batched with the poses: sent express, each tick's prey left the router as one write per
        agent, and the poses' latency p99 at N = 50 rose by half (docs/benchmarks.md)."""
        qos = RESENT_QOS if again else TICK_QOS if isinstance(message, msg.Tick) else {}
        self.session.put(key, msg.encode(message), encoding=msg.ENCODING, **qos)
        self.sent += 1

    def report_taken(self, agent: int) -> None:
        """Say that agent's final report is here: its cue to leave (it puts the report until then)."""
        self.session.put(self.keys.report_taken(agent), b"", express=True)

    # --- the clocks -----------------------------------------------------------------------------------

    async def wait_for_agents(self, bridge: Bridge, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        alive, n = self.census.alive, self.scenario.n_agents
        while len(alive) < n and loop.time() < deadline and not self.stop.is_set():
            await asyncio.sleep(0.05)
            bridge.drain()
        if len(alive) < n:
            print(f"world: {len(alive)} of {n} agents alive after {timeout:g} s; starting anyway",
                  file=sys.stderr, flush=True)

    async def run_free(self, bridge: Bridge, steps: int, progress: float) -> None:
        loop = asyncio.get_running_loop()
        clock, period, duration = self.clock, self.spec.period, steps * self.scenario.dt
        next_tick = loop.time()
        start = next_tick - clock.t / self.spec.time_scale  # a restarted world goes on from its t
        last_print = -math.inf
        while not self.stop.is_set():
            bridge.drain()  # every sample that arrived since the last tick
            live = self.intake.latest(self.census.alive)
            self.publish(self.keys.prey, msg.Prey(clock.step, time.time(), -1, *map(float, self.prey)))
            last_print = self._progress(self.observe(live), steps, progress, last_print)
            self.judge_contacts()
            if clock.t >= duration - 1e-9 or self.held_prey():
                break
            next_tick += period
            try:
                await asyncio.wait_for(self.stop.wait(), max(next_tick - loop.time(), 0.0))
            except asyncio.TimeoutError:
                pass
            lag = loop.time() - next_tick
            if lag > 0.5 * period:
                clock.late_ticks += 1
            if lag > STALL and not self.stalled:  # once per stall, not once per tick that catches up
                self.event(f"world clock stalled {lag:.1f} s (the world was frozen or starved of CPU)")
            self.stalled = lag > STALL
            t_new = min((loop.time() - start) * self.spec.time_scale, duration)
            self.prey = self.next_prey(live, t_new - clock.t)
            clock.t = t_new
            clock.step += 1

    async def run_lockstep(self, steps: int, progress: float, step_timeout: float, holds: list[float] = ()) -> None:
        """Tick k goes out once every live agent's pose of step k-1 is in (or ``step_timeout`` passed),
        before step k-1 is measured and recorded: the agents compute step k while the world records.
        ``holds``: run times at which the launcher stages a fault; the tick after each waits until it says
        it has (:attr:`go`), so that the fault starts at its time on the run's clock however late the
        launcher looks."""
        clock = self.clock
        last_print = -math.inf
        holds = list(holds)
        self.publish(self.keys.tick, msg.Tick(clock.step, time.time(), *map(float, self.prey)))
        while not self.stop.is_set():
            k = clock.step
            await self._await_poses(k, step_timeout)
            if holds and clock.t >= holds[0] - 1e-9:
                holds = [h for h in holds if h > clock.t + 1e-9]
                try:
                    await asyncio.wait_for(self.go.wait(), HOLD_MAX_S)
                except asyncio.TimeoutError:
                    pass
                self.go.clear()
            poses = self.intake.at_step(k, self.census.alive)
            prey = None
            if k < steps and not self.stop.is_set() and not self.held_prey():
                prey = self.next_prey(poses, self.scenario.dt)
                self.publish(self.keys.tick, msg.Tick(k + 1, time.time(), *map(float, prey)))
            last_print = self._progress(self.observe(poses), steps, progress, last_print)
            if prey is None:
                break
            self.prey = prey
            clock.step += 1
            clock.t = clock.step * self.scenario.dt

    def held_prey(self) -> bool:
        """``--end-after-capture S``: the prey was caught S simulated seconds ago or more."""
        if self.end_after_capture is None:
            return False
        if self.caught_at is None:
            self.caught_at = self.observer.summary.capture_time()
        return self.caught_at is not None and self.clock.t >= self.caught_at + self.end_after_capture - 1e-9

    async def _await_poses(self, k: int, timeout: float) -> None:
        """Until every live agent's pose of step ``k`` is in, or ``timeout`` seconds (the ones missing then
        are counted)."""
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while not self.stop.is_set():
            missing = self.intake.missing(k, self.census.alive)
            if not missing or loop.time() > deadline:
                self.clock.missed_poses += len(missing)
                return
            self.pose_arrived.clear()
            try:
                await asyncio.wait_for(self.pose_arrived.wait(), deadline - loop.time())
            except asyncio.TimeoutError:
                pass

    def _progress(self, metrics: dict[str, float] | None, steps: int, every: float, last: float) -> float:
        now = time.time()
        if every <= 0 or now - last < every:
            return last
        d = metrics["centroid_goal_distance"] if metrics else float("nan")
        cap = self.observer.summary.capture_time()
        print(f"t={self.clock.t:7.2f}/{steps * self.scenario.dt:.1f} s  agents {len(self.census.alive)}/"
              f"{self.scenario.n_agents}  centroid-prey {d:6.3f}  "
              + (f"captured at {cap:.2f} s" if cap is not None else "not captured"), flush=True)
        return now

    # --- end ------------------------------------------------------------------------------------------

    def _timed_result(self) -> dict[str, Any]:
        """The collisions judged at one instant, after judging what came in last (free clock only)."""
        if self.timed is None:
            return {}
        self.judge_contacts(force=True)
        return self.timed.result()

    def _design(self) -> dict[str, Any]:
        """The verdict :meth:`judge_design` reached (judged here if it was not asked, or failed)."""
        if self.design_judge is not None:
            self.design_judge.join()
        return self.design if self.design is not None else verdict(self.scenario.params, self.scenario.dt, self.spec.safety)

    def finish(self) -> dict[str, Any]:
        """The run's summary: outcome (the observer's), transport (the agents' stats) and the world's
        own figures; stored in the recording and written beside it."""
        s, c = self.spec, self.clock
        result = {"scenario": self.scenario.name, "n_agents": self.scenario.n_agents, "seed": s.seed,
                  "potential": s.combination, "duration": c.t, "steps": c.step, "dt": self.scenario.dt,
                  **self.observer.summary.result(), "clock": s.clock, "time_scale": s.time_scale,
                  "safety": s.safety, "run": s.run,
                  **transport_summary(self.stats.all(), self.rejected.counts)}
        result["messages_sent"] += self.sent
        result["messages_received"] += self.received
        self.settle_departures(force=True)
        self.tell_unreachable()
        if self.ending:  # an agent that sent its final report is stopping with the run, token or not yet
            self.census.stopped_at_end += [w for w in sorted(self.census.alive)
                                           if self.stats.final(w) and w not in self.census.stopped_at_end]
        if self.census.stopped_at_end:
            self.event(f"run ended: {len(self.census.stopped_at_end)} agents stopped with it")
        result.update({"startup_s": self.census.all_alive_after, "departures": self.census.departures,
                       "stopped_at_end": sorted(self.census.stopped_at_end),
                       "requested_faults": s.faults.requested(), "missed_lockstep_poses": c.missed_poses,
                       "world_late_ticks": c.late_ticks, "world_ticks": c.step + 1,
                       "poses_in_reach_per_s": self.traffic.per_s(s.period),
                       "world_segments": self.recorder.segment + 1, "end_after_capture": self.end_after_capture,
                       "snapshot_spread_max_s": self.snapshot_spread if s.clock == "free" else None,
                       **self._timed_result(),
                       "resumed_from": None if self.resumed is None else self.resumed.to_dict(),
                       "design": self._design(), "law": self.law})
        self.recorder.close(result)
        return result
