"""The transport's faults inside the reference simulator: delayed, lossy neighbour and prey data.

Every step each agent j "publishes" its position, and the prey its own; on every link (i, j) the
message is lost or delayed by the same rules as :mod:`zswarm.swarm.faults` (fixed delay plus uniform
jitter, rounded to whole steps; Bernoulli or Gilbert-Elliott loss; distance-dependent loss of poses).
Agent i then believes, of each j, the newest position that has reached it, and ignores beliefs older
than the staleness limit, as a distributed agent does. All of it is dense (N x N) numpy; meant for the
swarm sizes the distributed runs use (it refuses N > 2000). Obstacles are not faulted here.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from zswarm.swarm.faults import FaultModel
from zswarm.sim.batch_channel import BatchChannel

MAX_AGENTS = 2000


class FaultyChannel:
    """One run's faulty channel: :class:`zswarm.sim.batch_channel.BatchChannel` with a batch of one
    (the same rules, the same draws), plus the counters a run's summary reports."""

    def __init__(self, n: int, model: FaultModel, dt: float, sensing_radius: float, v_max: float,
                 staleness: float = 0.5, seed: int = 0, dims: int = 2, velocities: bool = False,
                 headings: bool = False) -> None:
        if n > MAX_AGENTS:
            raise ValueError(f"faults in the simulator handle at most {MAX_AGENTS} agents (got {n})")
        self.n, self.dt = n, dt
        self.batch = BatchChannel(n, [dataclasses.replace(model, seed=seed)], dt, np.array([sensing_radius]),
                                  np.array([v_max]), staleness, dims, velocities, headings)

    def step(self, k: int, positions: np.ndarray, prey: np.ndarray, velocities: np.ndarray | None = None,
             headings: np.ndarray | None = None):
        """Publish step k, deliver what arrives at step k; return (i, j, believed positions, goal per agent).
        ``velocities``: each agent's, carried with its pose (:meth:`heard_motion`)."""
        believed, near, goal = self.batch.step(k, positions[None], np.asarray(prey, dtype=float)[None],
                                               None if velocities is None else velocities[None],
                                               None if headings is None else headings[None])
        i, j = np.nonzero(near[0])
        return i, j, believed[0][i, j], goal[0]

    def heard_motion(self, k: int, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """After :meth:`step` k: the velocity agent i believes of j and that belief's age (s), per pair."""
        velocity, age = self.batch.heard_motion(k)
        return velocity[0][i, j], age[0][i, j]

    def known(self, k: int, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """After :meth:`step` k: every neighbour each agent has heard at all (fresh or stale) whose
        newest position may be within the sensing radius of it by now, as (i, j, P_j believed, age in
        seconds): :meth:`~zswarm.sim.batch_channel.BatchChannel.known`."""
        heard, believed, age = self.batch.known(k, positions[None])
        i, j = np.nonzero(heard[0])
        return i, j, believed[0][i, j], age[0][i, j]

    @property
    def headings(self) -> np.ndarray | None:
        """The heading each agent believes of each other (N, N), where the channel carries them."""
        return None if self.batch.belief_heading is None else self.batch.belief_heading[0]

    @property
    def observed_latency_ms(self) -> float | None:
        """Median delay of the delivered messages (whole steps)."""
        return self.batch.observed_latency_ms(0)

    @property
    def observed_dropout(self) -> float | None:
        return self.batch.observed_dropout(0)
