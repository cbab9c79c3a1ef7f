"""The control step, written once: sense -> law -> filter -> body. Every engine calls it; none names a law.

One step of every agent, over leading axes L = (runs, agents):

    u^_i   = law_g(obs_i)                      the law of agent i's group g (its batched form)
    u_i    = filter(u^, guard)                 the safety filter: a wrapper of whatever the laws command
    x_i'   = body_g(x_i, u_i, dt)              the body of agent i's group (:mod:`zswarm.control.body`)

A group is the agents that run one law in one body: every agent of a plain scenario, or one group of a
mixed swarm (:meth:`zswarm.swarm.scenario.Scenario.groups`). An agent that has not heard its target yet
(a NaN target) holds still. The filter guards every agent against every other, whatever their laws and
bodies. The engines only build what each agent sensed, its :class:`~zswarm.laws.contract.Observations`
(from the cell grid, from dense blocks, from Zenoh samples) and its :class:`Guard` (what the filter
keeps it clear of, with the age of what it knows of each), and apply the result, :class:`Stepped`.

An agent process steps one agent twenty times a second, where numpy's per-call cost would be most of
the work: :meth:`ControlStep.one` is the same step on a batch of one, with a plain-float shortcut inside
(the law's single form, the filter's (:mod:`zswarm.control.one_filter`), the point body's Euler step).
``tests/test_control_step.py`` holds it to the batched form for every registered law and every body.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from zswarm.control import body as bodies
from zswarm.control import safety as sf
from zswarm.control.one_filter import Acted, filter_floats
from zswarm.laws.bound import BoundLaw, LawFailed
from zswarm.laws.contract import Neighbour, Observation, Observations, Obstacle, _slots


BodyState = bodies.BodyState
tracked_point = bodies.tracked_point


def ahead(position: np.ndarray, heading: np.ndarray, look: np.ndarray | float) -> np.ndarray:
    """Where bodies are steered and guarded: each ``look`` ahead of its axle along its heading (a
    unicycle's tracked point, :func:`zswarm.control.body.tracked_point`), or where it is (``look`` 0: its
    heading, NaN or not, is not read)."""
    look = np.broadcast_to(np.asarray(look, dtype=float), np.shape(position)[:-1])
    if not look.any():
        return position
    return bodies.tracked_point(position, np.where(look > 0, heading, 0.0), look)


@dataclass(frozen=True)
class Guard:
    """What the filter keeps each agent clear of: its neighbours' tracked points as it believes them (G
    slots per agent, padded and masked), the age of each (s) and how far ahead of its axle each one's
    point is (``look``: a unicycle's look-ahead, 0 for the other bodies); ``brake``: agents that brake
    whatever they sense (an agent whose world is late: nothing it heard can bound anything)."""

    point: np.ndarray  # (L..., G, D)
    age: np.ndarray  # (L..., G)
    mask: np.ndarray  # (L..., G) bool
    look: np.ndarray | float = 0.0  # broadcasts against (L..., G)
    brake: np.ndarray | None = None  # (L...) bool
    # a body with inertia among them: each one's velocity as heard (L..., G, D) and acceleration bound
    # (broadcasts against (L..., G); inf: a body that stops at once)
    velocity: np.ndarray | None = None
    accel: np.ndarray | float = math.inf

    @classmethod
    def of_pairs(cls, n: int, agent: np.ndarray, point: np.ndarray, age: np.ndarray,
                 look: np.ndarray | float = 0.0, velocity: np.ndarray | None = None,
                 accel: np.ndarray | float = math.inf) -> Guard:
        """One swarm's guard (leading axes (1, N)) from flat lists: agent i guards against ``point``, ``age``
        (with inertia: ``velocity``, ``accel``)."""
        slot, g = _slots(agent, n)
        pts, ages, looks = np.zeros((1, n, g, point.shape[-1])), np.zeros((1, n, g)), np.zeros((1, n, g))
        mask = np.zeros((1, n, g), dtype=bool)
        pts[0, agent, slot], ages[0, agent, slot], looks[0, agent, slot], mask[0, agent, slot] = point, age, look, True
        vel, acc = None, math.inf
        if velocity is not None:
            vel, acc = np.zeros_like(pts), np.full((1, n, g), math.inf)
            vel[0, agent, slot], acc[0, agent, slot] = velocity, accel
        return cls(pts, ages, mask, looks, velocity=vel, accel=acc)

    @classmethod
    def of_one(cls, guarded: Sequence[tuple], dims: int, brake: bool = False) -> Guard:
        """One agent's guard (leading axes (1, 1)) from (point, age, look) triples, or (point, age, look,
        velocity, accel) where a body with inertia is among them."""
        g = len(guarded)
        velocity, accel = None, math.inf
        if any(len(x) > 3 for x in guarded):
            velocity = np.array([x[3] for x in guarded], dtype=float).reshape(1, 1, g, dims)
            accel = np.array([x[4] for x in guarded], dtype=float).reshape(1, 1, g)
        return cls(np.array([x[0] for x in guarded], dtype=float).reshape(1, 1, g, dims),
                   np.array([x[1] for x in guarded], dtype=float).reshape(1, 1, g),
                   np.ones((1, 1, g), dtype=bool), np.array([x[2] for x in guarded], dtype=float).reshape(1, 1, g),
                   np.array([[brake]]), velocity, accel)


class Stepped(NamedTuple):
    """One step: the bodies' next states, the commands they moved under, what the filter did."""

    state: bodies.BodyState
    command: np.ndarray  # (L..., D)
    filtered: sf.Filtered | None  # over the flattened leading axes (None: no filter)


#: A filter of the laws' commands: (commands (L..., D), observations, guard, bodies) -> what it let through.
Filter = Callable[[np.ndarray, Observations, Guard, bodies.BodyState], sf.Filtered]


@dataclass(frozen=True)
class Barrier:
    """The safety filter (:mod:`zswarm.control.safety`) as a wrapper of any law: its numbers for the runs
    along the first leading axis (``groups``: a slice or index array of runs, and their
    :class:`~zswarm.control.safety.Safety`), and how far ahead of each body its tracked point is (a
    unicycle's point ahead of its axle; 0 for the others)."""

    groups: tuple[tuple[Any, sf.Safety], ...]
    lookahead: np.ndarray | float = 0.0  # broadcasts against (L...)
    accel: np.ndarray | float = math.inf  # each body's acceleration bound (inf: it stops at once), as lookahead

    @property
    def inertial(self) -> bool:
        """Some body it guards cannot stop at once (S4): the engines hand it each neighbour's velocity."""
        return bool(np.isfinite(self.accel).any())

    def points(self, state: bodies.BodyState) -> np.ndarray:
        """Where each body is steered and guarded (:func:`ahead`)."""
        return ahead(state.position, state.heading, self.lookahead)

    def __call__(self, wanted: np.ndarray, obs: Observations, guard: Guard, state: bodies.BodyState) -> sf.Filtered:
        lead, dims = wanted.shape[:-1], wanted.shape[-1]
        points = self.points(state)
        flat = wanted.reshape(-1, dims)
        out, flags = flat.copy(), np.zeros((3, len(flat)), dtype=bool)  # acted, stalled, braked
        index = np.arange(len(flat)).reshape(lead)
        centre = np.broadcast_to(obs.obstacle_centre, obs.lead + obs.obstacle_centre.shape[-2:])
        radius = np.broadcast_to(obs.obstacle_radius, obs.lead + obs.obstacle_radius.shape[-1:])
        own = np.broadcast_to(np.asarray(self.lookahead, dtype=float), lead)
        theirs = np.broadcast_to(np.asarray(guard.look, dtype=float), guard.age.shape)
        inertial = self.inertial or bool(np.isfinite(guard.accel).any())
        for runs, safety in self.groups:
            at = index[runs].reshape(-1)
            n = len(at)
            me, look = points[runs].reshape(n, dims), own[runs].reshape(n)
            ii, kk = np.nonzero(guard.mask[runs].reshape(n, -1))
            io, mo = np.nonzero(obs.obstacle_mask[runs].reshape(n, -1))
            age = guard.age[runs].reshape(n, -1)[ii, kk]
            r = sf.rows(safety, n, ii, me[ii] - guard.point[runs].reshape(n, -1, dims)[ii, kk],
                        age, io, me[io] - centre[runs].reshape(n, -1, dims)[io, mo],
                        radius[runs].reshape(n, -1)[io, mo], sf.widening(look[ii] + theirs[runs].reshape(n, -1)[ii, kk]),
                        sf.widening(look[io]), self._inertia(runs, n, dims, state, guard, ii, kk, age, safety)
                        if inertial else None)
            if guard.brake is not None:
                r = r._replace(stale=r.stale | guard.brake[runs].reshape(n))
            done = sf.apply(flat[at], r)
            out[at] = done.command
            flags[:, at] = done.acted, done.stalled, done.braked
        return sf.Filtered(out, *flags)

    def _inertia(self, runs: Any, n: int, dims: int, state: bodies.BodyState, guard: Guard, ii: np.ndarray,
                 kk: np.ndarray, age: np.ndarray, safety: sf.Safety) -> sf.Inertia:
        """(S4)'s inputs for the agents of ``runs``: each one's velocity and acceleration bound, and each
        guarded neighbour's braking distance from its velocity as heard (at full speed where unheard)."""
        lead = state.position.shape[:-1]
        accel = np.broadcast_to(np.asarray(self.accel, dtype=float), lead)[runs].reshape(n)
        their = np.broadcast_to(np.asarray(guard.accel, dtype=float), guard.age.shape)[runs].reshape(n, -1)[ii, kk]
        if guard.velocity is None:
            stop = sf.stopping(np.full(len(ii), safety.v_max), their)
        else:
            stop = sf.neighbour_stop(guard.velocity[runs].reshape(n, -1, dims)[ii, kk], age, their, safety.v_max)
        return sf.Inertia(state.velocity[runs].reshape(n, dims), accel, stop)


@dataclass
class Group:
    """The agents that run one law in one body: ``index`` picks them from the leading axes (runs,
    agents); ``state`` is the law's per-agent state (b, n, S)."""

    law: BoundLaw
    body: bodies.BodySpec
    index: tuple[Any, Any]
    state: np.ndarray


class One(NamedTuple):
    """One agent's step: its command, what the filter did (None: nothing), its body's next state."""

    command: tuple[float, ...]
    acted: Acted | None
    position: tuple[float, ...]
    velocity: tuple[float, ...]
    heading: float | None


class ControlStep:
    """The step of a set of groups behind one filter (see the module doc). ``dt``: the control period."""

    def __init__(self, groups: list[Group], dt: float, filter: Filter | None = None) -> None:
        self.groups, self.dt, self.filter = groups, dt, filter
        self._single: tuple | None = None  # what :meth:`one` reads every tick, found once

    def _single_of(self, dims: int) -> tuple:
        """For :meth:`one`: the law's single form in floats (None: through an observation), its v_max,
        the filter's parameters (None: no filter) and look-ahead."""
        law = self.groups[0].law
        fast = law.law.floats if dims == 2 else None
        safety = look = None
        inertial = False
        if self.filter is not None:
            (_, safety), = self.filter.groups
            look = float(self.filter.lookahead)
            inertial = self.filter.inertial
        self._single = (fast, law.context.v_max, safety, look, inertial)
        return self._single

    @property
    def laws(self) -> list[BoundLaw]:
        return [g.law for g in self.groups]

    @property
    def hears_velocities(self) -> bool:
        """Some law may read its neighbours' velocities (a law that declares what it needs is taken at its
        word; one that declares nothing may read anything)."""
        return any("neighbour velocities" in g.law.law.needs or not type(g.law.law).needs for g in self.groups)

    @property
    def guards_inertia(self) -> bool:
        """Its filter guards a body with inertia: it needs each guarded neighbour's velocity (S4)."""
        return isinstance(self.filter, Barrier) and self.filter.inertial

    def start(self, positions: np.ndarray, facing: np.ndarray) -> bodies.BodyState:
        """Every body at rest at ``positions`` (L..., D); a headed one faces ``facing`` (its first goal)."""
        state = bodies.BodyState(np.array(positions, dtype=float), np.zeros_like(positions, dtype=float),
                                 np.full(positions.shape[:-1], np.nan))
        for g in self.groups:
            if g.body.headed:
                ahead = np.broadcast_to(facing, positions.shape)[g.index]
                state.heading[g.index] = bodies.start(g.body, positions[g.index], ahead).heading
        return state

    def __call__(self, obs: Observations, guard: Guard | None, state: bodies.BodyState, when: str = "") -> Stepped:
        """Every agent's step from what it sensed; a law that raises or answers with something other than
        a velocity is :class:`~zswarm.laws.bound.LawFailed` (``when`` says when, in its one line)."""
        blind = np.isnan(obs.target[..., 0])
        if blind.any():  # no target heard yet: it holds still (the law sees it standing on its target)
            obs = obs.replace(target=np.where(blind[..., None], obs.position, obs.target))
        wanted = np.zeros_like(obs.position)
        for g in self.groups:
            sub = _take(obs, g.index)
            if g.law.state_size:
                sub = sub.replace(state=g.state)
            try:
                wanted[g.index], g.state = g.law.decide_batch(sub)
            except Exception as exc:  # noqa: BLE001 - a user's law may raise anything: said in one line
                raise LawFailed.of(g.law.name, exc, when) from None
        if blind.any():
            wanted[blind] = 0.0
        filtered, command = None, wanted
        if self.filter is not None:
            filtered = self.filter(wanted, obs, guard, state)
            command = filtered.command.reshape(wanted.shape)
        if len(self.groups) == 1 and self.groups[0].index is _ALL:  # one body for all: no gathering
            return Stepped(bodies.step(self.groups[0].body, state, command, self.dt), command, filtered)
        position, velocity, heading = state.position.copy(), state.velocity.copy(), state.heading.copy()
        for g in self.groups:
            ix = g.index
            moved = bodies.step(g.body, bodies.BodyState(state.position[ix], state.velocity[ix], state.heading[ix]),
                                command[ix], self.dt)
            position[ix], velocity[ix], heading[ix] = moved
        return Stepped(bodies.BodyState(position, velocity, heading), command, filtered)

    def one(self, position: tuple[float, ...], velocity: tuple[float, ...], heading: float | None,
            neighbours: Sequence[tuple[tuple[float, ...], tuple[float, ...], float]],
            obstacles: Sequence[tuple[float, ...]], target: tuple[float, ...],
            guarded: Sequence[tuple[tuple[float, ...], float, float]], brake: bool, when: str = "") -> One:
        """The step of the one agent this step was made for (:func:`control_step` with ``agents``), a batch
        of one, from what it holds in plain floats: its body (``position``, ``velocity``, ``heading``), the
        neighbours its law may use (position, velocity, age: each within the sensing radius), the
        obstacles within it (centre..., radius), the ``target``; ``guarded`` the (tracked point, age,
        look-ahead) of each neighbour the filter guards it against (:class:`Guard`), ``brake`` its world
        is late. The same numbers as the batched form; in plain floats where that is cheaper (a law's
        single form in floats, :attr:`zswarm.laws.contract.SwarmLaw.floats`; the filter; the point body)."""
        g = self.groups[0]
        law = g.law
        fast, v_max, safety, look, inertial = self._single or self._single_of(len(position))
        try:
            if fast is not None and law.state_size:  # the law reads the floats, and its state
                v, kept = fast(position, velocity, target, obstacles, neighbours, v_max, self.dt,
                               tuple(g.state[0, 0].tolist()))
                v, g.state[0, 0] = law.checked(v), kept
            elif fast is not None:  # no observation to build: the law reads the floats
                v = law.checked(fast(position, velocity, target, obstacles, neighbours, v_max, self.dt))
            elif law.has_batch:  # a batch of one, built straight from the floats
                out, g.state = law.decide_batch(_batch_of_one(position, velocity, neighbours, obstacles, target,
                                                              v_max, self.dt, g.state))
                v = tuple(out[0, 0].tolist())
            else:
                v, g.state[0, 0] = law.decide(_observation(position, velocity, neighbours, obstacles, target,
                                                           v_max, self.dt, g.state[0, 0]))
        except Exception as exc:  # noqa: BLE001 - a user's law may raise anything: said in one line
            raise LawFailed.of(law.name, exc, when) from None
        u_hat, acted = (v if type(v) is tuple else tuple(v.tolist())), None
        command = u_hat
        if safety is not None:
            point = bodies.tracked_point(position, heading, look) if look else position
            command, acted = filter_floats(safety, point, velocity, self.filter.accel if inertial else math.inf,
                                           u_hat, guarded, obstacles, look, brake)
        if g.body.kind == "point":
            dt = self.dt
            if len(position) == 2:
                return One(command, acted, (position[0] + dt * command[0], position[1] + dt * command[1]), command, None)
            return One(command, acted, tuple([p + dt * c for p, c in zip(position, command)]), command, None)
        state = bodies.BodyState(np.array(position), np.array(velocity), np.array(np.nan if heading is None else heading))
        moved = bodies.step(g.body, state, np.array(command), self.dt)
        return One(command, acted, tuple(moved.position.tolist()), tuple(moved.velocity.tolist()),
                   float(moved.heading) if g.body.headed else None)


def _batch_of_one(position, velocity, neighbours, obstacles, target, v_max: float, dt: float,
                  state: np.ndarray) -> Observations:
    """One agent's :class:`~zswarm.laws.contract.Observations` (leading axes (1, 1)) from what it holds in
    plain floats: every neighbour and obstacle a real slot, none padded."""
    dims, k, m = len(position), len(neighbours), len(obstacles)
    near = np.array([(*n[0], *n[1], n[2]) for n in neighbours], dtype=float).reshape(1, 1, k, 2 * dims + 1)
    seen = np.array(obstacles, dtype=float).reshape(1, 1, m, dims + 1)
    return Observations(np.array(position, dtype=float).reshape(1, 1, dims),
                        np.array(velocity, dtype=float).reshape(1, 1, dims),
                        near[..., :dims], near[..., dims:2 * dims], near[..., 2 * dims],
                        np.ones((1, 1, k), dtype=bool), seen[..., :dims], seen[..., dims],
                        np.ones((1, 1, m), dtype=bool), np.array(target, dtype=float).reshape(1, 1, dims),
                        v_max, dt, state)


def _observation(position, velocity, neighbours, obstacles, target, v_max: float, dt: float,
                 state: np.ndarray) -> Observation:
    """One agent's :class:`~zswarm.laws.contract.Observation` from what it holds in plain floats."""
    dims = len(position)
    if neighbours:
        pos, vel = np.array([n[0] for n in neighbours], dtype=float), np.array([n[1] for n in neighbours], dtype=float)
        near = tuple(Neighbour(p, v, n[2]) for p, v, n in zip(pos, vel, neighbours))
    else:
        near = ()
    seen = tuple(Obstacle(np.array(o[:dims], dtype=float), float(o[dims])) for o in obstacles)
    return Observation(np.array(position, dtype=float), np.array(velocity, dtype=float), near, seen,
                       np.array(target, dtype=float), v_max, dt, state)


def _take(obs: Observations, index: tuple[Any, Any]) -> Observations:
    """The observations of the agents at ``index`` of the leading axes."""
    if index is _ALL:
        return obs
    v_max = obs.v_max if np.ndim(obs.v_max) == 0 else np.broadcast_to(obs.v_max, obs.lead)[index]
    return obs.replace(**{f.name: getattr(obs, f.name)[index] for f in dataclasses.fields(obs)
                          if f.name not in ("v_max", "dt", "state")}, v_max=v_max)


_ALL = (slice(None), slice(None))


# -- making the step of a run, a batch of runs or one agent ------------------------------------------------


def control_step(scenarios: Sequence, combinations_: Sequence | None = None, safety: Sequence[str] | str = "off",
                 agents: Sequence[int] | None = None, probe: bool = False) -> ControlStep:
    """The step of runs of ``scenarios`` (the same N, dt and dimension) over leading axes (runs, agents):
    each group of each run bound to its law (:func:`zswarm.laws.registry.bind`, ``probe``: and called
    once on a probe observation), runs whose groups can step together merged (their parameters as
    columns: :meth:`zswarm.laws.contract.SwarmLaw.merge`), and each run's filter under ``safety``.
    ``agents``: only these agents of the one scenario (an agent process: its own id)."""
    from zswarm.laws.registry import bind

    b = len(scenarios)
    combos = list(combinations_) if combinations_ is not None else [None] * b
    modes = [safety] * b if isinstance(safety, str) else list(safety)
    first = scenarios[0]
    ids = np.arange(first.n_agents) if agents is None else np.asarray(agents, dtype=np.intp)
    keyed: dict[tuple, list[tuple[int, BoundLaw, np.ndarray]]] = {}
    for r, s in enumerate(scenarios):
        combination = combos[r] or s.combination
        of = s.group_of(ids)
        for g, (choice, body) in enumerate(s.groups()):
            cols = np.flatnonzero(of == g)
            if len(cols):
                law = bind(s, combination, probe=probe, choice=choice)
                keyed.setdefault((choice.law, body, tuple(cols)), []).append((r, law, cols))
    groups = []
    for (_, kind, cols), found in keyed.items():
        for rows, law in _merged(found):
            runs = np.array([found[k][0] for k in rows])
            params = [scenarios[r].params for r in runs]
            spec = bodies.BodySpec(kind, *(_column([getattr(p.body, name) if name != "v_max" else p.swarm.v_max
                                                    for p in params]) for name in ("v_max", "turn_rate", "lookahead",
                                                                                   "accel")))
            index = _ALL if len(runs) == b and len(cols) == len(ids) else np.ix_(runs, np.array(cols))
            groups.append(Group(law, spec, index, law.start_state((len(runs), len(cols)))))
    filters: dict[sf.Safety, list[int]] = {}
    lookahead, accel = np.zeros((b, len(ids))), np.full((b, len(ids)), math.inf)
    for r, s in enumerate(scenarios):
        chosen = safety_of(s, modes[r])
        if chosen is not None:
            filters.setdefault(chosen, []).append(r)
        of = s.group_of(ids)
        for g, (_, body) in enumerate(s.groups()):
            if body == "unicycle":
                lookahead[r, of == g] = s.params.body.lookahead
        accel[r] = s.accels(ids)
    barrier = None
    if filters:
        groups_ = tuple((slice(None) if len(rows) == b else np.array(rows), safety_)
                        for safety_, rows in filters.items())
        one = agents is not None
        barrier = Barrier(groups_, float(lookahead.max()) if one else lookahead,
                          (float(accel.min()) if one else accel) if np.isfinite(accel).any() else math.inf)
    return ControlStep(groups, first.dt, barrier)


def safety_of(scenario, mode: str) -> sf.Safety | None:
    """The filter a run of ``scenario`` uses under ``mode`` (None: off), one for all its agents whatever
    their bodies (a unicycle's look-ahead widens the rows of its own pairs:
    :func:`zswarm.control.safety.widening`, a double integrator's braking distance its own and its
    neighbours' rows: :class:`~zswarm.control.safety.Inertia`)."""
    sf.parse_mode(mode)
    if mode == "off":
        return None
    return sf.safety_for(scenario.params, scenario.dt)  # each body's look-ahead widens its own rows (the step)


def _merged(found: list[tuple[int, BoundLaw, np.ndarray]]) -> list[tuple[list[int], BoundLaw]]:
    """The runs of one key that can step as one call of a law, and that law (their parameters as columns)."""
    laws = [law for _, law, _ in found]
    out = []
    for rows, merged in type(laws[0].law).merge([law.law for law in laws]):
        first = laws[rows[0]]
        out.append((rows, dataclasses.replace(first, law=merged)))
    return out


def _column(values: list[float]) -> np.ndarray | float:
    """One value per run as a (b, 1) column against (b, n) (a plain number where every run has it)."""
    if all(v == values[0] for v in values):
        return float(values[0])
    return np.asarray(values, dtype=float)[:, None]
