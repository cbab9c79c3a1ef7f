"""What a bystander hears of a running swarm: the figures of ``zswarm monitor``.

A :class:`RunWatch` subscribes, on any session that reaches the run's router, to the agents'
liveliness tokens, their poses, their stats and the prey, through the one bridge (samples wait in ring
channels; :meth:`RunWatch.poll` takes them in). It decodes and validates every message like an agent
does, counting what it rejects by reason, and folds it into a :class:`Snapshot`: agents alive, pose
rate per agent over the last window, the pose latency and data age the agents themselves measured
(their cumulative histograms), rejected messages by reason, late ticks and the prey.
"""

from __future__ import annotations

import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any

from zswarm.net import histogram
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge, teardown
from zswarm.net.keys import Keys

WINDOW = 2.0  # seconds over which pose rates are counted
#: How long after an agent's token is gone a watcher (the world, a monitor) waits for its final report
#: before it calls the departure a crash (the report and the token come on different channels, in
#: either order).
CRASH_GRACE_S = 1.0
#: How long after the world's final tick a watcher waits for the run's agents to stop before it says
#: how the run ended anyway.
END_SETTLE_S = 3.0


def how_gone(final_report: bool, waited_s: float, settle: bool = False) -> str:
    r"""How an agent whose liveliness token went has gone: *left* (its final report came: stopped
    cleanly), *crashed* (no report after :data:`CRASH_GRACE_S`, or none by the time it must be
    ``settle``\ d), or *going* (not yet told apart)."""
    if final_report:
        return "left"
    return "crashed" if settle or waited_s >= CRASH_GRACE_S else "going"


@dataclass
class Snapshot:
    t: float
    alive: list[int]
    pose_rate: dict[int, float]  # poses per second per agent over the last window
    latency_p50_ms: float | None
    latency_p99_ms: float | None
    age_p50_ms: float | None
    age_p99_ms: float | None
    rejected: dict[str, int]
    late_ticks: int
    ticks: int
    prey: tuple[float, ...] | None
    prey_rate: float
    agents_reporting: int
    gone: dict[int, str] = field(default_factory=dict)  # id -> "crashed", "left", "run ended" or "going"

    @property
    def mean_pose_rate(self) -> float | None:
        rates = [self.pose_rate.get(i, 0.0) for i in self.alive]
        return sum(rates) / len(rates) if rates else None

    def to_dict(self) -> dict[str, Any]:
        return {"t": self.t, "alive": len(self.alive), "alive_ids": self.alive,
                "mean_pose_rate": self.mean_pose_rate, "pose_rate": {str(k): v for k, v in self.pose_rate.items()},
                "latency_p50_ms": self.latency_p50_ms, "latency_p99_ms": self.latency_p99_ms,
                "age_p50_ms": self.age_p50_ms, "age_p99_ms": self.age_p99_ms, "rejected": self.rejected,
                "late_ticks": self.late_ticks, "ticks": self.ticks, "prey": self.prey, "prey_rate": self.prey_rate,
                "agents_reporting": self.agents_reporting, "gone": {str(k): v for k, v in self.gone.items()}}


@dataclass
class RunWatch:
    keys: Keys
    bridge: Bridge | None = None
    alive: set[int] = field(default_factory=set)
    poses: dict[int, deque] = field(default_factory=dict)  # arrival times within the window
    prey_times: deque = field(default_factory=deque)
    prey: tuple[float, ...] | None = None
    stats: dict[int, msg.Stats] = field(default_factory=dict)
    own_rejections: Counter = field(default_factory=Counter)
    declared: list = field(default_factory=list)
    started: float = 0.0
    gone_at: dict[int, float] = field(default_factory=dict)  # id -> when its token went (it has not returned)
    gone_after_end: set[int] = field(default_factory=set)
    ended: bool = False  # the world announced the final tick
    ended_at: float | None = None  # when this watch heard it (its own clock)

    def start(self, session) -> None:
        self.started = time.time()
        self.bridge = Bridge(session, None, deliver=self.handle, channels=True)
        self.declared = [self.bridge.subscribe_liveliness(self.keys.all_alive, "alive"),
                         self.bridge.subscribe(self.keys.all_poses, "pose"),
                         self.bridge.subscribe(self.keys.all_stats, "stats"),
                         self.bridge.subscribe(self.keys.prey, "prey"),
                         self.bridge.subscribe(self.keys.tick, "tick")]

    def stop(self, session) -> None:
        if self.bridge is not None:
            teardown(self.bridge, self.declared, session)

    def poll(self) -> None:
        if self.bridge is not None:
            self.bridge.drain()

    def handle(self, item) -> None:
        tag, key, payload, deleted, received = item
        if tag == "alive":
            agent = Keys.agent_of(key)
            if agent is not None:
                (self.alive.discard if deleted else self.alive.add)(agent)
                if deleted:
                    self.gone_at[agent] = received
                    if self.ended:
                        self.gone_after_end.add(agent)
                else:
                    self.gone_at.pop(agent, None)
                    self.gone_after_end.discard(agent)
            return
        try:
            message = msg.decode(payload)
        except msg.DecodeError as exc:
            self.own_rejections[exc.reason] += 1
            return
        if tag == "pose" and isinstance(message, msg.Pose):
            self.poses.setdefault(message.id, deque()).append(received)
        elif tag == "stats" and isinstance(message, msg.Stats):
            self.stats[message.id] = message
        elif tag == "tick" and isinstance(message, msg.Tick):
            if message.final and not self.ended:
                self.ended, self.ended_at = True, received
        elif tag == "prey" and isinstance(message, msg.Prey):
            self.prey = message.position
            self.prey_times.append(received)
        else:
            self.own_rejections["unexpected"] += 1

    def snapshot(self, now: float | None = None) -> Snapshot:
        now = time.time() if now is None else now
        window = min(WINDOW, max(now - self.started, 1e-3))  # a watch younger than the window has heard less
        for times in (*self.poses.values(), self.prey_times):
            while times and times[0] < now - WINDOW:
                times.popleft()
        latency: Counter = Counter()
        age: Counter = Counter()
        rejected: Counter = Counter(self.own_rejections)
        late = ticks = 0
        for s in self.stats.values():
            latency.update(s.latency_hist)
            age.update(s.age_hist)
            rejected.update(s.rejected)
            late += s.late_ticks
            ticks += s.ticks
        return Snapshot(t=now, alive=sorted(self.alive),
                        pose_rate={i: len(t) / window for i, t in sorted(self.poses.items())},
                        latency_p50_ms=histogram.percentile(latency, 0.5), latency_p99_ms=histogram.percentile(latency, 0.99),
                        age_p50_ms=histogram.percentile(age, 0.5), age_p99_ms=histogram.percentile(age, 0.99),
                        rejected={k: v for k, v in sorted(rejected.items()) if v},
                        late_ticks=late, ticks=ticks, prey=self.prey, prey_rate=len(self.prey_times) / window,
                        agents_reporting=len(self.stats), gone=self.gone(now))

    def over(self, now: float, settle_s: float = END_SETTLE_S) -> bool:
        """The run has ended (the world's final tick) and its agents have stopped, or ``settle_s`` passed."""
        return self.ended and (not self.alive or now - self.ended_at >= settle_s)

    def ending(self, now: float) -> str:
        """One line: how the run ended, as heard here."""
        gone = self.gone(now)
        ended = sorted(i for i, how in gone.items() if how in ("run ended", "left"))
        crashed = sorted(i for i, how in gone.items() if how == "crashed")
        line = f"the run ended: {len(ended)} agents stopped with it"
        if crashed:
            line += f", {len(crashed)} had crashed before ({', '.join(map(str, crashed))})"
        if self.alive:
            line += f", {len(self.alive)} still heard {now - self.ended_at:.0f} s after its end ({', '.join(map(str, sorted(self.alive)))})"
        return line

    def gone(self, now: float) -> dict[int, str]:
        """Each agent whose token went and has not come back: *run ended* (after the final tick), *left*
        (its final report came: stopped cleanly), *crashed* (none within the world's grace), or *going*."""
        out = {}
        for who, at in sorted(self.gone_at.items()):
            s = self.stats.get(who)
            out[who] = "run ended" if who in self.gone_after_end else how_gone(s is not None and s.final, now - at)
        return out
