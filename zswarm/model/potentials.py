"""Artificial potentials and their forces (Kim, Wang & Shin 2006, eqs 6-15, 25-28, 35-36).

Everything is vectorized. What an agent sensed is given as flat pair lists, the same shape whether it
comes from one agent process (every pair index 0) or from the simulator's neighbour grid (many
agents):

- ``psi_g``: (N, 2) goal offsets P_i - P_goal (eq 6);
- ``obs_agent, psi_o``: (M,) agent index and (M, 2) offset P_i - O_j to each sensed obstacle (eq 9);
- ``nbr_agent, psi_f``: (K,) agent index and (K, 2) offset P_i - P_k to each sensed neighbour (eq 25).

Only what is in those lists contributes: the sensing radius is applied when the lists are built
(:func:`sense_one` here, :mod:`zswarm.model.neighbours` for the swarm). Every force is the exact negative
gradient of its potential with respect to P_i; ``tests/test_potentials.py`` checks each against a
central finite difference.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from zswarm.model.formation import formation_offset, pair_gain
from zswarm.model.neighbour_law import NeighbourLaw, PairList, neighbour_force, unit_toward
from zswarm.model.params import PotentialParams

Combination = Literal["additive", "multiplicative"]
COMBINATIONS: tuple[Combination, ...] = ("additive", "multiplicative")


def goal_terms(psi_g: np.ndarray, p: PotentialParams) -> tuple[np.ndarray, np.ndarray]:
    """U^g = c_g (1 - exp(-|psi|^2/l_g^2)) (eq 7) and F^g = -2 c_g psi/l_g^2 exp(...) (eq 8).

    ``psi_g``: (..., 2); the parameters may be arrays that broadcast against (...) (one set per run of
    a batch, :mod:`zswarm.sim.batch`)."""
    e = np.exp(-np.einsum("...j,...j->...", psi_g, psi_g) / p.l_g**2)
    return p.c_g * (1.0 - e), (-2.0 * p.c_g / p.l_g**2 * e)[..., None] * psi_g


def obstacle_terms(psi_o: np.ndarray, p: PotentialParams) -> tuple[np.ndarray, np.ndarray]:
    """Per obstacle pair: c_o exp(-|psi|^2/l_o^2) (eq 10) and 2 c_o psi/l_o^2 exp(...) (eq 11).
    Leading axes and parameters broadcast as in :func:`goal_terms`."""
    e = p.c_o * np.exp(-np.einsum("...j,...j->...", psi_o, psi_o) / p.l_o**2)
    return e, (2.0 / p.l_o**2 * e)[..., None] * psi_o


def formation_terms(
    psi_f: np.ndarray, p: PotentialParams, c_f: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Per neighbour pair: the bracket of eq 26 and the force of eq 28, F = -g(|psi|) psi."""
    r2 = np.einsum("ij,ij->i", psi_f, psi_f)
    u = (
        p.c_r * np.exp(-r2 / p.l_r**2)
        - p.c_a * np.exp(-r2 / p.l_a**2)
        + p.c_a_prime * r2
        + c_f
    )
    return u, -pair_gain(r2, p)[:, None] * psi_f


def _per_agent(n: int, idx: np.ndarray, u: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    pairs = PairList(idx, n)
    return pairs.total(u), pairs.total(f)


def field(
    psi_g: np.ndarray,
    obs_agent: np.ndarray,
    psi_o: np.ndarray,
    nbr_agent: np.ndarray,
    psi_f: np.ndarray,
    p: PotentialParams,
    combination: Combination = "multiplicative",
    c_f: float = 0.0,
    law: NeighbourLaw | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Total potential U_i (N,) and force F_i = -grad_i U_i (N, 2) of every agent.

    additive (eqs 12-13):        U = U^o + U^g,                     F = F^o + F^g
    multiplicative (eqs 14-15):  U = U^o U^g / c_g + U^g,
                                 F = (U^g/c_g) F^o + (1 + U^o/c_g) F^g
    (the second form is eq 15 regrouped: -grad(U^g/c_g) = F^g/c_g). Both add the formation
    term U^f, F^f of eqs 26-28 (total eqs 35-36) when neighbour pairs are given.

    ``law``: an interaction other than the paper's (:mod:`zswarm.model.neighbour_law`) replaces F^f and,
    with the gate, weighs the goal term (F^g above). U stays eq 35's (with the paper's eq 26 sum), the
    energy the metrics report: the variants' forces are not all gradients of one swarm potential.
    """
    n = psi_g.shape[0]
    u_g, f_g = goal_terms(psi_g, p)
    u_o, f_o = _per_agent(n, obs_agent, *obstacle_terms(psi_o, p))
    variant = law is not None and not law.interaction.is_paper
    goal_weight = 1.0
    f_n = None
    if variant and len(nbr_agent):
        f_n, weight = neighbour_force(PairList(nbr_agent, n), psi_f, np.ones(len(nbr_agent), dtype=bool),
                                      unit_toward(psi_g), p, law)
        goal_weight = weight[:, None]
    if combination == "additive":
        u, f = u_o + u_g, f_o + goal_weight * f_g
    elif combination == "multiplicative":
        u = u_o * u_g / p.c_g + u_g
        f = (u_g / p.c_g)[:, None] * f_o + goal_weight * ((1.0 + u_o / p.c_g)[:, None] * f_g)
    else:
        raise ValueError(f"unknown combination {combination!r}; use one of {COMBINATIONS}")
    if len(nbr_agent):
        u_f, f_f = _per_agent(n, nbr_agent, *formation_terms(psi_f, p, c_f))
        u, f = u + u_f, f + (f_f if f_n is None else f_n)
    return u, f


def obstacle_offsets(points: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """psi^o = P - B, with B the nearest point of a circular obstacle's boundary (eq 9 for circles).

    A point obstacle is a circle of radius 0 (B = O_j, eq 9 exactly). For a circle of radius rho,
    psi^o = (P - C)(1 - rho/|P - C|); since |psi^o| = |P - C| - rho, eq 10 becomes
    c_o exp(-(|P - C| - rho)^2/l_o^2), whose gradient is again eq 11 with this psi^o.
    """
    d = points - centers  # (..., 2), radii (...): any leading axes
    dist = np.sqrt(np.einsum("...j,...j->...", d, d))
    scale = np.where(dist > 0.0, 1.0 - radii / np.where(dist > 0.0, dist, 1.0), 0.0)
    return d * scale[..., None]


def saturate(velocity: np.ndarray, v_max: float) -> np.ndarray:
    """Speed limit: scale each row of ``velocity`` (..., 2) down to norm ``v_max`` (a number, or an array
    that broadcasts against (...)) where it is faster."""
    speed = np.sqrt(np.einsum("...j,...j->...", velocity, velocity))
    scale = np.where(speed > v_max, v_max / np.where(speed > 0, speed, 1.0), 1.0)
    return velocity * scale[..., None]


@dataclass(frozen=True)
class Sensed:
    """What one agent sensed within its radius: obstacle offsets and neighbour offsets."""

    psi_o: np.ndarray  # (M, 2)
    psi_f: np.ndarray  # (K, 2)


def sense_one(
    position: np.ndarray,
    obstacle_centers: np.ndarray,
    obstacle_radii: np.ndarray,
    neighbour_positions: np.ndarray,
    sensing_radius: float,
) -> Sensed:
    """Keep the obstacles whose nearest boundary point, and the neighbours, within ``sensing_radius``."""
    dims = len(position)
    pos = np.broadcast_to(position, (len(obstacle_centers), dims))
    psi_o = obstacle_offsets(pos, obstacle_centers.reshape(-1, dims), obstacle_radii.reshape(-1))
    psi_f = position - neighbour_positions.reshape(-1, dims)
    keep_o = np.einsum("ij,ij->i", psi_o, psi_o) <= sensing_radius**2
    keep_f = np.einsum("ij,ij->i", psi_f, psi_f) <= sensing_radius**2
    return Sensed(psi_o=psi_o[keep_o], psi_f=psi_f[keep_f])


@dataclass(frozen=True)
class Controller:
    """The control law of one agent: P' = sat(-grad U_i) (eq 5 with the speed limit)."""

    p: PotentialParams
    combination: Combination = "multiplicative"
    formation: bool = True
    c_f: float = 0.0
    law: NeighbourLaw | None = None  # None: the paper's interaction

    def velocity(self, position: np.ndarray, goal: np.ndarray, sensed: Sensed, v_max: float) -> np.ndarray:
        """Commanded velocity of a single agent from its own state and what it sensed."""
        psi_f = sensed.psi_f if self.formation else np.zeros((0, len(position)))
        _, f = field(
            (position - goal)[None, :],
            np.zeros(len(sensed.psi_o), dtype=np.intp),
            sensed.psi_o,
            np.zeros(len(psi_f), dtype=np.intp),
            psi_f,
            self.p,
            self.combination,
            self.c_f,
            self.law,
        )
        return saturate(f, v_max)[0]


def make_controller(
    p: PotentialParams, combination: Combination = "multiplicative", formation: bool = True,
    law: NeighbourLaw | None = None,
) -> Controller:
    """Factory: the controller with its formation offset c_f (eq 27) computed once; ``law`` (from
    :func:`zswarm.model.neighbour_law.neighbour_law`) for an interaction other than the paper's."""
    if combination not in COMBINATIONS:
        raise ValueError(f"unknown combination {combination!r}; use one of {COMBINATIONS}")
    if law is not None and law.interaction.is_paper:
        law = None
    return Controller(p=p, combination=combination, formation=formation, c_f=formation_offset(p), law=law)
