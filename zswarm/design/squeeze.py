"""A swarm squeezed against an obstacle (Fig 10): a brute-force check of what Props 4 and 5 promise.

Props 3-5 reason about one pair, or bound forces one at a time. A swarm adds up N - 1 attractions on
every agent, and the goal's pull presses the whole swarm against an obstacle that lies on its way
(Fig 10, the case Prop 4 is about). With soft (bounded) repulsion the sum can squeeze neighbours far
closer than the pair spacing d^f, or onto each other. This module runs exactly that case with the full
control law (eq 36, speed limit, sensing radius, interaction): N agents start in a disc (in 3-D, a ball) 1 behind a
point obstacle that sits on the straight line to a static goal, where the goal pulls hardest
(l_g/sqrt2 from it, at least 1), and it records the closest any two agents and any agent and the
obstacle come during the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from zswarm.swarm.metrics import components
from zswarm.paper.neighbour_law import neighbour_law
from zswarm.paper.neighbours import pairs_within
from zswarm.paper.params import Params
from zswarm.paper.formation import formation_offset
from zswarm.paper.field import field
from zswarm.paper.potentials import saturate


@dataclass(frozen=True)
class Squeeze:
    n_agents: int
    min_pair_distance: float  # over the whole run
    min_obstacle_distance: float  # over the whole run
    final_median_nearest: float
    final_groups: int  # groups of the sensing graph at the end


def _disc(n: int, spacing: float) -> np.ndarray:
    """``n`` points evenly filling a disc of radius spacing sqrt(n)/1.5 (Vogel's sunflower spiral: no two
    closer than about 0.9 spacing), so no pair starts in contact."""
    k = np.arange(n) + 0.5
    radius = spacing * math.sqrt(n) / 1.5
    r, theta = radius * np.sqrt(k / n), k * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


def _ball(n: int, spacing: float) -> np.ndarray:
    """``n`` points filling a ball at about ``spacing`` apart: a cubic lattice of that pitch, the ``n``
    nearest its centre (the 3-D counterpart of :func:`_disc`)."""
    side = int(math.ceil(n ** (1.0 / 3.0))) + 2
    axis = spacing * (np.arange(side) - (side - 1) / 2.0)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    order = np.argsort(np.einsum("ij,ij->i", grid, grid), kind="stable")
    return grid[order[:n]]


@lru_cache(maxsize=512)
def squeeze(params: Params, n: int, seed: int = 2006, duration: float = 60.0, dt: float = 0.05) -> Squeeze:
    """``n`` agents of the set ``params`` (its potentials, sensing radius, speed and interaction)."""
    p, sensing_radius, v_max = params.potential, params.swarm.sensing_radius, params.swarm.v_max
    law = neighbour_law(params)
    # the obstacle where the goal pulls hardest (|psi_g| = l_g/sqrt2, eq 8's peak; at least 1 away), the
    # swarm 1 behind it: the press of Fig 10 at its strongest, whatever the goal's range
    reach = max(1.0, p.l_g / math.sqrt(2.0))
    if params.swarm.dimensions == 2:
        x = _disc(n, 0.5) + np.array([-reach - 1.0 - 0.5 * math.sqrt(n) / 1.5, 0.0])
    else:  # a ball of agents behind a point obstacle, pressed the same way
        x = _ball(n, 0.5) + np.array([-reach - 1.0 - 0.5 * math.ceil(n ** (1.0 / 3.0)) / 2.0, 0.0, 0.0])
    x = x + np.random.default_rng(seed).uniform(-0.02, 0.02, x.shape)  # no exact symmetry
    obstacle = np.zeros((1, x.shape[1]))
    obstacle[0, 0] = -reach
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
        _, f = field(x, agents, psi_o[sensed], i, psi_f, p, "multiplicative", c_f, law)
        x = x + dt * saturate(f, v_max)
    finite = nearest[np.isfinite(nearest)]
    i, j = pairs_within(x, sensing_radius)
    return Squeeze(n_agents=n, min_pair_distance=min_pair, min_obstacle_distance=min_obs,
                   final_median_nearest=float(np.median(finite)) if len(finite) else math.inf,
                   final_groups=len(np.unique(components(n, i, j))))
