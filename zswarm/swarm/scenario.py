"""What a scenario is: obstacles, the prey's motion, where agents spawn, N and the parameters.

A scenario is 2-D (the paper's plane, the default) or 3-D (``dimensions = 3``: positions (x, y, z),
spherical obstacles, a box to spawn in, a prey that flies). Every coordinate a scenario holds has
that many components; an obstacle's ``z`` is ignored in 2-D. The dimension is a parameter of the
set (``dimensions``), since the design checks that count neighbours depend on it.

A scenario is a frozen description; everything random about a run (the spawn positions) is drawn from
the run's seed by :meth:`Scenario.initial_positions`. The registered ones and TOML files are in
:mod:`zswarm.swarm.scenarios`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zswarm.errors import UsageError
from zswarm.paper.neighbour_law import neighbour_law
from zswarm.paper.neighbours import ObstacleIndex
from zswarm.paper.numeric import all_finite
from zswarm.paper.params import DEFAULT_PARAMS, LawChoice, Params, groups_of
from zswarm.paper.potentials import COMBINATIONS, Combination
from zswarm.swarm.prey import PreyMotion


@dataclass(frozen=True)
class Obstacle:
    """A circular (in 3-D, spherical) obstacle; radius 0 is the paper's point obstacle (eq 9)."""

    x: float
    y: float
    radius: float = 0.0
    z: float = 0.0

    def __post_init__(self) -> None:
        if not all_finite((self.x, self.y)):
            raise ValueError(f"an obstacle's x and y must be finite numbers (got x = {self.x!r}, y = {self.y!r})")
        if not all_finite((self.z,)):
            raise ValueError(f"an obstacle's z must be a finite number (got z = {self.z!r})")
        if not (all_finite((self.radius,)) and self.radius >= 0):
            raise ValueError(f"an obstacle's radius must be a finite number >= 0 (got {self.radius!r} at "
                             f"({self.x:g}, {self.y:g}))")


Box = tuple[float, ...]  # x_min, y_min, x_max, y_max (3-D: x_min, y_min, z_min, x_max, y_max, z_max)


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    params: Params = DEFAULT_PARAMS
    obstacles: tuple[Obstacle, ...] = ()
    prey_start: tuple[float, ...] = (0.0, 0.0)
    prey: PreyMotion = field(default_factory=PreyMotion)
    spawn: Box = (-4.5, -1.5, -2.5, 1.5)
    starts: tuple[tuple[float, ...], ...] = ()  # explicit start positions (override spawn)
    duration: float = 30.0
    dt: float = 0.05
    combination: Combination = "multiplicative"
    formation: bool = True
    capture_radius: float = 0.5

    def __post_init__(self) -> None:
        d = self.dimensions
        if self.combination not in COMBINATIONS:
            raise ValueError(f"combination must be one of {', '.join(COMBINATIONS)} (got {self.combination!r})")
        for name in ("duration", "dt", "capture_radius"):
            value = getattr(self, name)
            if not (all_finite((value,)) and value > 0):
                raise ValueError(f"scenario {name} must be a finite number > 0 (got {value!r})")
        if len(self.prey_start) != d or len(self.spawn) != 2 * d or any(len(p) != d for p in self.starts):
            shape = ("[x, y], spawn [x_min, y_min, x_max, y_max] and each start [x, y]" if d == 2 else
                     "[x, y, z], spawn [x_min, y_min, z_min, x_max, y_max, z_max] and each start [x, y, z]")
            raise ValueError(f"in {d}-D, prey_start must be {shape} (got prey_start {list(self.prey_start)}, "
                             f"spawn {list(self.spawn)})")
        for name, values in (("prey_start", self.prey_start), ("spawn", self.spawn),
                             *((f"starts[{k}]", p) for k, p in enumerate(self.starts))):
            if not all_finite(values):
                raise ValueError(f"scenario {name} must hold finite numbers (got {tuple(values)!r})")
        if not all(lo < hi for lo, hi in zip(self.spawn[:d], self.spawn[d:])):
            raise ValueError(f"spawn must be the minimum corner then the maximum corner, min < max (got {self.spawn})")
        if self.formation:
            neighbour_law(self.params)  # an interaction this potential cannot use fails here, in one line
        bob = self.prey.bob / self.prey.radius if d == 3 and self.prey.kind == "circle" else 0.0
        prey_speed = self.prey.speed * math.sqrt(1.0 + bob * bob)  # a flying circle rises and falls too
        if prey_speed >= self.params.swarm.v_max:
            raise ValueError(f"the prey must be slower than the agents (Section 5): prey speed "
                             f"{prey_speed:g} >= v_max {self.params.swarm.v_max}")
        if d == 3 and any(body == "unicycle" for _, body in self.groups()):
            raise ValueError("a unicycle drives on the ground: use body = point or double-integrator in 3-D")
        listed = sum(count for count, _, _ in groups_of(self.params.mix.groups))
        if listed > self.n_agents:
            raise ValueError(f"groups list {listed} agents, more than the scenario's {self.n_agents}")

    @property
    def dimensions(self) -> int:
        """2 (the paper's plane) or 3: the parameter ``dimensions`` of its set."""
        return self.params.swarm.dimensions

    @property
    def n_agents(self) -> int:
        return len(self.starts) if self.starts else self.params.swarm.n_agents

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt))

    def groups(self) -> list[tuple[LawChoice, str]]:
        """Its groups of agents, each one's law and body: those ``groups`` lists (a mixed swarm), then the
        scenario's own law and body, which every agent beyond them runs (:func:`zswarm.paper.params.groups_of`)."""
        own = self.params.law
        listed = [(own if law == own.law else LawChoice(law), body or self.params.body.body)
                  for _, law, body in groups_of(self.params.mix.groups)]
        return listed + [(own, self.params.body.body)]

    def group_of(self, ids: np.ndarray) -> np.ndarray:
        """The group (an index into :meth:`groups`) of each agent id: the listed groups take ids from 0 in
        order; every id beyond them is in the last."""
        edges = np.cumsum([count for count, _, _ in groups_of(self.params.mix.groups)], dtype=np.intp)
        return np.searchsorted(edges, np.asarray(ids), side="right")

    def accels(self, ids: np.ndarray | None = None) -> np.ndarray:
        """The acceleration bound of each agent (of ``ids``, default all; inf: a body that stops at once),
        by its group's body: what its neighbours' safety filters keep of its braking
        (:class:`zswarm.control.safety.Inertia`)."""
        ids = np.arange(self.n_agents) if ids is None else np.asarray(ids)
        inertial = [g for g, (_, body) in enumerate(self.groups()) if body == "double-integrator"]
        return np.where(np.isin(self.group_of(ids), inertial), self.params.body.accel, math.inf)

    def members(self) -> list[tuple[np.ndarray, LawChoice, str]]:
        """Each group that has agents: their ids, its law and its body (one group for a plain scenario)."""
        ids = np.arange(self.n_agents)
        of = self.group_of(ids)
        return [(ids[of == g], choice, body) for g, (choice, body) in enumerate(self.groups()) if (of == g).any()]

    def obstacle_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M, D) and radii (M,)."""
        centers = np.array([(o.x, o.y, o.z)[:self.dimensions] for o in self.obstacles],
                           dtype=float).reshape(-1, self.dimensions)
        return centers, np.array([o.radius for o in self.obstacles], dtype=float)

    def initial_positions(self, rng: np.random.Generator) -> np.ndarray:
        if self.starts:
            return np.array(self.starts, dtype=float)
        centers, radii = self.obstacle_arrays()
        return spawn_positions(rng, self.n_agents, self.spawn, 4.0 * self.params.swarm.robot_radius,
                               centers, radii)

    def arena(self, margin: float = 1.0) -> Box:
        """The region a run plays out in: the spawn box (or starts), every obstacle, the prey's start and
        where its motion can take it (its circle, its straight path over the run, the evasive prey's
        bounds), widened by ``margin``. What a map view should frame. A prey farther from the rest than
        twice the rest's size (``bench-field``'s, out of reach on purpose) is left out of the frame.
        (x_min, y_min, x_max, y_max); in 3-D (x_min, y_min, z_min, x_max, y_max, z_max)."""
        d = self.dimensions
        xs = [self.spawn[0], self.spawn[d]] + [p[0] for p in self.starts]
        ys = [self.spawn[1], self.spawn[d + 1]] + [p[1] for p in self.starts]
        for o in self.obstacles:
            xs += [o.x - o.radius, o.x + o.radius]
            ys += [o.y - o.radius, o.y + o.radius]
        px, py = [self.prey_start[0]], [self.prey_start[1]]
        m = self.prey
        if m.kind == "circle":
            px += [m.center[0] - m.radius, m.center[0] + m.radius]
            py += [m.center[1] - m.radius, m.center[1] + m.radius]
        elif m.kind == "straight":
            h, reach = math.radians(m.heading_deg), m.speed * self.duration
            px.append(self.prey_start[0] + reach * math.cos(h))
            py.append(self.prey_start[1] + reach * math.sin(h))
        elif m.kind == "evasive":
            px += [m.bounds[0], m.bounds[2]]
            py += [m.bounds[1], m.bounds[3]]
        size = math.hypot(max(xs) - min(xs), max(ys) - min(ys))
        gap = math.hypot(max(min(px) - max(xs), min(xs) - max(px), 0.0), max(min(py) - max(ys), min(ys) - max(py), 0.0))
        if gap <= 2.0 * size:
            xs, ys = xs + px, ys + py
        if d == 2:
            return (min(xs) - margin, min(ys) - margin, max(xs) + margin, max(ys) + margin)
        zs = [self.spawn[2], self.spawn[5], self.prey_start[2]] + [p[2] for p in self.starts]
        zs += [v for o in self.obstacles for v in (o.z - o.radius, o.z + o.radius)]
        if m.kind == "circle":
            z_c = m.center[2] if len(m.center) == 3 else 0.0
            zs += [z_c - m.bob, z_c + m.bob]
        elif m.kind == "straight":
            zs.append(self.prey_start[2] + m.speed * self.duration * math.sin(math.radians(m.climb_deg)))
        return (min(xs) - margin, min(ys) - margin, min(zs) - margin,
                max(xs) + margin, max(ys) + margin, max(zs) + margin)

    def check_placement(self) -> None:
        """Raise :class:`UsageError` (one line) if the spawn region cannot hold the swarm. Whether it can
        does not depend on the seed (the grid is fixed; the seed only picks cells and jitter), so one
        call before anything starts answers for every process of a run."""
        self.initial_positions(np.random.default_rng(0))

    def with_params(self, params: Params) -> Scenario:
        return dataclasses.replace(self, params=params)

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON-safe): what a recording stores as ``scenario_definition``."""
        out = dataclasses.asdict(self)
        out["params"] = self.params.flat()
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Scenario:
        """The inverse of :meth:`to_dict` (a recording's ``scenario_definition``)."""
        try:
            prey = dict(d["prey"])
            prey["center"], prey["bounds"] = tuple(prey["center"]), tuple(prey["bounds"])
            return cls(name=d["name"], description=d["description"], params=Params.from_flat(d["params"]),
                       obstacles=tuple(Obstacle(**o) for o in d["obstacles"]), prey_start=tuple(d["prey_start"]),
                       prey=PreyMotion(**prey), spawn=tuple(d["spawn"]), starts=tuple(tuple(s) for s in d["starts"]),
                       duration=d["duration"], dt=d["dt"], combination=d["combination"], formation=d["formation"],
                       capture_radius=d["capture_radius"])
        except (KeyError, TypeError, ValueError) as exc:
            raise UsageError(f"not a zswarm scenario definition ({type(exc).__name__}: {exc})") from None


def spawn_positions(rng: np.random.Generator, n: int, box: Box, min_sep: float,
                    centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """``n`` points in ``box`` (2-D or 3-D), at least ``min_sep`` apart and clear of obstacles (jittered grid)."""
    d = len(box) // 2
    lo, size = np.array(box[:d], dtype=float), np.array(box[d:], dtype=float) - np.array(box[:d], dtype=float)
    volume = float(np.prod(size)) / n
    s = (math.sqrt(volume) if d == 2 else math.cbrt(volume)) / 1.1
    for _ in range(60):
        axes = [lo[k] + s * (0.5 + np.arange(max(int(size[k] // s), 1))) for k in range(d)]
        cells = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, d)
        if len(centers):  # drop cells within s of an obstacle (a cell grid: O(N) memory, not N x obstacles)
            blocked, _ = ObstacleIndex(centers, radii, s).sensed(cells)
            cells = np.delete(cells, np.unique(blocked), axis=0)
        if len(cells) >= n:
            break
        s *= 0.95
    if len(cells) < n or s <= min_sep:
        raise UsageError(f"cannot place {n} agents {min_sep:g} apart in spawn region {box}; enlarge it")
    chosen = cells[rng.choice(len(cells), size=n, replace=False)]
    return chosen + rng.uniform(-(s - min_sep) / 2, (s - min_sep) / 2, size=(n, d))
