"""Network faults inside the reference simulator, for one run or many at once: delayed, lossy
neighbour and prey data (:mod:`zswarm.sim.channel` is this with a batch of one).

Run r draws from its own generator, ``default_rng([faults_r.seed, 0x5EED])``, three uniforms per link
and step (drawn ahead in blocks of steps: a PCG64 stream gives the same doubles whether asked for one
step or many), so a run's faults do not depend on the other runs of its batch. The rules: delay
(latency + uniform jitter, whole steps), Bernoulli or Gilbert-Elliott loss, distance-dependent loss of
poses, newest-message beliefs and the staleness limit.
"""

from __future__ import annotations

import math

import numpy as np

from zswarm.swarm.faults import FaultModel
from zswarm.paper.neighbours import cell_meets, subscription_radius

BLOCK = 32  # steps of uniforms drawn per generator call, at most
BLOCK_BYTES = 64 * 2**20  # and at most this much memory for them (N = 2000 draws 96 MB a step: one at a time)


class BatchChannel:
    def __init__(self, n: int, models: list[FaultModel], dt: float, sensing_radius: np.ndarray,
                 v_max: np.ndarray, staleness: float = 0.5, dims: int = 2, velocities: bool = False,
                 headings: bool = False) -> None:
        """``sensing_radius``, ``v_max``: of each run (B,). An agent's cells cover the disc
        R + 2 v_max dt about it (:attr:`zswarm.net.runspec.RunSpec.subscription_radius`).
        ``velocities``: carry each pose's velocity with it (a law that uses its neighbours' velocities;
        otherwise they read as 0, and the runs do not pay for them); ``headings``: each pose's heading (a
        unicycle's: the safety filter guards its point ahead of its axle)."""
        self.velocities = velocities
        b = len(models)
        self.n, self.dt = n, dt
        self.rngs = [np.random.default_rng([m.seed, 0x5EED]) for m in models]
        col = lambda name: np.array([getattr(m, name) for m in models], dtype=float)[:, None, None]  # noqa: E731
        self.latency, self.jitter, self.dropout = col("latency"), col("jitter"), col("dropout")
        self.distance_loss = col("distance_loss")
        burst = col("burst")
        self.gilbert = (burst > 0) & (self.dropout > 0)
        self.r_bad = np.where(self.gilbert, 1.0 / np.where(burst > 0, burst, 1.0), 0.0)
        self.p_bad = np.where(self.gilbert, self.dropout * self.r_bad / (1.0 - self.dropout), 0.0)
        self.radius = np.asarray(sensing_radius, dtype=float)[:, None, None]
        self.v_max = np.asarray(v_max, dtype=float)[:, None, None]
        self.cells = subscription_radius(self.radius, self.v_max, dt)
        max_delay = max(int(math.ceil((m.latency + m.jitter) / dt)) + 1 for m in models)
        self.slots = max_delay + 1  # a ring longer than any run's delay: the same arrivals as its own ring
        s = n + 1  # column n is the prey
        self.history = np.zeros((b, self.slots, s, dims))
        motion = (b, self.slots, n, dims) if velocities else (b, 1, n, dims)
        self.history_velocity = np.zeros(motion)  # what each pose says of its velocity
        self.belief_velocity = np.zeros((b, n, n, dims) if velocities else (b, 1, n, dims))
        self.history_heading = np.zeros((b, self.slots, n)) if headings else None
        self.belief_heading = np.zeros((b, n, n)) if headings else None
        self.incoming = np.full((b, self.slots, n, s), -1, dtype=np.int64)
        self.belief_stamp = np.full((b, n, s), -1, dtype=np.int64)
        self.belief_received = np.full((b, n, n), -1, dtype=np.int64)  # the step each newest pose arrived
        self.belief_pos = np.zeros((b, n, s, dims))
        self.bad = np.zeros((b, n, s), dtype=bool)
        self.stale_steps = int(round(staleness / dt))
        self.lost = np.zeros(b, dtype=np.int64)
        self.steps = 0  # steps published: n (n - 1) pose links and n prey links each
        self.delay_counts = np.zeros((b, max_delay + 1), dtype=np.int64)  # delivered messages by delay (steps)
        self.block = max(1, min(BLOCK, BLOCK_BYTES // (b * 3 * n * (n + 1) * 8)))
        self._uniforms: np.ndarray | None = None
        self._block_start = 0

    def _draws(self, k: int) -> np.ndarray:
        """(B, 3, N, N + 1) uniforms of step k, from each run's generator in its own order."""
        if self._uniforms is None or not self._block_start <= k < self._block_start + self.block:
            shape = (self.block, 3, self.n, self.n + 1)
            self._uniforms = np.stack([rng.random(shape) for rng in self.rngs], axis=1)
            self._block_start = k
        return self._uniforms[k - self._block_start]

    def step(self, k: int, positions: np.ndarray, prey: np.ndarray, velocities: np.ndarray | None = None,
             headings: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Publish step k and deliver what arrives at it; (positions (B, N, 2), prey (B, 2)) ->
        (believed positions (B, N, N, 2), which of them agent i uses (B, N, N), goal per agent (B, N, 2),
        NaN where no fresh prey position has reached it). ``velocities`` (B, N, 2): what each pose says
        of its sender's velocity, believed with its position (:meth:`heard_motion`)."""
        n = self.n
        self.steps += 1
        sources = np.concatenate([positions, prey[:, None, :]], axis=1)
        self.history[:, k % self.slots] = sources
        if self.velocities:
            self.history_velocity[:, k % self.slots] = velocities
        if self.history_heading is not None:
            self.history_heading[:, k % self.slots] = headings
        u = self._draws(k)
        self.bad = np.where(self.bad, u[:, 0] >= self.r_bad, u[:, 0] < self.p_bad)
        lost = np.where(self.gilbert, self.bad, u[:, 0] < self.dropout)
        d = np.linalg.norm(positions[:, :, None, :] - sources[:, None, :, :], axis=-1)
        ratio = np.minimum(d / self.radius, 1e3)
        ratio[:, :, n] = 0.0  # the prey is not lost with distance
        lost |= (self.distance_loss > 0) & (u[:, 1] < self.distance_loss * ratio**2)
        lost[:, np.arange(n), np.arange(n)] = True  # nobody listens to itself
        self.lost += lost.sum(axis=(1, 2)) - n
        delay = np.maximum(np.rint((self.latency + self.jitter * (2.0 * u[:, 2] - 1.0)) / self.dt), 0).astype(np.int64)
        rr, ii, jj = np.nonzero(~lost)
        delivered = delay[rr, ii, jj]
        self.incoming[rr, (k + delivered) % self.slots, ii, jj] = k  # k is the newest stamp yet
        width = self.delay_counts.shape[1]
        self.delay_counts += np.bincount(rr * width + np.minimum(delivered, width - 1),
                                         minlength=self.delay_counts.size).reshape(self.delay_counts.shape)
        now = self.incoming[:, k % self.slots]
        newer = now > self.belief_stamp
        br, bi, bj = np.nonzero(newer)
        stamp = now[br, bi, bj]
        self.belief_stamp[br, bi, bj] = stamp
        self.belief_received[newer[:, :, :n]] = k
        self.belief_pos[br, bi, bj] = self.history[br, stamp % self.slots, bj]
        pose = bj < n
        if self.velocities:
            self.belief_velocity[br[pose], bi[pose], bj[pose]] = self.history_velocity[
                br[pose], stamp[pose] % self.slots, bj[pose]]
        if self.history_heading is not None:
            self.belief_heading[br[pose], bi[pose], bj[pose]] = self.history_heading[
                br[pose], stamp[pose] % self.slots, bj[pose]]
        self.incoming[:, k % self.slots] = -1
        fresh = (self.belief_stamp >= 0) & (k - self.belief_stamp <= self.stale_steps)
        goal = np.where(fresh[:, :, n, None], self.belief_pos[:, :, n], np.nan)
        believed = self.belief_pos[:, :, :n]
        near = fresh[:, :, :n] & (np.linalg.norm(positions[:, :, None, :] - believed, axis=-1) <= self.radius)
        return believed, near, goal

    def observed_dropout(self, r: int) -> float | None:
        """The share of run r's messages lost so far."""
        sent = self.steps * self.n * self.n
        return int(self.lost[r]) / sent if sent else None

    def observed_latency_ms(self, r: int) -> float | None:
        """The median delay of run r's delivered messages (whole steps)."""
        counts = self.delay_counts[r]
        total = int(counts.sum())
        if total == 0:
            return None
        return int(np.searchsorted(np.cumsum(counts), (total + 1) // 2)) * self.dt * 1000.0

    def heard_motion(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """After :meth:`step` k: the velocity each agent believes of each other (B, N, N, D), and the
        age of that belief in seconds (B, N, N)."""
        stamp = self.belief_stamp[:, :, : self.n]
        return np.broadcast_to(self.belief_velocity, stamp.shape + self.belief_velocity.shape[-1:]), (k - stamp) * self.dt

    def known(self, k: int, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """After :meth:`step` k, what the safety filter guards against, by an agent process's own rule
        (:meth:`agents.sensing.Sensing.sense` and ``_guarded``, in steps): every neighbour an agent has
        heard whose newest position may be within the sensing radius of it by now (no farther than
        v_max times its age beyond it), less the ones that have gone quiet and can have left. Quiet:
        nothing came from it for the staleness limit longer than from the one heard last, beyond its
        own path's extra delay (how much later its newest pose arrived after it was sent than the
        promptest neighbour's). Can have left: its newest position plus what it can have moved while
        the freshest was still heard (v_max times its age beyond the freshest's) reaches past the
        subscription disc. Kept all the same when its member token, ``latency`` old (tokens are not
        lost), is in a cell the agent listens to. As (mask (B, N, N), believed positions (B, N, N, D),
        ages in seconds (B, N, N))."""
        stamp = self.belief_stamp[:, :, : self.n]
        believed = self.belief_pos[:, :, : self.n]
        age = (k - stamp) * self.dt
        d = np.linalg.norm(positions[:, :, None, :] - believed, axis=-1)
        heard = (stamp >= 0) & (d - self.v_max * age <= self.radius)
        quiet, lag = k - self.belief_received, self.belief_received - stamp  # steps
        least = lambda a: np.where(heard, a, np.iinfo(np.int64).max).min(axis=-1, keepdims=True)  # noqa: E731
        gone_quiet = quiet - np.maximum(lag - least(lag), 0) > least(quiet) + self.stale_steps
        can_have_left = d + self.v_max * (stamp.max(axis=-1, keepdims=True, initial=-1, where=heard) - stamp) * self.dt > self.cells
        heard &= ~(gone_quiet & can_have_left) | self._members(k, positions)
        return heard, believed, age

    def _members(self, k: int, positions: np.ndarray) -> np.ndarray:
        """(B, N, N): j's member token, ``latency`` old, in a cell agent i listens to (the cells, of side
        the sensing radius, that its subscription disc meets)."""
        lag = np.rint(self.latency[:, 0, 0] / self.dt).astype(np.int64)  # (B,): tokens have no jitter
        then = k - lag
        where = self.history[np.arange(len(lag)), then % self.slots, : self.n]  # (B, N, D)
        meets = cell_meets(positions[:, :, None, :], where[:, None, :, :], self.cells, self.radius[..., None])
        return (then >= 0)[:, None, None] & meets
