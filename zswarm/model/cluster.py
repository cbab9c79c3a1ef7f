"""A swarm squeezed against an obstacle (Fig 10): a brute-force check of what Props 4 and 5 promise.

Props 3-5 reason about one pair, or bound forces one at a time. A swarm adds up N - 1 attractions on
every agent, and the goal's pull presses the whole swarm against an obstacle that lies on its way
(Fig 10, the case Prop 4 is about). With soft (bounded) repulsion the sum can squeeze neighbours far
closer than the pair spacing d^f, or onto each other. This module runs exactly that case with the full
control law (eq 36, speed limit, sensing radius): N agents start in a disc behind a point obstacle that
sits on the straight line to a static goal, and it records the closest any two agents and any agent
and the obstacle come during the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from zswarm.model.neighbours import pairs_within
from zswarm.model.params import PotentialParams
from zswarm.model.potentials import field, formation_offset, saturate

MAX_AGENTS = 60  # beyond this the check uses 60 agents (it is a design check, not a benchmark)


@dataclass(frozen=True)
class Squeeze:
    n_agents: int
    min_pair_distance: float  # over the whole run
    min_obstacle_distance: float  # over the whole run
    final_median_nearest: float


@lru_cache(maxsize=512)
def squeeze(p: PotentialParams, n_agents: int, sensing_radius: float, v_max: float, seed: int = 2006,
            duration: float = 60.0, dt: float = 0.05) -> Squeeze:
    n = min(n_agents, MAX_AGENTS)
    rng = np.random.default_rng(seed)
    spacing = 0.5
    radius = spacing * math.sqrt(n) / 1.5
    angle = rng.uniform(0.0, 2.0 * np.pi, n)
    rad = radius * np.sqrt((np.arange(n) + 0.5) / n)  # evenly filled disc, shuffled angles
    x = np.column_stack([-2.0 - radius + rad * np.cos(angle), rad * np.sin(angle)])
    obstacle = np.array([[-1.0, 0.0]])
    c_f = formation_offset(p)
    min_pair = min_obs = math.inf
    nearest = np.full(n, math.inf)
    for _ in range(int(round(duration / dt))):
        i, j = pairs_within(x, sensing_radius)
        psi_f = x[i] - x[j]
        d = np.sqrt(np.einsum("ij,ij->i", psi_f, psi_f))
        if len(d):
            min_pair = min(min_pair, float(d.min()))
            nearest = np.full(n, math.inf)
            np.minimum.at(nearest, i, d)
        psi_o = x - obstacle
        dist_o = np.sqrt(np.einsum("ij,ij->i", psi_o, psi_o))
        min_obs = min(min_obs, float(dist_o.min()))
        sensed = dist_o <= sensing_radius
        agents = np.flatnonzero(sensed)
        _, f = field(x, agents, psi_o[sensed], i, psi_f, p, "multiplicative", c_f)
        x = x + dt * saturate(f, v_max)
    finite = nearest[np.isfinite(nearest)]
    return Squeeze(n_agents=n, min_pair_distance=min_pair, min_obstacle_distance=min_obs,
                   final_median_nearest=float(np.median(finite)) if len(finite) else math.inf)
