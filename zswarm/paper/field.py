"""The control law, written once: every agent's potential, force and command (eqs 5-15, 25-28, 35-36).

    v_i = sat(F_i, v_max),   F_i = -grad_i U_i                                    (eq 5, eq 36)

    additive (eqs 12-13):        U = U^o + U^g,                 F = F^o + w_i F^g
    multiplicative (eqs 14-15):  U = U^o U^g / c_g + U^g,       F = (U^g/c_g) F^o + w_i (1 + U^o/c_g) F^g

plus the formation term U^f, F^f of eqs 26-28 (or an interaction of :mod:`zswarm.paper.neighbour_law`,
whose gate sets the goal weight w_i; w_i = 1 otherwise) and, with ``swirl``, the circulation about the
goal (:func:`zswarm.paper.neighbour_law.swirl_force`, which U does not hold: it is no gradient). The
multiplicative F is eq 15 regrouped: -grad(U^g/c_g) = F^g/c_g. U stays eq 35's (with the paper's eq 26
sum), the energy the metrics report.

:func:`field` is the one implementation, over any leading batch axes (agents, or runs x agents, each
with D = 2 or 3 coordinates). What each agent sensed comes as pairs, in one of two layouts
(:mod:`zswarm.paper.neighbour_law`): a flat list (pair k belongs to agent ``agent[k]``; the reference
simulator's cell grid, or one agent) or a dense masked block (the batched simulator). Its consumers:

- the reference simulator, a batch of one (:func:`swarm_field`, flat pairs from the cell grid);
- the batched simulator, a batch of many (dense blocks, each run's parameters as columns);
- a 3-D agent process: the same code on one row (:meth:`Law.velocity`);
- a 2-D agent process: :mod:`zswarm.paper.agent_law`, the same arithmetic in plain floats, kept
  because it is ten times cheaper at one agent's size (``docs/benchmarks.md``); a property test
  (``tests/test_one_law.py``) holds it, and every other consumer, equal to :func:`field` to 1e-12.

A scenario's law is compiled once (:func:`compile_law`: the formation offset c_f, the pair spacing
d^f and the interaction's numbers) and handed to whoever needs it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zswarm.paper.formation import equilibria, formation_offset
from zswarm.paper.neighbour_law import (
    NeighbourLaw,
    PairList,
    Pairs,
    neighbour_force,
    neighbour_law,
    swirl_force,
    unit_toward,
)
from zswarm.paper.neighbours import ObstacleIndex, pairs_within
from zswarm.paper.params import Params, PotentialParams
from zswarm.paper.potentials import (
    COMBINATIONS,
    Combination,
    formation_terms,
    goal_terms,
    obstacle_offsets,
    obstacle_terms,
    saturate,
)

_NO_PAIRS = np.zeros(0, dtype=np.intp)


def field(psi_g: np.ndarray, obstacles: np.ndarray | Pairs, psi_o: np.ndarray, neighbours: np.ndarray | Pairs,
          psi_f: np.ndarray, p: PotentialParams, combination: Combination | np.ndarray = "multiplicative",
          c_f: float = 0.0, law: NeighbourLaw | None = None, *, p_pairs=None,
          energy: bool = True, force: bool = True) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Total potential U_i (...) and force F_i = -grad_i U_i (..., D) of every agent (see the module doc).

    ``psi_g``: (..., D) goal offsets P_i - P_goal (eq 6); ``obstacles``, ``psi_o``: the sensed obstacle
    pairs and their offsets P_i - B_j (eq 9); ``neighbours``, ``psi_f``: the sensed neighbour pairs and
    P_i - P_k (eq 25). Pairs are a :class:`~zswarm.paper.neighbour_law.PairList` or
    :class:`~zswarm.paper.neighbour_law.DensePairs`, or a plain array of agent indices (a flat list).
    ``combination``: a name, or a boolean array (True: multiplicative) that broadcasts against (...),
    one per run of a batch. ``p``: one parameter set, or columns that broadcast against (...);
    ``p_pairs``: the same columns shaped for the pairs (default ``p``). ``law``: an interaction other
    than the paper's. ``energy=False`` skips U, ``force=False`` skips F (each then returned as None: an
    observer that only wants the swarm's energy does not pay for the neighbour forces).
    """
    n = psi_g.shape[0]
    obstacles = obstacles if not isinstance(obstacles, np.ndarray) else PairList(obstacles, n)
    neighbours = neighbours if not isinstance(neighbours, np.ndarray) else PairList(neighbours, n)
    pp = p if p_pairs is None else p_pairs
    u_g, f_g = goal_terms(psi_g, p)
    e_o, f_o = obstacle_terms(psi_o, pp)
    u_o, f_o = obstacles.total(e_o), obstacles.total(f_o)
    if not force:
        return _energy(combination, u_o, u_g, neighbours, psi_f, pp, c_f, p), None
    goal_weight, f_f = 1.0, None
    if neighbours.count:
        f_f, weight = neighbour_force(neighbours, psi_f, unit_toward(psi_g), pp, law)
        if law is not None and law.interaction.gate:
            goal_weight = weight[..., None]
    if isinstance(combination, str):
        if combination not in COMBINATIONS:
            raise ValueError(f"unknown combination {combination!r}; use one of {COMBINATIONS}")
        mult = combination == "multiplicative"
        f = _combined(mult, f_o, f_g, u_o, u_g, goal_weight, p)
    else:
        mult = np.asarray(combination, dtype=bool)
        f = np.where(mult[..., None], _combined(True, f_o, f_g, u_o, u_g, goal_weight, p),
                     _combined(False, f_o, f_g, u_o, u_g, goal_weight, p))
    if f_f is not None:
        f = f + f_f
    if law is not None and law.interaction.swirl:
        f = f + swirl_force(psi_g, f_g, law)
    if not energy:
        return None, f
    return _energy(combination, u_o, u_g, neighbours, psi_f, pp, c_f, p), f


def _energy(combination: Combination | np.ndarray, u_o: np.ndarray, u_g: np.ndarray, neighbours: Pairs,
            psi_f: np.ndarray, pp, c_f: float, p: PotentialParams) -> np.ndarray:
    """U_i: U^o and U^g combined as eq 13 (additive) or eq 15 (multiplicative), plus the formation terms."""
    if isinstance(combination, str):
        if combination not in COMBINATIONS:
            raise ValueError(f"unknown combination {combination!r}; use one of {COMBINATIONS}")
        mult = combination == "multiplicative"
    else:
        mult = np.asarray(combination, dtype=bool)
    u = np.where(mult, u_o * u_g / p.c_g + u_g, u_o + u_g)
    if neighbours.count:
        u = u + neighbours.total(formation_terms(psi_f, pp, c_f)[0])
    return u


def _combined(multiplicative: bool, f_o: np.ndarray, f_g: np.ndarray, u_o: np.ndarray, u_g: np.ndarray,
              goal_weight, p: PotentialParams) -> np.ndarray:
    """F^o and F^g combined: eq 13 (additive) or eq 15 (multiplicative), the goal term weighted."""
    if multiplicative:
        return (u_g / p.c_g)[..., None] * f_o + goal_weight * ((1.0 + u_o / p.c_g)[..., None] * f_g)
    return f_o + goal_weight * f_g


def swarm_field(law: "Law", obstacles: ObstacleIndex, positions: np.ndarray, goal: np.ndarray,
                pairs: tuple[np.ndarray, np.ndarray] | None = None,
                force: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Every agent's U_i and F_i from what it senses: the reference simulator's batch of one.

    Obstacles are the ones within the sensing radius of ``obstacles``; ``pairs`` is ``(i, psi_f)``,
    the neighbour terms each agent i uses with psi^f = P_i - P_j as it believes it (default: every
    pair within the sensing radius, at the true positions, from the cell grid). ``goal`` is (D,) or
    one per agent (N, D). ``force=False``: U_i alone (F_i None).
    """
    if not law.formation:
        i, psi_f = _NO_PAIRS, np.zeros((0, positions.shape[1]))
    elif pairs is None:
        i, j = pairs_within(positions, obstacles.sensing_radius)
        psi_f = positions[i] - positions[j]
    else:
        i, psi_f = pairs
    a, m = obstacles.sensed(positions)
    psi_o = obstacle_offsets(positions[a], obstacles.centers[m], obstacles.radii[m])
    return field(positions - goal, a, psi_o, i, psi_f, law.p, law.combination, law.c_f, law.neighbours,
                 force=force)


@dataclass(frozen=True)
class Sensed:
    """What one agent sensed within its radius: obstacle offsets and neighbour offsets."""

    psi_o: np.ndarray  # (M, D)
    psi_f: np.ndarray  # (K, D)


def sense_one(position: np.ndarray, obstacle_centers: np.ndarray, obstacle_radii: np.ndarray,
              neighbour_positions: np.ndarray, sensing_radius: float) -> Sensed:
    """Keep the obstacles whose nearest boundary point, and the neighbours, within ``sensing_radius``."""
    dims = len(position)
    pos = np.broadcast_to(position, (len(obstacle_centers), dims))
    psi_o = obstacle_offsets(pos, obstacle_centers.reshape(-1, dims), obstacle_radii.reshape(-1))
    psi_f = position - neighbour_positions.reshape(-1, dims)
    keep_o = np.einsum("ij,ij->i", psi_o, psi_o) <= sensing_radius**2
    keep_f = np.einsum("ij,ij->i", psi_f, psi_f) <= sensing_radius**2
    return Sensed(psi_o=psi_o[keep_o], psi_f=psi_f[keep_f])


@dataclass(frozen=True)
class Law:
    """A scenario's control law, compiled once (:func:`compile_law`) and handed to the reference
    simulator, its observer, the batched simulator and the agents."""

    p: PotentialParams
    combination: Combination = "multiplicative"
    formation: bool = True
    c_f: float = 0.0  # eq 27's offset
    neighbours: NeighbourLaw | None = None  # None: the paper's interaction
    spacing: float | None = None  # the pair spacing d^f (None: the potential has none)
    v_max: float = 1.0

    def velocity(self, position: np.ndarray, goal: np.ndarray, sensed: Sensed,
                 v_max: float | None = None) -> np.ndarray:
        """One agent's command sat(F_i) from what it sensed: :func:`field` on one row."""
        psi_f = sensed.psi_f if self.formation else np.zeros((0, len(position)))
        _, f = field((position - goal)[None, :], np.zeros(len(sensed.psi_o), dtype=np.intp), sensed.psi_o,
                     np.zeros(len(psi_f), dtype=np.intp), psi_f, self.p, self.combination, self.c_f,
                     self.neighbours, energy=False)
        return saturate(f, self.v_max if v_max is None else v_max)[0]


def make_law(p: PotentialParams, combination: Combination = "multiplicative", formation: bool = True,
             neighbours: NeighbourLaw | None = None, v_max: float = 1.0) -> Law:
    """The law of a potential alone (its formation offset and spacing worked out once here)."""
    if combination not in COMBINATIONS:
        raise ValueError(f"unknown combination {combination!r}; use one of {COMBINATIONS}")
    if neighbours is not None and neighbours.interaction.is_paper:
        neighbours = None
    return Law(p, combination, formation, formation_offset(p), neighbours, equilibria(p).spacing, v_max)


def compile_law(params: Params, combination: Combination, formation: bool = True) -> Law:
    """A parameter set's law: potential, interaction, speed limit (raises ParamError where the
    interaction cannot be used)."""
    return make_law(params.potential, combination, formation, neighbour_law(params), params.swarm.v_max)
