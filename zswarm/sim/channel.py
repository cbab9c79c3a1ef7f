"""The transport's faults inside the reference simulator: delayed, lossy neighbour and prey data.

Every step each agent j "publishes" its position, and the prey its own; on every link (i, j) the
message is lost or delayed by the same rules as :mod:`zswarm.model.faults` (fixed delay plus uniform
jitter, rounded to whole steps; Bernoulli or Gilbert-Elliott loss; distance-dependent loss of poses).
Agent i then believes, of each j, the newest position that has reached it, and ignores beliefs older
than the staleness limit, as a distributed agent does. All of it is dense (N x N) numpy; meant for the
swarm sizes the distributed runs use (it refuses N > 2000). Obstacles are not faulted here.
"""

from __future__ import annotations

import math

import numpy as np

from zswarm.model.faults import FaultModel

MAX_AGENTS = 2000


class FaultyChannel:
    def __init__(self, n: int, model: FaultModel, dt: float, sensing_radius: float, staleness: float = 0.5,
                 seed: int = 0) -> None:
        if n > MAX_AGENTS:
            raise ValueError(f"faults in the simulator handle at most {MAX_AGENTS} agents (got {n})")
        self.n, self.m, self.dt, self.radius = n, model, dt, sensing_radius
        self.rng = np.random.default_rng([seed, 0x5EED])
        self.max_delay = int(math.ceil((model.latency + model.jitter) / dt)) + 1
        self.slots = self.max_delay + 1
        s = n + 1  # column n is the prey
        self.history = np.zeros((self.slots, s, 2))
        self.incoming = np.full((self.slots, n, s), -1, dtype=np.int64)
        self.belief_stamp = np.full((n, s), -1, dtype=np.int64)
        self.belief_pos = np.zeros((n, s, 2))
        self.bad = np.zeros((n, s), dtype=bool)  # Gilbert-Elliott state per link
        self.stale_steps = int(round(staleness / dt))
        self.sent = self.lost = 0
        self.delay_counts = np.zeros(self.max_delay + 1, dtype=np.int64)

    def step(self, k: int, positions: np.ndarray, prey: np.ndarray):
        """Publish step k, deliver what arrives at step k; return (i, j, believed positions, goal per agent)."""
        n, m = self.n, self.m
        sources = np.vstack([positions, prey[None]])
        self.history[k % self.slots] = sources
        u = self.rng.random((3, n, n + 1))
        if m.burst > 0 and m.dropout > 0:
            r = 1.0 / m.burst
            p = m.dropout * r / (1.0 - m.dropout)
            self.bad = np.where(self.bad, u[0] >= r, u[0] < p)
            lost = self.bad.copy()
        else:
            lost = u[0] < m.dropout
        if m.distance_loss > 0:
            d = np.linalg.norm(positions[:, None, :] - sources[None, :, :], axis=-1)
            ratio = np.minimum(d / self.radius, 1e3)
            ratio[:, n] = 0.0  # the prey is not lost with distance
            lost |= u[1] < m.distance_loss * ratio**2
        np.fill_diagonal(lost[:, :n], True)  # nobody listens to itself
        delay = np.maximum(np.rint((m.latency + m.jitter * (2.0 * u[2] - 1.0)) / self.dt), 0).astype(np.int64)
        ok = ~lost
        self.sent += int(n * n)  # n (n - 1) pose links and n prey links
        self.lost += int(lost.sum()) - n
        arrive = (k + delay) % self.slots
        ii, jj = np.nonzero(ok)
        self.delay_counts += np.bincount(delay[ii, jj], minlength=len(self.delay_counts))[:len(self.delay_counts)]
        slot = arrive[ii, jj]
        np.maximum.at(self.incoming, (slot, ii, jj), k)
        now = self.incoming[k % self.slots]
        newer = now > self.belief_stamp
        bi, bj = np.nonzero(newer)
        self.belief_stamp[bi, bj] = now[bi, bj]
        self.belief_pos[bi, bj] = self.history[now[bi, bj] % self.slots, bj]
        self.incoming[k % self.slots] = -1
        fresh = (self.belief_stamp >= 0) & (k - self.belief_stamp <= self.stale_steps)
        goal = np.where(fresh[:, n, None], self.belief_pos[:, n], np.nan)
        near = fresh[:, :n] & (np.linalg.norm(positions[:, None, :] - self.belief_pos[:, :n], axis=-1) <= self.radius)
        i, j = np.nonzero(near)
        return i, j, self.belief_pos[i, j], goal

    @property
    def observed_latency_ms(self) -> float | None:
        """Median delay of the delivered messages (whole steps)."""
        total = int(self.delay_counts.sum())
        if total == 0:
            return None
        k = int(np.searchsorted(np.cumsum(self.delay_counts), (total + 1) // 2))
        return k * self.dt * 1000.0

    @property
    def observed_dropout(self) -> float | None:
        return self.lost / self.sent if self.sent else None
