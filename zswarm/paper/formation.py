"""The inter-agent pair potential of eq 26 as a function of distance, and its equilibrium spacing.

For one pair at distance r (psi = P_i - P_k, r = |psi|), eq 26 reads

    u(r) = c_r exp(-r^2/l_r^2) - c_a exp(-r^2/l_a^2) + c'_a r^2 + c_f

so du/dr = r * g(r) with

    g(r) = -2 c_r/l_r^2 exp(-r^2/l_r^2) + 2 c_a/l_a^2 exp(-r^2/l_a^2) + 2 c'_a,

and the force on agent i from k (eq 28) is F = -g(r) psi. Agents rest where g(r) = 0; a spacing is a
stable minimum where g changes sign from negative (repulsion) to positive (attraction). If g(0) > 0
the pair attracts at contact: r = 0 is itself a minimum, and agents that come close collapse.

Closed form (eq 27). Dropping the quadratic term, g(r) = 0 gives, with s = r^2,

    s = c'_f = l_r^2 l_a^2 / (l_r^2 - l_a^2) * ln( c_a l_r^2 / (c_r l_a^2) ),    d^f = sqrt(c'_f),

and c_f = -(c_r e^{-s/l_r^2} - c_a e^{-s/l_a^2} + c'_a s) makes the minimum value zero (eq 27).
The OCR'd text prints ``c_a c'_a`` inside the logarithm; that mixes units (c'_a is a strength per
length^2) and is not what g(r) = 0 gives, so it is not used. Because eq 27 ignores c'_a, the true
spacing is found numerically as well (:func:`equilibria`).

H-stability (not in the paper). A pair spacing is not enough: in a swarm every agent adds up N - 1
attractions, and with a soft (bounded) repulsion the sum can squeeze agents onto each other, more so
as N grows (Ruelle's H-stability; D'Orsogna et al., PRL 96, 104302, 2006). The Gaussian part of eq 26
is H-stable when its 2-D Fourier transform is non-negative,

    u_hat(k) = pi (c_r l_r^2 e^{-k^2 l_r^2/4} - c_a l_a^2 e^{-k^2 l_a^2/4}) >= 0 for all k,

i.e. c_r l_r^2 >= c_a l_a^2 with l_r <= l_a (the repulsion is stronger in total and shorter-ranged).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from zswarm.paper.numeric import sign_changes
from zswarm.paper.params import PotentialParams


def pair_potential(r: np.ndarray, p: PotentialParams, c_f: float = 0.0) -> np.ndarray:
    """u(r) of eq 26 for one pair (vectorized over r)."""
    r2 = np.square(r)
    return (
        p.c_r * np.exp(-r2 / p.l_r**2) - p.c_a * np.exp(-r2 / p.l_a**2) + p.c_a_prime * r2 + c_f
    )


def pair_gain(r2: np.ndarray, p: PotentialParams) -> np.ndarray:
    """g with du/dr = r g(r), as a function of r^2; the force on i from k is -g psi (eq 28)."""
    return (
        -2.0 * p.c_r / p.l_r**2 * np.exp(-r2 / p.l_r**2)
        + 2.0 * p.c_a / p.l_a**2 * np.exp(-r2 / p.l_a**2)
        + 2.0 * p.c_a_prime
    )


def closed_form_spacing(p: PotentialParams) -> float | None:
    """d^f = sqrt(c'_f) of eq 27 (None where undefined: l_r = l_a, or a non-positive c'_f)."""
    if p.l_r == p.l_a or p.c_r <= 0.0 or p.c_a <= 0.0:
        return None
    s = p.l_r**2 * p.l_a**2 / (p.l_r**2 - p.l_a**2) * math.log(p.c_a * p.l_r**2 / (p.c_r * p.l_a**2))
    return math.sqrt(s) if s > 0.0 else None


@dataclass(frozen=True)
class Equilibria:
    """Where a pair of agents can rest (every r > 0 with g(r) = 0), and what happens at contact."""

    stable: tuple[float, ...]  # local minima of u at r > 0
    unstable: tuple[float, ...]  # local maxima of u at r > 0
    attracts_at_contact: bool  # g(0) > 0: r = 0 is a minimum, close agents collapse
    disperses: bool  # u keeps decreasing at the search limit: pairs drift apart

    @property
    def spacing(self) -> float | None:
        """The stable spacing with the lowest potential (None if there is none)."""
        return self.stable[0] if self.stable else None

    @property
    def is_stable(self) -> bool:
        """A swarm has a stable spacing: a minimum at r > 0 and repulsion at contact."""
        return bool(self.stable) and not self.attracts_at_contact


@lru_cache(maxsize=256)
def equilibria(p: PotentialParams, samples: int = 40_001) -> Equilibria:
    """All rest distances of a pair, by sign changes of g on a fine grid refined by bisection."""
    r = np.linspace(0.0, 20.0 * max(p.l_r, p.l_a), samples)
    g = pair_gain(r * r, p)
    stable: list[tuple[float, float]] = []
    unstable: list[float] = []
    for root, sign_before in sign_changes(lambda x: pair_gain(x * x, p), r):
        if sign_before < 0:
            stable.append((float(pair_potential(np.array(root), p)), root))
        else:
            unstable.append(root)
    stable.sort()
    return Equilibria(
        stable=tuple(x for _, x in stable),
        unstable=tuple(unstable),
        attracts_at_contact=bool(g[0] > 0),
        disperses=bool(g[-1] < 0),
    )


def fourier_gaussian_part(k: np.ndarray, p: PotentialParams, dimensions: int = 2) -> np.ndarray:
    """u_hat(k) of the two Gaussians of eq 26 (the D-dimensional Fourier transform: c exp(-r^2/l^2) has
    c (sqrt(pi) l)^D exp(-k^2 l^2/4))."""
    k2 = np.square(k)
    sp = np.sqrt(np.pi)
    return (p.c_r * (sp * p.l_r) ** dimensions * np.exp(-k2 * p.l_r**2 / 4.0)
            - p.c_a * (sp * p.l_a) ** dimensions * np.exp(-k2 * p.l_a**2 / 4.0))


def h_stable(p: PotentialParams, dimensions: int = 2) -> bool:
    """The Gaussian part of eq 26 is positive definite in D dimensions (no catastrophic collapse as N
    grows): its Fourier transform is nowhere negative."""
    k = np.linspace(0.0, 60.0 / min(p.l_r, p.l_a), 20_001)
    scale = np.pi ** (dimensions / 2) * (p.c_r * p.l_r**dimensions + p.c_a * p.l_a**dimensions)
    return bool(np.all(fourier_gaussian_part(k, p, dimensions) >= -1e-12 * scale))


def formation_offset(p: PotentialParams) -> float:
    """c_f of eq 27: shifts the pair potential so that its minimum is zero.

    Uses the numerically found stable spacing; falls back to the closed form, then to 0.
    """
    d = equilibria(p).spacing or closed_form_spacing(p)
    if d is None:
        return 0.0
    return -float(pair_potential(np.array(d), p))


def epsilon(p: PotentialParams, n_agents: int) -> float:
    """Cohesion radius of Prop 3 (eq 34); infinite when c'_a = 0."""
    if n_agents <= 1:
        return 0.0
    if p.c_a_prime == 0:
        return math.inf
    return ((n_agents - 1) * math.exp(-0.5) * (p.c_r / p.l_r + p.c_a / p.l_a)
            / (math.sqrt(2.0) * p.c_a_prime * n_agents))
