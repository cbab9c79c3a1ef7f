"""Artificial potentials and their per-pair terms (Kim, Wang & Shin 2006, eqs 6-11, 26-28).

The terms of one agent's potential, vectorized over any leading axes: the goal (eqs 7-8), each sensed
obstacle (eqs 9-11, circles through their nearest boundary point), each sensed neighbour (eqs 26 and
28), and the speed limit. :mod:`zswarm.paper.field` combines them into every agent's force, once, for
every runner. Every force is the exact negative gradient of its potential with respect to P_i;
``tests/test_potentials.py`` checks each against a central finite difference.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from zswarm.paper.formation import pair_gain
from zswarm.paper.params import PotentialParams

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
    r2 = np.einsum("...j,...j->...", psi_f, psi_f)
    u = (
        p.c_r * np.exp(-r2 / p.l_r**2)
        - p.c_a * np.exp(-r2 / p.l_a**2)
        + p.c_a_prime * r2
        + c_f
    )
    return u, -pair_gain(r2, p)[..., None] * psi_f


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
