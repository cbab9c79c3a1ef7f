"""The law contract: what a control law is given (one agent's observation) and what it gives back (a
desired velocity), in one form for one agent and one for a batch.

A law sees what an agent really has, and nothing global:

- its own ``position`` and ``velocity`` (D = 2 or 3 coordinates);
- each sensed neighbour's ``position``, ``velocity`` and ``age`` (seconds since that neighbour sent it);
- the obstacles within reach, each a ``centre`` and a ``radius`` (0: the paper's point obstacle);
- the ``target``: the goal or the prey as it last sensed it;
- ``v_max``, the control period ``dt``, the dimension, and the law's own per-agent ``state``.

The least a user writes is one function ``law(obs) -> velocity`` (a sequence of D floats). A law with
parameters, per-agent state or a batched form subclasses :class:`SwarmLaw`. The batched observation,
:class:`Observations`, holds the same fields over leading axes (runs, agents), with neighbours and
obstacles padded to a common count and masked; :meth:`Observations.stack` and :meth:`Observations.one`
are the only places the two layouts are converted, so a law written for one agent runs in a batch by a
per-agent loop, and a batched form is held to its single form by ``tests/test_law_conformance.py``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Sequence

import numpy as np

from zswarm.errors import ParamError


@dataclass(frozen=True)
class Neighbour:
    """A sensed neighbour as the agent knows it: where it was, how it moved, how old that is (s)."""

    position: np.ndarray
    velocity: np.ndarray
    age: float = 0.0


@dataclass(frozen=True)
class Obstacle:
    """An obstacle within reach: a disc (a ball in 3-D) of ``radius`` about ``centre``."""

    centre: np.ndarray
    radius: float = 0.0


@dataclass(frozen=True)
class Observation:
    """What one agent has at one control step (see the module doc)."""

    position: np.ndarray
    velocity: np.ndarray
    neighbours: tuple[Neighbour, ...]
    obstacles: tuple[Obstacle, ...]
    target: np.ndarray
    v_max: float
    dt: float
    state: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def dims(self) -> int:
        return len(self.position)


@dataclass(frozen=True)
class Observations:
    """Observations over leading axes L (runs, agents): each field of :class:`Observation` as an array,
    neighbours (L, K) and obstacles (L, M) padded and masked. ``v_max`` broadcasts against L."""

    position: np.ndarray  # (L..., D)
    velocity: np.ndarray  # (L..., D)
    neighbour_position: np.ndarray  # (L..., K, D)
    neighbour_velocity: np.ndarray  # (L..., K, D)
    neighbour_age: np.ndarray  # (L..., K)
    neighbour_mask: np.ndarray  # (L..., K) bool: which slots hold a sensed neighbour
    obstacle_centre: np.ndarray  # (L..., M, D)
    obstacle_radius: np.ndarray  # (L..., M)
    obstacle_mask: np.ndarray  # (L..., M) bool
    target: np.ndarray  # (L..., D)
    v_max: np.ndarray | float  # broadcasts against (L...)
    dt: float
    state: np.ndarray  # (L..., S)

    @property
    def dims(self) -> int:
        return self.position.shape[-1]

    @property
    def lead(self) -> tuple[int, ...]:
        return self.position.shape[:-1]

    @classmethod
    def stack(cls, rows: Sequence[Sequence[Observation]]) -> Observations:
        """(B, N) single observations as one batch, neighbours and obstacles padded with masked slots
        (filled with values a law must not see: far away, fast, old)."""
        b, n = len(rows), len(rows[0])
        if any(len(r) != n for r in rows):
            raise ValueError("every run of a batch needs the same number of agents")
        first = rows[0][0]
        d, s = first.dims, len(first.state)
        k = max((len(o.neighbours) for r in rows for o in r), default=0)
        m = max((len(o.obstacles) for r in rows for o in r), default=0)
        out = {name: np.zeros(shape) for name, shape in (
            ("position", (b, n, d)), ("velocity", (b, n, d)), ("target", (b, n, d)), ("state", (b, n, s)),
            ("neighbour_position", (b, n, k, d)), ("neighbour_velocity", (b, n, k, d)),
            ("neighbour_age", (b, n, k)), ("obstacle_centre", (b, n, m, d)), ("obstacle_radius", (b, n, m)),
            ("v_max", (b, n)))}
        out["neighbour_position"][:] = _PAD
        out["neighbour_velocity"][:] = _PAD
        out["neighbour_age"][:] = _PAD
        out["obstacle_centre"][:] = _PAD
        out["obstacle_radius"][:] = 1.0
        nmask, omask = np.zeros((b, n, k), dtype=bool), np.zeros((b, n, m), dtype=bool)
        for r, row in enumerate(rows):
            for i, o in enumerate(row):
                out["position"][r, i], out["velocity"][r, i], out["target"][r, i] = o.position, o.velocity, o.target
                out["state"][r, i], out["v_max"][r, i] = o.state, o.v_max
                for j, nb in enumerate(o.neighbours):
                    out["neighbour_position"][r, i, j], out["neighbour_velocity"][r, i, j] = nb.position, nb.velocity
                    out["neighbour_age"][r, i, j] = nb.age
                    nmask[r, i, j] = True
                for j, ob in enumerate(o.obstacles):
                    out["obstacle_centre"][r, i, j], out["obstacle_radius"][r, i, j] = ob.centre, ob.radius
                    omask[r, i, j] = True
        return cls(neighbour_mask=nmask, obstacle_mask=omask, dt=first.dt, **out)

    @classmethod
    def of_swarm(cls, position: np.ndarray, velocity: np.ndarray, target: np.ndarray, v_max: float, dt: float,
                 state: np.ndarray, pairs: tuple[np.ndarray, ...],
                 obstacles: tuple[np.ndarray, np.ndarray, np.ndarray], velocities: bool = True) -> Observations:
        """One swarm's observations (leading axes (1, N)) from flat lists: ``pairs`` (agent i, the
        neighbour's position, velocity, age; or agent i and neighbour j, sensed exactly and now) and
        ``obstacles`` (agent i, centre, radius), each padded to the most any agent has. Without
        ``velocities`` (no law reads them) exact neighbours' velocities read as 0."""
        n, d = position.shape
        agent = pairs[0]
        slot, k = _slots(agent, n)
        if len(pairs) == 2 and n <= _DENSE:  # exact and small: every agent a slot, masked (no copy)
            nmask = np.zeros((1, n, n), dtype=bool)
            nmask[0, agent, pairs[1]] = True
            npos, nvel = np.broadcast_to(position, (1, n, n, d)), np.broadcast_to(velocity, (1, n, n, d))
            return cls._with_obstacles(position, velocity, target, v_max, dt, state, obstacles, npos, nvel,
                                       np.zeros((1, n, n)), nmask)
        if len(pairs) == 2:  # exact: a gather of the swarm's own rows, a padding row beyond them
            index = np.full((n, k), n)
            index[agent, slot] = pairs[1]
            pad = np.full((1, d), _PAD)
            npos = np.concatenate([position, pad])[index][None]
            nvel = np.concatenate([velocity, pad])[index][None] if velocities else np.broadcast_to(0.0, npos.shape)
            nage = np.broadcast_to(0.0, (1, n, k))
        else:
            packed = np.full((1, n, k, 2 * d + 1), _PAD)  # one scatter for position, velocity and age
            packed[0, agent, slot] = np.concatenate([pairs[1], pairs[2], np.asarray(pairs[3], dtype=float)[:, None]],
                                                    axis=1)
            npos, nvel, nage = packed[..., :d], packed[..., d:2 * d], packed[..., 2 * d]
        nmask = np.zeros((1, n, k), dtype=bool)
        nmask[0, agent, slot] = True
        return cls._with_obstacles(position, velocity, target, v_max, dt, state, obstacles, npos, nvel, nage, nmask)

    @classmethod
    def _with_obstacles(cls, position, velocity, target, v_max, dt, state, obstacles, npos, nvel, nage,
                        nmask) -> Observations:
        """:meth:`of_swarm`'s observations, its obstacles padded to the most any agent senses."""
        n, d = position.shape
        o_agent, centre, radius = obstacles
        o_slot, m = _slots(o_agent, n)
        ocen, orad, omask = np.full((1, n, m, d), _PAD), np.ones((1, n, m)), np.zeros((1, n, m), dtype=bool)
        ocen[0, o_agent, o_slot], orad[0, o_agent, o_slot], omask[0, o_agent, o_slot] = centre, radius, True
        return cls(position=position[None], velocity=velocity[None], neighbour_position=npos, neighbour_velocity=nvel,
                   neighbour_age=nage, neighbour_mask=nmask, obstacle_centre=ocen, obstacle_radius=orad,
                   obstacle_mask=omask, target=target[None], v_max=v_max, dt=dt, state=state[None])

    def one(self, index: tuple[int, ...]) -> Observation:
        """The single observation at ``index`` of the leading axes (its masked slots dropped)."""
        nm, om = self.neighbour_mask[index], self.obstacle_mask[index]
        v_max = np.broadcast_to(self.v_max, self.lead)[index]
        return Observation(
            position=self.position[index].copy(), velocity=self.velocity[index].copy(),
            neighbours=tuple(Neighbour(p.copy(), v.copy(), float(a)) for p, v, a in zip(
                self.neighbour_position[index][nm], self.neighbour_velocity[index][nm], self.neighbour_age[index][nm])),
            obstacles=tuple(Obstacle(c.copy(), float(r)) for c, r in zip(
                self.obstacle_centre[index][om], self.obstacle_radius[index][om])),
            target=self.target[index].copy(), v_max=float(v_max), dt=self.dt, state=self.state[index].copy())

    def replace(self, **changes: Any) -> Observations:
        """A copy with some fields changed (no checks: the cheap copy a step makes several times)."""
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__, **changes)
        return out


_PAD = 1e6  # what a masked slot holds: a law that reads it unmasked gives a visibly wrong answer
_DENSE = 128  # up to this many agents, a swarm's observations hold every agent as a masked slot (no gather)


def _slots(agent: np.ndarray, n: int) -> tuple[np.ndarray, int]:
    """Each pair's slot among its agent's pairs (in the order given), and the most slots any agent uses."""
    agent = np.asarray(agent, dtype=np.intp)
    if len(agent) == 0:
        return agent, 0
    counts = np.bincount(agent, minlength=n)
    first = np.cumsum(counts) - counts
    if np.all(agent[1:] >= agent[:-1]):  # already grouped by agent (the pair search's usual order)
        return np.arange(len(agent)) - first[agent], int(counts.max())
    order = np.argsort(agent, kind="stable")
    slot = np.empty(len(agent), dtype=np.intp)
    slot[order] = np.arange(len(agent)) - first[agent[order]]
    return slot, int(counts.max())


@dataclass(frozen=True)
class Context:
    """What a law knows of the run when it is bound, before any agent steps: the dimension, the
    control period, the speed limit, the sensing radius, the agents' radius and the pair spacing d
    the scenario is built for (the paper's d^f; R / 1.2 where its potential has none)."""

    dims: int
    dt: float
    v_max: float
    sensing_radius: float
    robot_radius: float
    spacing: float


@dataclass(frozen=True)
class NoParams:
    """A law without parameters of its own."""


class SwarmLaw:
    """A law as a class: its parameters (``Params``, a frozen dataclass whose defaults are the
    published values; set from a params file's ``[law]`` table or ``--set law.NAME=VALUE``), the ranges
    ``zswarm tune`` may search (``ranges``), what it needs beyond positions (``needs``), the size of its
    per-agent state (``state_size``: then both forms return ``(velocity, state)`` and read
    ``obs.state``, zeros at the start), and optionally a batched form (:meth:`batch`).

    The single form :meth:`command` defaults to the batched form on a batch of one; a law defines at
    least one of the two."""

    name: ClassVar[str] = ""
    reference: ClassVar[str] = ""
    Params: ClassVar[type] = NoParams
    ranges: ClassVar[dict[str, tuple[float, float]]] = {}
    needs: ClassVar[tuple[str, ...]] = ()
    state_size: ClassVar[int] = 0
    #: The paper's design guidelines (Propositions 1-5, ``zswarm design``) hold for it (apf alone).
    guidelines: ClassVar[bool] = False

    def __init__(self, params: Any, context: Context) -> None:
        self.params, self.context = params, context

    @classmethod
    def params_from(cls, scenario: Any, settings: dict[str, float | int], combination: str | None) -> Any:
        """Its parameter set for a run of ``scenario``: the published defaults with ``settings`` (the
        run's ``law.NAME`` values) applied, each checked (:func:`law_params`)."""
        return law_params(cls, settings)

    @classmethod
    def merge(cls, laws: list[SwarmLaw]) -> list[tuple[list[int], SwarmLaw]]:
        """The laws of several runs (the same class), as few instances as can step them in one call of
        the batched form: here, the runs whose parameters and context are equal share the first's."""
        groups: dict[tuple, list[int]] = {}
        for r, law in enumerate(laws):
            groups.setdefault((repr(law.params), law.context), []).append(r)
        return [(rows, laws[rows[0]]) for rows in groups.values()]

    def describe_params(self) -> dict[str, Any] | None:
        """What a run records of its parameters (None: nothing beyond the settings)."""
        if dataclasses.is_dataclass(self.params) and not isinstance(self.params, type):
            return dataclasses.asdict(self.params)
        return None

    #: Optionally, the single form in plain floats for one 2-D agent, where numpy's per-call cost would be
    #: most of the work: ``floats(position, velocity, target, obstacles, neighbours, v_max, dt)`` (tuples;
    #: obstacles as (cx, cy, radius), neighbours as (position, velocity, age)) -> (vx, vy); a law with a
    #: state takes it last, as a tuple, and returns (velocity, its next state).
    #: The control step calls it for an agent process (:meth:`zswarm.control.step.ControlStep.one`); the
    #: batched form stays the law's definition, and ``tests/test_control_step.py`` holds this one to it.
    floats: Any = None

    def command(self, obs: Observation) -> Any:
        if type(self).batch is SwarmLaw.batch:
            raise NotImplementedError(f"law {self.name or type(self).__name__} defines neither command nor batch")
        out = self.batch(Observations.stack([[obs]]))
        if self.state_size:
            return out[0][0, 0], out[1][0, 0]
        return out[0, 0]

    def batch(self, obs: Observations) -> Any:
        """The batched form over ``obs``'s leading axes: (L..., D) velocities (and (L..., S) states)."""
        raise NotImplementedError

    @classmethod
    def has_batch(cls) -> bool:
        return cls.batch is not SwarmLaw.batch


# -- vectorized helpers the built-in laws share ----------------------------------------------------------

def norm(x: np.ndarray) -> np.ndarray:
    """|x| over the last axis."""
    return np.sqrt(np.einsum("...k,...k->...", x, x))


def unit(x: np.ndarray) -> np.ndarray:
    """x / |x| over the last axis (0 where x = 0)."""
    n = norm(x)[..., None]
    return np.divide(x, n, out=np.zeros_like(x), where=n > 0.0)


def masked_sum(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Sum over the slot axis (-2 for vectors (L, K, D), -1 for scalars (L, K)) of the masked-in slots."""
    if values.ndim == mask.ndim + 1:
        return np.where(mask[..., None], values, 0.0).sum(axis=-2)
    return np.where(mask, values, 0.0).sum(axis=-1)


def unit_2d(x: float, y: float) -> tuple[float, float]:
    """:func:`unit` of one 2-D vector in floats."""
    n = math.sqrt(x * x + y * y)
    return (x / n, y / n) if n > 0.0 else (0.0, 0.0)


def saturate_2d(x: float, y: float, v_max: float) -> tuple[float, float]:
    """:func:`zswarm.paper.potentials.saturate` of one 2-D vector in floats."""
    speed = math.sqrt(x * x + y * y)
    if speed > v_max:
        s = v_max / speed
        return x * s, y * s
    return x, y


def param(default: float, dimension: str = "none", doc: str = "", lo: float = 0.0, lo_open: bool = True,
          hi: float = float("inf")) -> Any:
    """A law parameter: its published default, its dimension (:meth:`zswarm.laws.scale.Units.scaled`),
    what it is, and its valid range (checked in one place, :func:`law_params`)."""
    return field(default=default, metadata={"dimension": dimension, "doc": doc, "lo": lo, "lo_open": lo_open,
                                            "hi": hi})


def law_params(cls: type[SwarmLaw], settings: dict[str, float | int]) -> Any:
    """The law's parameter set: its published defaults with ``settings`` applied, each checked in one
    line against the range its field declares (:func:`zswarm.laws.contract.param`)."""
    params_cls = cls.Params
    if params_cls is NoParams or not dataclasses.is_dataclass(params_cls):
        if settings:
            raise ParamError(f"law {cls.name} has no parameters of its own (got law.{next(iter(settings))})")
        return NoParams()
    fields = {f.name: f for f in dataclasses.fields(params_cls)}
    for name, value in settings.items():
        f = fields.get(name)
        if f is None:
            raise ParamError(f"law {cls.name} has no parameter {name!r}; its parameters: {', '.join(fields)}")
        meta = f.metadata
        lo, hi, lo_open = meta.get("lo", -math.inf), meta.get("hi", math.inf), meta.get("lo_open", False)
        if not math.isfinite(value) or value < lo or (lo_open and value == lo) or value > hi:
            bound = f"{'>' if lo_open else '>='} {lo:g}" + ("" if math.isinf(hi) else f" and <= {hi:g}")
            raise ParamError(f"law.{name} must be a finite number {bound} (got {value!r})")
    return params_cls(**{k: float(v) for k, v in settings.items()})
