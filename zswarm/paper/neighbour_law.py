"""The force an agent takes from its sensed neighbours under each interaction, written once.

Eq 28 splits the pair force F = -g(r) psi into its repulsion and attraction parts,

    g(r) = g_r(r) + g_a(r),  g_r = -2 c_r/l_r^2 e^{-r^2/l_r^2},  g_a = 2 c_a/l_a^2 e^{-r^2/l_a^2} + 2 c'_a,

and the variants of :mod:`zswarm.paper.interaction` act on those parts, with w_k the weight of pair k:

    F_i = sum_k w_k (-g_r psi_k) + A_i,   A_i = sum_k w_k (-g_a psi_k)               (paper's sum)
                                          A_i = sum_k w_k (-g_a psi_k) / max(sum_k w_k, 1)  (mean)

- w_k = 1 for a sensed neighbour; ``cutoff`` multiplies it by rho(r/R) (1 up to 0.8 R, then
  (1 + cos(pi (r/R - 0.8)/0.2))/2 down to 0 at R); ``nearest`` sets it to 0 beyond the k nearest.
  For a fixed neighbour set each of these is -grad_i of a potential: the sum of the pair potentials
  (nearest), their mean for the attraction (mean), or per pair u_c(r) = -int_r^R g(s) s rho(s/R) ds
  (cutoff). ``tests/test_neighbour_law.py`` checks each against a finite difference.
- ``gate`` multiplies the agent's goal term by 1 - max_k near(r_k) ahead(cos_k), where
  cos_k is the cosine between the direction to neighbour k and the direction to the goal,
  ahead = clip((cos - 1/2)/(1/4), 0, 1) (a cone of about 41-60 degrees about the goal direction) and
  near = clip((g_out - r)/(g_out - g_in), 0, 1) with g_out = gate d^f and g_in = 0.9 g_out (GATE_INNER): an agent
  with a neighbour ahead within g_in takes no goal pull. The gate is not the gradient of a potential.

The sums are over pairs given either as a flat list (agent index per pair: one agent process, or the
reference simulator's neighbour grid) or as a dense (B, N, N) block (the batched simulator): the two
:class:`Pairs` classes below are the only place the layouts differ. With no interaction (``law`` None)
:func:`neighbour_force` is the paper's eq 28, summed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.errors import ParamError
from zswarm.paper.formation import equilibria, pair_gain
from zswarm.paper.interaction import Interaction
from zswarm.paper.params import Params, PotentialParams

CUTOFF_INNER = 0.8  # the bump is 1 up to this fraction of R
GATE_INNER = 0.9  # g_in = GATE_INNER g_out
AHEAD_COS = 0.5  # a neighbour counts as ahead from this cosine ...
AHEAD_FULL = 0.75  # ... and fully from this one


@dataclass(frozen=True)
class NeighbourLaw:
    """An interaction with the numbers it needs, fixed once per run (:func:`neighbour_law`)."""

    interaction: Interaction
    sensing_radius: float
    gate_out: float = math.inf  # g_out = gate d^f
    k_nearest: int = 0
    swirl: float = 0.0  # kappa: the circulation as a multiple of the goal pull ((B, 1, 1) in a batch)
    swirl_radius: float = 0.0  # rho: agents within it of the goal circulate ((B, 1) in a batch)

    @property
    def gate_in(self) -> float:
        return GATE_INNER * self.gate_out


def neighbour_law(params: Params) -> NeighbourLaw:
    """The law of a parameter set; raises :class:`ParamError` where the interaction cannot be used."""
    spec = params.interaction.spec
    gate_out = math.inf
    if spec.gate:
        spacing = equilibria(params.potential).spacing
        if spacing is None:
            raise ParamError(f"interaction {spec.name} needs a pair spacing d^f (the gate is gate x d^f), and "
                             "this potential has none (zswarm design says why); drop gate or fix the potential")
        gate_out = params.interaction.gate * spacing
    swirl = params.interaction.swirl if spec.swirl else 0.0
    if spec.swirl and params.interaction.swirl_radius <= 0.0:
        raise ParamError(f"interaction {spec.name} needs swirl_radius > 0 (how far from the goal agents circulate; "
                         "large-swarm uses 0.7 times the radius of the gathered swarm): --set swirl_radius=R")
    return NeighbourLaw(spec, params.swarm.sensing_radius, gate_out, params.interaction.k_nearest, swirl,
                        params.interaction.swirl_radius if spec.swirl else 0.0)


def cutoff_weight(r: np.ndarray, radius: float) -> np.ndarray:
    """rho(r/R): 1 up to 0.8 R, a half cosine down to 0 at R, 0 beyond."""
    z = (np.asarray(r, dtype=float) / radius - CUTOFF_INNER) / (1.0 - CUTOFF_INNER)
    return np.where(z <= 0.0, 1.0, np.where(z >= 1.0, 0.0, 0.5 * (1.0 + np.cos(np.pi * np.clip(z, 0.0, 1.0)))))


def repulsion_gain(r2: np.ndarray, p: PotentialParams) -> np.ndarray:
    """g_r(r) as a function of r^2: the repulsion part of eq 28's gain."""
    return -2.0 * p.c_r / p.l_r**2 * np.exp(-r2 / p.l_r**2)


def attraction_gain(r2: np.ndarray, p: PotentialParams) -> np.ndarray:
    """g_a(r) as a function of r^2: the attraction part of eq 28's gain (c_a and c'_a)."""
    return 2.0 * p.c_a / p.l_a**2 * np.exp(-r2 / p.l_a**2) + 2.0 * p.c_a_prime


def gate_block(r: np.ndarray, cos: np.ndarray, law: NeighbourLaw) -> np.ndarray:
    """near(r) ahead(cos) of each pair: how much that neighbour blocks the agent's goal pull."""
    near = np.clip((law.gate_out - r) / (law.gate_out - law.gate_in), 0.0, 1.0)
    ahead = np.clip((cos - AHEAD_COS) / (AHEAD_FULL - AHEAD_COS), 0.0, 1.0)
    return near * ahead


class PairList:
    """Pairs as a flat list: pair k belongs to agent ``agent[k]`` of ``n`` (every listed pair counts)."""

    def __init__(self, agent: np.ndarray, n: int) -> None:
        self.agent, self.n = np.asarray(agent, dtype=np.intp), n

    @property
    def count(self) -> int:
        return len(self.agent)

    def sensed(self) -> np.ndarray:
        return np.ones(len(self.agent), dtype=bool)

    def total(self, v: np.ndarray) -> np.ndarray:
        """Per-agent sum of per-pair values (K,) or vectors (K, D)."""
        if v.ndim == 1:
            return np.bincount(self.agent, weights=v, minlength=self.n)
        return np.stack([np.bincount(self.agent, weights=v[:, c], minlength=self.n) for c in range(v.shape[1])],
                        axis=1)

    def largest(self, v: np.ndarray) -> np.ndarray:
        """Per-agent maximum of non-negative per-pair values (0 without pairs)."""
        out = np.zeros(self.n)
        np.maximum.at(out, self.agent, v)
        return out

    def rank(self, r2: np.ndarray) -> np.ndarray:
        """Each pair's place among its agent's pairs by distance (0: the nearest)."""
        order = np.lexsort((r2, self.agent))
        first = np.searchsorted(self.agent[order], self.agent[order], side="left")
        rank = np.empty(len(r2), dtype=np.intp)
        rank[order] = np.arange(len(r2)) - first
        return rank

    def per_pair(self, per_agent: np.ndarray) -> np.ndarray:
        return per_agent[self.agent]


class DensePairs:
    """Pairs as a dense block (B, N, M): pair (b, i, j) belongs to agent i of run b and counts where
    ``mask`` holds (the others are out of range, padding, or the agent itself)."""

    def __init__(self, mask: np.ndarray) -> None:
        self.mask = mask

    @property
    def count(self) -> int:
        return self.mask.shape[-1]

    def sensed(self) -> np.ndarray:
        return self.mask

    def total(self, v: np.ndarray) -> np.ndarray:
        """Per-agent sum over the sensed pairs of per-pair values (B, N, M) or vectors (B, N, M, D)."""
        mask = self.mask if v.ndim == self.mask.ndim else self.mask[..., None]
        return np.where(mask, v, 0.0).sum(axis=2)

    def largest(self, v: np.ndarray) -> np.ndarray:
        return np.where(self.mask, v, 0.0).max(axis=2, initial=0.0)

    def rank(self, r2: np.ndarray) -> np.ndarray:
        return np.argsort(np.argsort(r2, axis=2, kind="stable"), axis=2, kind="stable")

    def per_pair(self, per_agent: np.ndarray) -> np.ndarray:
        return per_agent[:, :, None]


Pairs = PairList | DensePairs


def neighbour_force(pairs: Pairs, psi: np.ndarray, to_goal: np.ndarray, p: PotentialParams,
                    law: NeighbourLaw | None) -> tuple[np.ndarray, np.ndarray]:
    """Every agent's force from its sensed neighbours and the weight of its goal term (1 without the gate).

    ``psi``: per pair P_i - P_k (..., D); ``to_goal``: per agent the unit vector toward its goal (0 at
    the goal); ``law``: None (or the paper's) for eq 28 summed, F = -sum_k g(|psi_k|) psi_k. The
    potential parameters may be columns that broadcast against the pairs (a batch).
    """
    r2 = np.einsum("...j,...j->...", psi, psi)
    if law is None or law.interaction.is_paper:
        return pairs.total(-pair_gain(r2, p)[..., None] * psi), np.ones(to_goal.shape[:-1])
    spec, sensed = law.interaction, pairs.sensed()
    r2 = np.where(sensed, r2, np.inf)
    w = sensed.astype(float)
    if spec.cutoff:
        w = w * cutoff_weight(np.sqrt(np.where(sensed, r2, 0.0)), law.sensing_radius)
    if spec.nearest:
        w = np.where(pairs.rank(r2) < law.k_nearest, w, 0.0)
    use = w > 0.0
    r2u = np.where(use, r2, 0.0)
    wv = w[..., None]
    # w is 0 on a pair not used (and r2u 0, so its gain is finite): its terms are 0 without masking them again
    rep = pairs.total(-wv * repulsion_gain(r2u, p)[..., None] * psi)
    att = pairs.total(-wv * attraction_gain(r2u, p)[..., None] * psi)
    if spec.mean:
        att = att / np.maximum(pairs.total(w), 1.0)[..., None]
    weight = np.ones(rep.shape[:-1])
    if spec.gate:
        r = np.sqrt(r2u)
        cos = -np.einsum("...j,...j->...", np.where(use[..., None], psi, 0.0), pairs.per_pair(to_goal))
        cos = cos / np.where(r > 0.0, r, 1.0)
        weight = 1.0 - pairs.largest(np.where(use, gate_block(r, cos, law), 0.0))
    return rep + att, weight


def swirl_force(psi_g: np.ndarray, f_g: np.ndarray, law: NeighbourLaw) -> np.ndarray:
    """``swirl``: kappa times the goal pull F^g turned a quarter turn, (-F^g_y, F^g_x[, 0]), for an agent
    within rho of the goal (|psi_g| < rho), 0 beyond. In 3-D it turns about the vertical through the
    goal. F^g points at the goal, so this is a rotation about it, clockwise seen from above;
    with the Gaussian goal of eq 7 near its centre, F^g ~ -2 c_g/l_g^2 psi_g, a rigid rotation at
    2 kappa c_g/l_g^2 rad/s. Not the gradient of a potential (its curl is not zero), as the gate is not."""
    turned = np.zeros_like(f_g)
    turned[..., 0], turned[..., 1] = -f_g[..., 1], f_g[..., 0]
    inside = np.einsum("...j,...j->...", psi_g, psi_g) < np.square(law.swirl_radius)  # a number or (B, 1)
    return law.swirl * inside[..., None] * turned  # swirl: a number or (B, 1, 1)


def unit_toward(psi_g: np.ndarray) -> np.ndarray:
    """-psi_g / |psi_g| (..., 2): the direction to the goal, 0 at the goal."""
    d = np.sqrt(np.einsum("...j,...j->...", psi_g, psi_g))
    return -psi_g / np.where(d > 0.0, d, 1.0)[..., None] * (d > 0.0)[..., None]
