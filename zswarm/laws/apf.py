"""``apf``: the paper's law (Kim, Wang & Shin 2006, eqs 5-15, 25-28, 35-36) behind the law contract,
with every interaction of :mod:`zswarm.paper.interaction`. Its parameters are the scenario's own (the
potential, the interaction, the combination, ``--set c_o=...``); it has no ``[law]`` table, and the
paper's design guidelines (``zswarm design``) hold for it.

    v_i = sat(F_i, v_max),   F_i = -grad_i U_i                                       (eq 5, eq 36)

The batched form is the one law, :func:`zswarm.paper.field.field`, on dense blocks; runs with other
potentials step in the same call, each run's parameters as columns (:meth:`Apf.merge`). The single form
in 2-D is the same arithmetic in plain floats, term by term and in the same order, written for the
handful of obstacles and neighbours one agent senses (at that size numpy's per-call cost would be most of
the work: 0.1 ms against 0.01 ms); in 3-D it is the field on one row. Both use what they are given:
the engines give a law only what lies within the sensing radius (neighbours by their sensed position,
obstacles by their nearest boundary point), as the paper's agent senses it.
``tests/test_law_conformance.py`` holds the two forms equal for every interaction and combination.

- goal (eqs 7-8): U^g = c_g (1 - e^{-|psi_g|^2/l_g^2}), F^g = -2 c_g/l_g^2 e^{...} psi_g;
- obstacles (eqs 9-11, circles through their nearest boundary point): U^o = sum c_o e^{-|psi_o|^2/l_o^2},
  F^o = sum 2/l_o^2 c_o e^{...} psi_o;
- combination: additive (eqs 12-13) F = F^o + F^g; multiplicative (eqs 14-15)
  F = (U^g/c_g) F^o + (1 + U^o/c_g) F^g;
- formation (eqs 26-28): F^f = -sum g(|psi_f|^2) psi_f, or an interaction of
  :func:`zswarm.paper.neighbour_law.neighbour_force` (its goal gate weighs the goal term);
- swirl (:func:`zswarm.paper.neighbour_law.swirl_force`): kappa (-F^g_y, F^g_x) within rho of the goal.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Iterable

import numpy as np

from zswarm.errors import ParamError
from zswarm.laws.contract import Context, Observation, Observations, SwarmLaw
from zswarm.paper.field import Law, compile_law, field, sense_one
from zswarm.paper.interaction import Interaction
from zswarm.paper.neighbour_law import AHEAD_COS, AHEAD_FULL, CUTOFF_INNER, DensePairs, NeighbourLaw
from zswarm.paper.params import PotentialParams
from zswarm.paper.potentials import Combination, obstacle_offsets, saturate

Point = tuple[float, float]
Circle = tuple[float, float, float]  # centre x, y and radius (0: the paper's point obstacle)
_POTENTIAL = [f.name for f in dataclasses.fields(PotentialParams)]


class Apf(SwarmLaw):
    name = "apf"
    reference = "Kim, Wang & Shin (2006), eqs 5-15, 25-28, 35-36; zswarm design checks it (Propositions 1-5)"
    needs = ("obstacles",)
    guidelines = True

    def __init__(self, params: Law, context: Context, columns: _Columns | None = None) -> None:
        """``params``: the scenario's compiled law (:func:`zswarm.paper.field.compile_law`); ``columns``:
        the parameters of several runs stepped in one call (:meth:`merge`)."""
        super().__init__(params, context)
        self.law, self.columns = params, columns

    @classmethod
    def params_from(cls, scenario, settings: dict[str, float | int], combination: Combination | None) -> Law:
        if settings:
            raise ParamError(f"apf takes its parameters from the scenario (--set c_o=..., [params]), not law.* "
                             f"(got law.{next(iter(settings))})")
        return compile_law(scenario.params, combination or scenario.combination, scenario.formation)

    @classmethod
    def merge(cls, laws: list[SwarmLaw]) -> list[tuple[list[int], SwarmLaw]]:
        """Runs whose interaction is the same (its modifiers, and k for ``nearest``) step as one call,
        every other number a column (a run without formation in the paper's group: no neighbour terms)."""
        groups: dict[tuple, list[int]] = {}
        for r, law in enumerate(laws):
            nb = _neighbours(law.law)
            groups.setdefault(("paper", 0) if nb is None else (nb.interaction.name, nb.k_nearest), []).append(r)
        out: list[tuple[list[int], SwarmLaw]] = []
        for rows in groups.values():
            first = laws[rows[0]]
            if len(rows) == 1:
                out.append((rows, first))
                continue
            out.append((rows, cls(first.law, first.context, _Columns([laws[r].law for r in rows],
                                                                     [laws[r].context for r in rows]))))
        return out

    def floats(self, position, velocity, target, obstacles, neighbours, v_max: float, dt: float) -> tuple[float, float]:
        """The single form in plain floats (2-D): :func:`_velocity_2d` on what one agent holds."""
        law = self.law
        return _velocity_2d(position[0], position[1], target, obstacles, [n[0] for n in neighbours],
                            self.context.sensing_radius, law.p, law.combination, law.formation, v_max, law.neighbours)

    def command(self, obs: Observation) -> Any:
        law = self.law
        if obs.dims == 2:
            return _velocity_2d(float(obs.position[0]), float(obs.position[1]), obs.target.tolist(),
                                [(*o.centre.tolist(), o.radius) for o in obs.obstacles],
                                [n.position.tolist() for n in obs.neighbours], self.context.sensing_radius,
                                law.p, law.combination, law.formation, float(obs.v_max), law.neighbours)
        centres = np.array([o.centre for o in obs.obstacles], dtype=float).reshape(-1, obs.dims)
        radii = np.array([o.radius for o in obs.obstacles], dtype=float)
        others = np.array([n.position for n in obs.neighbours], dtype=float).reshape(-1, obs.dims)
        return law.velocity(obs.position, obs.target, sense_one(obs.position, centres, radii, others, math.inf),
                            obs.v_max)

    def batch(self, obs: Observations) -> np.ndarray:
        c = self.columns or _Columns.one(self.law, self.context)
        x = obs.position
        psi_o = obstacle_offsets(x[..., None, :], obs.obstacle_centre, obs.obstacle_radius)
        psi_f = x[..., None, :] - obs.neighbour_position
        sensed_f = obs.neighbour_mask & c.formation
        _, f = field(x - obs.target, DensePairs(obs.obstacle_mask), psi_o, DensePairs(sensed_f), psi_f, c.p_agent,
                     c.multiplicative, law=c.neighbours, p_pairs=c.p_pair, energy=False)
        return saturate(f, np.asarray(obs.v_max, dtype=float))

    def describe_params(self) -> dict[str, Any]:
        law = self.law
        return {**dataclasses.asdict(law.p), "combination": law.combination,
                "interaction": "paper" if law.neighbours is None else law.neighbours.interaction.name}


def _neighbours(law: Law) -> NeighbourLaw | None:
    """The interaction a run steps with (None: the paper's). Without formation there are no neighbour
    terms: only a swirl about the goal is left of it."""
    nb = law.neighbours
    if nb is None or law.formation:
        return nb
    return dataclasses.replace(nb, interaction=Interaction(swirl=True)) if nb.interaction.swirl else None


class _Columns:
    """What :meth:`Apf.batch` reads, for one run (numbers) or several (columns that broadcast against
    (b, n) per agent and (b, n, K) per pair)."""

    def __init__(self, laws: list[Law], contexts: list[Context]) -> None:
        col = lambda values, axes: np.asarray(values, dtype=float).reshape((-1,) + (1,) * axes)  # noqa: E731
        self.p_agent = _Potentials({n: col([getattr(l.p, n) for l in laws], 1) for n in _POTENTIAL})
        self.p_pair = _Potentials({n: col([getattr(l.p, n) for l in laws], 2) for n in _POTENTIAL})
        self.multiplicative = np.array([l.combination == "multiplicative" for l in laws])[:, None]
        self.formation = np.array([l.formation for l in laws])[:, None, None]
        first = _neighbours(laws[0])
        self.neighbours = None if first is None else NeighbourLaw(
            first.interaction, col([c.sensing_radius for c in contexts], 2),
            col([_neighbours(l).gate_out for l in laws], 2), first.k_nearest,
            col([_neighbours(l).swirl for l in laws], 2), col([_neighbours(l).swirl_radius for l in laws], 1))

    @classmethod
    def one(cls, law: Law, context: Context) -> _Columns:
        out = cls.__new__(cls)
        out.p_agent = out.p_pair = law.p
        out.multiplicative, out.formation = law.combination, law.formation
        out.neighbours = _neighbours(law)
        return out


class _Potentials:
    """One potential's numbers as attributes (columns), what :mod:`zswarm.paper.potentials` reads."""

    def __init__(self, values: dict[str, np.ndarray]) -> None:
        self.__dict__.update(values)


# -- the single form in 2-D, in plain floats --------------------------------------------------------------


def _velocity_2d(x: float, y: float, goal: Point, obstacles: Iterable[Circle], neighbours: Iterable[Point],
                   sensing_radius: float, p: PotentialParams, combination: Combination, formation: bool,
                   v_max: float, law: NeighbourLaw | None = None) -> Point:
    """Commanded velocity of the agent at (x, y) from what it sensed: every obstacle and neighbour given
    (the ones within the sensing radius; ``sensing_radius`` sets the cutoff interaction's fall-off).
    ``law``: an interaction other than the paper's."""
    goal_weight, variant = 1.0, None
    if formation and law is not None and not law.interaction.is_paper:
        variant, goal_weight = _neighbour_force_2d(x, y, goal, neighbours, sensing_radius, p, law)
    gx, gy = x - goal[0], y - goal[1]
    lg2 = p.l_g**2
    e = math.exp(-(gx * gx + gy * gy) / lg2)
    u_g = p.c_g * (1.0 - e)
    k = -2.0 * p.c_g / lg2 * e
    fgx, fgy = k * gx, k * gy

    lo2 = p.l_o**2
    u_o = fox = foy = 0.0
    for cx, cy, rho in obstacles:
        dx, dy = x - cx, y - cy
        dist = math.sqrt(dx * dx + dy * dy)
        scale = 1.0 - rho / dist if dist > 0.0 else 0.0
        px, py = dx * scale, dy * scale
        d2 = px * px + py * py
        e = p.c_o * math.exp(-d2 / lo2)
        u_o += e
        k = 2.0 / lo2 * e
        fox += k * px
        foy += k * py

    if combination == "additive":
        fx, fy = fox + goal_weight * fgx, foy + goal_weight * fgy
    else:
        a, b = u_g / p.c_g, 1.0 + u_o / p.c_g
        fx, fy = a * fox + goal_weight * (b * fgx), a * foy + goal_weight * (b * fgy)

    if variant is not None:
        fx, fy = fx + variant[0], fy + variant[1]
    elif formation:
        lr2, la2 = p.l_r**2, p.l_a**2
        ffx = ffy = 0.0
        for nx, ny in neighbours:
            px, py = x - nx, y - ny
            r2 = px * px + py * py
            g = (-2.0 * p.c_r / lr2 * math.exp(-r2 / lr2) + 2.0 * p.c_a / la2 * math.exp(-r2 / la2)
                 + 2.0 * p.c_a_prime)
            ffx += -g * px
            ffy += -g * py
        fx, fy = fx + ffx, fy + ffy
    if law is not None and law.interaction.swirl and gx * gx + gy * gy < law.swirl_radius * law.swirl_radius:
        fx, fy = fx + law.swirl * -fgy, fy + law.swirl * fgx

    speed = math.sqrt(fx * fx + fy * fy)
    if speed > v_max:
        s = v_max / speed
        return fx * s, fy * s
    return fx, fy


def _neighbour_force_2d(x: float, y: float, goal: Point, neighbours: Iterable[Point], radius: float,
                        p: PotentialParams, law: NeighbourLaw) -> tuple[Point, float]:
    """:func:`zswarm.paper.neighbour_law.neighbour_force` for one agent in floats: its force from its
    neighbours and the weight of its goal term."""
    spec = law.interaction
    sensed = []
    for nx, ny in neighbours:
        px, py = x - nx, y - ny
        sensed.append((px * px + py * py, px, py))
    if spec.nearest:
        sensed.sort(key=lambda s: s[0])  # stable: ties keep the order heard, as the vectorized rank does
        del sensed[law.k_nearest:]
    gx, gy = goal[0] - x, goal[1] - y
    gd = math.sqrt(gx * gx + gy * gy)
    tx, ty = (gx / gd, gy / gd) if gd > 0.0 else (0.0, 0.0)
    lr2, la2 = p.l_r**2, p.l_a**2
    rx = ry = ax = ay = wsum = block = 0.0
    for r2, px, py in sensed:
        r = math.sqrt(r2)
        w = 1.0
        if spec.cutoff:
            z = (r / radius - CUTOFF_INNER) / (1.0 - CUTOFF_INNER)
            w = 1.0 if z <= 0.0 else 0.0 if z >= 1.0 else 0.5 * (1.0 + math.cos(math.pi * z))
            if w <= 0.0:
                continue
        g_r = -2.0 * p.c_r / lr2 * math.exp(-r2 / lr2)
        g_a = 2.0 * p.c_a / la2 * math.exp(-r2 / la2) + 2.0 * p.c_a_prime
        rx += -w * g_r * px
        ry += -w * g_r * py
        ax += -w * g_a * px
        ay += -w * g_a * py
        wsum += w
        if spec.gate:
            cos = -(px * tx + py * ty) / (r if r > 0.0 else 1.0)
            near = min(max((law.gate_out - r) / (law.gate_out - law.gate_in), 0.0), 1.0)
            ahead = min(max((cos - AHEAD_COS) / (AHEAD_FULL - AHEAD_COS), 0.0), 1.0)
            block = max(block, near * ahead)
    if spec.mean:
        k = max(wsum, 1.0)
        ax, ay = ax / k, ay / k
    return (rx + ax, ry + ay), 1.0 - block
