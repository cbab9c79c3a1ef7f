"""Many independent runs stepped together as one array program: the batched reference simulator.

B runs (each its own scenario, seed, parameter set, combination and faults; all with the same N, dt
and dimension D) are held as (B, N, D) arrays and stepped by the one law (:func:`zswarm.model.law.field`,
called once per group of runs that share an interaction, each run's parameters as columns), the one
prey motion (:func:`zswarm.model.prey.step`, vectorized over the runs that share a motion) and the
one body step, as :mod:`zswarm.sim.simulator` steps a batch of one:

    v_k = sat(-grad U_i(P_k), v_max),  P_{k+1} = P_k + dt v_k,  prey_{k+1} = prey.step(prey_k, P_k)

(each run's body moving as :mod:`zswarm.model.body` says; the point body is the line above)

with every sum over neighbours and obstacles dense (all pairs within a run, masked by the sensing
radius) instead of a cell grid: for the swarm sizes a tuning search simulates (N of 10 to a few
hundred) one dense program over all runs costs far less than B grid searches. Faults go through
:class:`BatchChannel`, the same rules as :class:`zswarm.sim.channel.FaultyChannel` with each run's own
seeded generator, so each run is the run :func:`zswarm.sim.simulator.simulate` makes alone, up to the
order of floating-point sums (``tests/test_batch.py`` holds every position within 1e-9 at every step).

Each run's outcome is folded by the one step loop and tally (:mod:`zswarm.sim.tally`) that a single
run of :func:`zswarm.sim.outcome.run_outcome` goes through as a batch of one.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
import numpy as np

from zswarm.laws.bound import BoundLaw, LawFailed
from zswarm.laws.contract import Observations
from zswarm.laws.registry import bind, context_of
from zswarm.model import body as bodies
from zswarm.model import metrics
from zswarm.model import prey as prey_motion
from zswarm.model import safety as sf
from zswarm.model.faults import FaultModel
from zswarm.model.interaction import Interaction
from zswarm.model.law import field
from zswarm.model.neighbour_law import DensePairs, NeighbourLaw, neighbour_law
from zswarm.model.params import PotentialParams
from zswarm.model.potentials import Combination, obstacle_offsets, saturate
from zswarm.model.prey import PreyMotion
from zswarm.model.safety_tally import safety_of
from zswarm.model.scenarios import Scenario
from zswarm.sim.batch_channel import BatchChannel
from zswarm.sim.tally import Outcome, OutcomeTally, Sensed, drive

#: Dense pairs cost B N^2 memory per step; beyond this N use :func:`zswarm.sim.simulator.simulate`.
MAX_AGENTS = 1000


@dataclass(frozen=True)
class Member:
    """One run of a batch: what :func:`zswarm.sim.simulator.simulate` would be called with."""

    scenario: Scenario
    seed: int
    faults: FaultModel | None = None
    combination: Combination | None = None
    safety: str = "off"

    @property
    def faulty(self) -> bool:
        return self.faults is not None and self.faults.active


def _column(values: list[float], dims: int) -> np.ndarray:
    """(B,) values shaped (B, 1, ..., 1) to broadcast against (B, ...) arrays of ``dims`` axes."""
    return np.asarray(values, dtype=float).reshape((-1,) + (1,) * (dims - 1))


class _Potentials:
    """Each run's potential parameters as columns (B, 1, ...) that broadcast against (B, ...) arrays of
    ``dims`` axes: what the functions of :mod:`zswarm.model.potentials` take in place of one set."""

    def __init__(self, params: list[PotentialParams], dims: int) -> None:
        for name in ("l_o", "l_g", "l_a", "l_r", "c_o", "c_g", "c_a", "c_r", "c_a_prime"):
            setattr(self, name, _column([getattr(p, name) for p in params], dims))


@dataclass(frozen=True)
class _LawGroup:
    """The runs of a batch that share an interaction: the law steps them in one call of
    :func:`zswarm.model.law.field`, with their parameters as columns."""

    rows: np.ndarray | slice  # a slice when the group is the whole batch (no copy)
    law: NeighbourLaw | None  # None: the paper's eq 28 (or no formation)
    per_agent: _Potentials  # (b, 1) columns against (b, N)
    per_pair: _Potentials  # (b, 1, 1) columns against (b, N, N|M)
    multiplicative: np.ndarray  # (b, 1)


def _law_groups(scen: list[Scenario], combinations: list[Combination]) -> list[_LawGroup]:
    """The runs grouped by interaction (and k): a run without formation, or with the paper's
    interaction, belongs to the paper's group; each group's gate distance and sensing radius as
    (b, 1, 1) columns."""
    groups: dict[tuple[str, int], list[int]] = {}
    laws = [neighbour_law(s.params) for s in scen]
    for r, law in enumerate(laws):
        if scen[r].params.law.law != "apf":  # another law: stepped through the contract (_ContractGroup)
            continue
        if not scen[r].formation:  # no neighbour terms: only a swirl about the goal is left of the interaction
            laws[r] = law = dataclasses.replace(law, interaction=Interaction(swirl=law.interaction.swirl))
        key = ("paper", 0) if law.interaction.is_paper else (law.interaction.name, law.k_nearest)
        groups.setdefault(key, []).append(r)
    out = []
    for key, rows in groups.items():
        first = laws[rows[0]]
        law = None if key[0] == "paper" else NeighbourLaw(
            first.interaction, _column([laws[r].sensing_radius for r in rows], 3),
            _column([laws[r].gate_out for r in rows], 3), first.k_nearest,
            _column([laws[r].swirl for r in rows], 3), _column([laws[r].swirl_radius for r in rows], 2))
        pots = [scen[r].params.potential for r in rows]
        index = slice(None) if len(rows) == len(scen) else np.array(rows)
        out.append(_LawGroup(index, law, _Potentials(pots, 2), _Potentials(pots, 3),
                             np.array([combinations[r] == "multiplicative" for r in rows])[:, None]))
    return out


@dataclass
class _ContractGroup:
    """The runs of a batch that run one law other than apf, bound alike (the same law, settings and
    context): one call of its batched form (or its per-agent loop) steps them, with their state."""

    rows: np.ndarray
    law: BoundLaw
    state: np.ndarray  # (b, N, S)


def _contract_groups(scen: list[Scenario], combinations: list[Combination], n: int) -> list[_ContractGroup]:
    groups: dict[tuple, list[int]] = {}
    for r, s in enumerate(scen):
        if s.params.law.law != "apf":
            groups.setdefault((s.params.law, context_of(s)), []).append(r)
    out = []
    for rows in groups.values():
        law = bind(scen[rows[0]], combinations[rows[0]])
        out.append(_ContractGroup(np.array(rows), law, law.start_state((len(rows), n))))
    return out


def _safety_groups(members: list[Member]) -> list[tuple[np.ndarray, sf.Safety]]:
    """The runs that filter their commands, grouped by their filter's numbers."""
    groups: dict[sf.Safety, list[int]] = {}
    for r, m in enumerate(members):
        safety = safety_of(m.scenario, m.safety, m.faulty)
        if safety is not None:
            if m.scenario.params.body.body != "point":
                raise ValueError("the batched simulator filters point bodies only: use simulate() for the others")
            groups.setdefault(safety, []).append(r)
    return [(np.array(rows), safety) for safety, rows in groups.items()]


def _body_groups(scen: list) -> list[tuple[np.ndarray, bodies.BodySpec]]:
    """The runs of each body kind, with their limits as (runs, 1) columns."""
    out = []
    for kind in bodies.KINDS:
        rows = np.flatnonzero([s.params.body.body == kind for s in scen])
        if len(rows):
            col = lambda f: np.array([f(scen[r].params) for r in rows])[:, None]  # noqa: E731
            out.append((rows, bodies.BodySpec(kind, col(lambda p: p.swarm.v_max), col(lambda p: p.body.turn_rate),
                                              col(lambda p: p.body.lookahead), col(lambda p: p.body.accel))))
    return out


class BatchSimulator:
    """State of B runs and their common step (see the module doc)."""

    def __init__(self, members: list[Member]) -> None:
        if not members:
            raise ValueError("a batch needs at least one run")
        first = members[0].scenario
        self.n, self.dt = first.n_agents, first.dt
        self.dims = first.dimensions
        for m in members:
            if m.scenario.n_agents != self.n or m.scenario.dt != self.dt or m.scenario.dimensions != self.dims:
                raise ValueError(f"every run of a batch needs the same N, dt and dimensions (got N={m.scenario.n_agents}, "
                                 f"dt={m.scenario.dt}, {m.scenario.dimensions}-D beside N={self.n}, dt={self.dt}, "
                                 f"{self.dims}-D)")
        if self.n > MAX_AGENTS:
            raise ValueError(f"the batched simulator takes at most {MAX_AGENTS} agents (got {self.n})")
        self.members = members
        b = len(members)
        scen = [m.scenario for m in members]
        combinations = [m.combination or m.scenario.combination for m in members]
        self.laws = _law_groups(scen, combinations)
        self.contract = _contract_groups(scen, combinations, self.n)
        self.formation = _column([float(s.formation) for s in scen], 3)
        self.radius = np.array([s.params.swarm.sensing_radius for s in scen])
        self.v_max = np.array([s.params.swarm.v_max for s in scen])
        positions = np.stack([s.initial_positions(np.random.default_rng(m.seed)) for s, m in zip(scen, members)])
        self.prey = np.array([s.prey_start for s in scen], dtype=float)
        self.bodies = _body_groups(scen)
        self.state = bodies.BodyState(positions, np.zeros_like(positions), np.full(positions.shape[:2], np.nan))
        for rows, spec in self.bodies:
            start = bodies.start(spec, positions[rows], self.prey[rows][:, None, :])
            self.state.velocity[rows], self.state.heading[rows] = start.velocity, start.heading
        m_obs = max(len(s.obstacles) for s in scen)
        self.centers = np.zeros((b, m_obs, self.dims))
        self.radii = np.zeros((b, m_obs))
        self.has_obstacle = np.zeros((b, m_obs), dtype=bool)
        for r, s in enumerate(scen):
            c, rho = s.obstacle_arrays()
            self.centers[r, :len(c)], self.radii[r, :len(c)], self.has_obstacle[r, :len(c)] = c, rho, True
        self.motions: dict[PreyMotion, np.ndarray] = {}
        for r, s in enumerate(scen):
            self.motions.setdefault(s.prey, np.zeros(b, dtype=bool))[r] = True
        self.faulty = np.flatnonzero([m.faulty for m in members])
        self.channel = (BatchChannel(self.n, [members[r].faults for r in self.faulty], self.dt,
                                     self.radius[self.faulty], self.v_max[self.faulty], dims=self.dims,
                                     velocities=bool(self.contract))
                        if len(self.faulty) else None)
        self.off_diagonal = ~np.eye(self.n, dtype=bool)
        self.upper = np.triu(np.ones((self.n, self.n), dtype=bool), 1)
        self.step_index = 0
        self.filters = _safety_groups(members)
        self.counts = np.zeros((b, 3), dtype=np.int64)  # interventions, stalled, braked (agent-steps)
        self._pending_counts: np.ndarray | None = None

    # -- the control law -------------------------------------------------------------------------------

    def velocities(self) -> np.ndarray:
        """Every agent's commanded velocity (B, N, D) from what it senses now: the one law
        (:func:`zswarm.model.law.field`) on dense blocks, one call per group of runs that share an
        interaction."""
        x = self.positions
        goal = np.broadcast_to(self.prey[:, None, :], x.shape)
        psi_f = x[:, :, None, :] - x[:, None, :, :]  # (B, N, N, D): P_i - P_j
        r2 = np.einsum("bijk,bijk->bij", psi_f, psi_f)
        near = (r2 <= np.square(self.radius)[:, None, None]) & self.off_diagonal
        blind, heard = None, None
        if self.channel is not None:  # the faulty runs use what reached them instead
            f_idx = self.faulty
            believed, sensed, heard_goal = self.channel.step(self.step_index, x[f_idx], self.prey[f_idx],
                                                             self.state.velocity[f_idx])
            if self.contract:
                heard = (f_idx, believed, *self.channel.heard_motion(self.step_index))
            blind = np.zeros(x.shape[:2], dtype=bool)
            blind[f_idx] = np.isnan(heard_goal[..., 0])
            goal = goal.copy()
            goal[f_idx] = np.where(blind[f_idx, :, None], x[f_idx], heard_goal)
            psi_f = psi_f.copy()
            psi_f[f_idx] = x[f_idx][:, :, None, :] - believed
            near = near.copy()
            near[f_idx] = sensed
        sensed_f = near
        near = near & (self.formation > 0)
        # obstacles (eqs 9-11): the sensed ones, |P - C| - rho within the sensing radius
        d = x[:, :, None, :] - self.centers[:, None, :, :]
        dist = np.sqrt(np.einsum("bimk,bimk->bim", d, d))
        sensed_o = self.has_obstacle[:, None, :] & (dist - self.radii[:, None, :] <= self.radius[:, None, None])
        psi_o = obstacle_offsets(x[:, :, None, :], self.centers[:, None, :, :], self.radii[:, None, :])
        psi_g = x - goal
        f = np.zeros_like(x)  # runs of another law are filled below; no garbage through saturate
        for g in self.laws:
            r = g.rows
            f[r] = field(psi_g[r], DensePairs(sensed_o[r]), psi_o[r], DensePairs(near[r]), psi_f[r], g.per_agent,
                         g.multiplicative, law=g.law, p_pairs=g.per_pair, energy=False)[1]
        v = saturate(f, self.v_max[:, None])
        if self.contract:
            self._contract_velocities(v, x, goal, sensed_f, sensed_o, heard)
        if blind is not None:
            v[blind] = 0.0
        if self.filters:
            v = self._filter(x, v, sensed_o)
        return v

    def _contract_velocities(self, v: np.ndarray, x: np.ndarray, goal: np.ndarray, near: np.ndarray,
                             sensed_o: np.ndarray, heard: tuple | None) -> None:
        """Into ``v``: the commands of the runs whose law is not apf, each group's law through the
        contract on its observations: every other agent within the sensing radius (or, through the
        faulty channel, what reached it, with the velocity and age it came with), the obstacles within
        it, the target."""
        b, n, dims = x.shape
        nb_pos = np.broadcast_to(x[:, None, :, :], (b, n, n, dims))
        nb_vel = np.broadcast_to(self.state.velocity[:, None, :, :], (b, n, n, dims))
        nb_age = np.zeros((b, n, n))
        if heard is not None:
            f_idx, believed, velocity, age = heard
            nb_pos, nb_vel = nb_pos.copy(), nb_vel.copy()
            nb_pos[f_idx], nb_vel[f_idx], nb_age[f_idx] = believed, velocity, age
        m = self.centers.shape[1]
        for g in self.contract:
            r = g.rows
            obs = Observations(
                position=x[r], velocity=self.state.velocity[r], neighbour_position=nb_pos[r],
                neighbour_velocity=nb_vel[r], neighbour_age=nb_age[r], neighbour_mask=near[r],
                obstacle_centre=np.broadcast_to(self.centers[r][:, None], (len(r), n, m, dims)),
                obstacle_radius=np.broadcast_to(self.radii[r][:, None], (len(r), n, m)), obstacle_mask=sensed_o[r],
                target=goal[r], v_max=self.v_max[r][:, None], dt=self.dt, state=g.state)
            try:
                v[r], g.state = g.law.decide_batch(obs)
            except Exception as exc:  # noqa: BLE001 - a user's law may raise anything: said in one line
                raise LawFailed.of(g.law.name, exc, f"at t = {self.step_index * self.dt:.2f} s of a batch") from None

    def _filter(self, x: np.ndarray, v: np.ndarray, sensed_o: np.ndarray) -> np.ndarray:
        """The safety filter (:mod:`zswarm.model.safety`) on the commands of the runs that use it, all of
        a group's agents in one exact projection: exact neighbours, or through the faulty channel the
        newest each agent heard (fresh or not) with its age."""
        b, n, dims = x.shape
        near = (np.einsum("bijk,bijk->bij", x[:, :, None] - x[:, None], x[:, :, None] - x[:, None])
                <= np.square(self.radius)[:, None, None]) & self.off_diagonal
        psi = x[:, :, None, :] - x[:, None, :, :]
        age = np.zeros((b, n, n))
        if self.channel is not None:
            f_idx = self.faulty
            heard, believed, heard_age = self.channel.known(self.step_index, x[f_idx])
            near, psi, age = near.copy(), psi.copy(), age.copy()
            near[f_idx], psi[f_idx], age[f_idx] = heard & self.off_diagonal, x[f_idx][:, :, None, :] - believed, heard_age
        out = v.copy()
        counts = np.zeros((b, 3), dtype=np.int64)
        for runs, safety in self.filters:
            rr, ii, jj = np.nonzero(near[runs])
            ro, io, mo = np.nonzero(sensed_o[runs])
            run_of = runs[ro]
            r = sf.rows(safety, len(runs) * n, rr * n + ii, psi[runs][rr, ii, jj], age[runs][rr, ii, jj],
                        ro * n + io, x[run_of, io] - self.centers[run_of, mo], self.radii[run_of, mo])
            done = sf.apply(v[runs].reshape(-1, dims), r)
            out[runs] = done.command.reshape(len(runs), n, dims)
            counts[runs] = np.stack([done.acted, done.stalled, done.braked], axis=-1).reshape(len(runs), n, 3).sum(axis=1)
        self._pending_counts = counts
        return out

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    def advance(self, v: np.ndarray) -> None:
        """Move each run's prey (from the agents' current positions), then the agents' bodies under the
        commands ``v``."""
        if self._pending_counts is not None:  # counted when applied, as the simulator and the agents do
            self.counts += self._pending_counts
            self._pending_counts = None
        self.prey = self._prey_step()
        x, u, h = self.state.position.copy(), self.state.velocity.copy(), self.state.heading.copy()
        for rows, spec in self.bodies:
            moved = bodies.step(spec, bodies.BodyState(x[rows], u[rows], h[rows]), v[rows], self.dt)
            x[rows], u[rows], h[rows] = moved
        self.state = bodies.BodyState(x, u, h)
        self.step_index += 1

    def safety_counts(self) -> np.ndarray:
        """(B, 3): the agent-steps each run's filter changed, stalled and braked (applied steps)."""
        return self.counts

    def sensed(self) -> Sensed:
        """What every run senses now, for the tally: the pairs of its sensing graph (dense) and its
        sensed obstacles."""
        x = self.positions
        d = x[:, :, None, :] - x[:, None, :, :]
        r2 = np.einsum("bijk,bijk->bij", d, d)
        r, i, j = np.nonzero((r2 <= np.square(self.radius)[:, None, None]) & self.upper)
        clearance = metrics.obstacle_clearance(x[:, :, None, :], self.centers[:, None, :, :], self.radii[:, None, :])
        ro, a, m = np.nonzero(self.has_obstacle[:, None, :] & (clearance <= self.radius[:, None, None]))
        return Sensed(r, i, j, np.sqrt(r2[r, i, j]), ro, a, m, clearance[ro, a, m])

    def _prey_step(self) -> np.ndarray:
        """:func:`zswarm.model.prey.step` for every run, one call per motion the runs share."""
        out = self.prey.copy()
        for motion, rows in self.motions.items():
            out[rows] = prey_motion.step(motion, self.prey[rows], self.dt, self.positions[rows])
        return out


@dataclass
class BatchResult:
    outcomes: list[Outcome]
    trajectory: np.ndarray | None = None  # (steps + 1, B, N, D) when kept
    prey_trajectory: np.ndarray | None = None  # (steps + 1, B, D)


def simulate_batch(members: list[Member], steps: int, keep_trajectory: bool = False) -> BatchResult:
    """Run every member for ``steps`` steps through the one step loop (:func:`zswarm.sim.tally.drive`)."""
    sim = BatchSimulator(members)
    tally = OutcomeTally(len(members), sim.n, sim.dt, np.array([m.scenario.capture_radius for m in members]),
                         np.array([m.scenario.params.swarm.robot_radius for m in members]))
    if not keep_trajectory:
        drive(sim, steps, tally)
        return BatchResult(tally.outcomes(sim.safety_counts()))
    traj, prey_traj = np.empty((steps + 1, *sim.positions.shape)), np.empty((steps + 1, *sim.prey.shape))

    def keep(k: int, v: np.ndarray) -> None:
        traj[k], prey_traj[k] = sim.positions, sim.prey

    drive(sim, steps, tally, watch=keep)
    return BatchResult(tally.outcomes(sim.safety_counts()), traj, prey_traj)
