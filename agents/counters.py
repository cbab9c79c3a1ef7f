"""An agent's counters, and the stats message that carries them to the world once a second."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from zswarm.net import histogram
from zswarm.net import messages as msg
from zswarm.net.poses import Rejections


@dataclass
class Counters:
    rejections: Rejections
    sent: int = 0
    received: int = 0
    poses: int = 0  # other agents' poses taken in
    crossed: int = 0  # ... sent from another router
    ticks: int = 0
    late_ticks: int = 0
    late_s: float = 0.0  # free clock: how far late ticks moved the schedule on, in all (seconds)
    interventions: int = 0  # the safety filter: ticks it changed the command
    stalled_ticks: int = 0  # ... left it under a tenth of the law's speed
    braked_ticks: int = 0  # ... stopped the agent on data older than its bound
    stalled_run: int = 0  # ticks in a row stalled now
    stalled_long: bool = False  # stalled for a second or more in a row, at some point
    ages: dict[int, int] = field(default_factory=dict)  # histogram: age of neighbour data when used
    latency: dict[int, int] = field(default_factory=dict)  # histogram: publish-to-receipt of poses
    obstacle_queries_failed: int = 0
    heard: dict[int, int] = field(default_factory=dict)  # id -> poses of it taken in
    seq_received: int = 0
    seq_lost: int = 0
    born: float = field(default_factory=time.time, compare=False)  # wall time its first process started (a taker-over carries it)
    departed: dict[int, float] = field(default_factory=dict)
    returned: dict[int, float] = field(default_factory=dict)
    # since the last stats message: the longest inbound queue seen at a tick, and the latest tick start
    window_queue_max: int = 0
    window_lag_ms: float = 0.0

    def count_sequence(self, pose: msg.Pose, nb, last: int | None, distance, radius: float) -> int:
        """Observed loss from sequence numbers: a gap of g counts g - 1 lost when the sender was within
        the sensing radius both before and after it (then every pose it sent reached the agent's cells;
        otherwise it may simply have been out of range); a late arrival that filled a gap is taken back.
        ``nb``: what it held of the sender before this pose, ``last`` the newest sequence number it saw of
        it; returns the newest now."""
        if last is not None and nb is not None and distance(pose) <= radius and distance(nb.latest) <= radius:
            if pose.seq > last:
                self.seq_lost += pose.seq - last - 1 if pose.seq - last - 1 <= 50 else 0
                self.seq_received += 1
            elif pose.seq < last and self.seq_lost > 0:
                self.seq_lost -= 1
                self.seq_received += 1
        return max(pose.seq, last or 0)

    @staticmethod
    def add(hist: dict[int, int], ms: float) -> None:
        b = histogram.to_bin(ms)
        hist[b] = hist.get(b, 0) + 1

    def stats(self, agent: int, period: float, injected: tuple[int, int] = (0, 0), final: bool = False) -> msg.Stats:
        """The stats message (``period``: the agent's tick period, in which the ticks it let go by are
        counted; ``injected``: messages the fault injector dropped and passed)."""
        health = msg.Health(obstacle_queries_failed=self.obstacle_queries_failed, seq_received=self.seq_received,
                            seq_lost=self.seq_lost, injected_drops=injected[0], injected_passed=injected[1],
                            queue_max=self.window_queue_max, tick_lag_max_ms=float(self.window_lag_ms),
                            poses=self.poses, crossed=self.crossed, interventions=self.interventions,
                            stalled_ticks=self.stalled_ticks, braked_ticks=self.braked_ticks,
                            stalled_long=int(self.stalled_long), skipped_ticks=int(self.late_s / period))
        heard, heard_poses = self.heard_lists()
        return msg.Stats(agent, self.sent, self.received, dict(self.rejections.counts), self.late_ticks, self.ticks,
                         dict(self.ages), dict(self.latency), final, health, heard,
                         dict(self.departed), dict(self.returned), heard_poses, self.born)

    def heard_lists(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The ids heard (sorted, at most MAX_HEARD) and the poses taken in from each."""
        ids = tuple(sorted(self.heard))[:msg.MAX_HEARD]
        return ids, tuple(self.heard[i] for i in ids)

    def new_window(self) -> None:
        self.window_queue_max, self.window_lag_ms = 0, 0.0
