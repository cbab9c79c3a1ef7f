"""Many independent runs stepped together as one array program: the batched reference simulator.

B runs (each its own scenario, seed, parameter set, combination and faults; all with the same N, dt
and dimension D) are held as (B, N, D) arrays and stepped by the equations of :mod:`zswarm.sim.simulator`:

    v_k = sat(-grad U_i(P_k), v_max),  P_{k+1} = P_k + dt v_k,  prey_{k+1} = prey.step(prey_k, P_k)

(each run's body moving as :mod:`zswarm.model.body` says; the point body is the line above)

with every sum over neighbours and obstacles dense (all pairs within a run, masked by the sensing
radius) instead of a cell grid: for the swarm sizes a tuning search simulates (N of 10 to a few
hundred) one dense program over all runs costs far less than B grid searches. Faults go through
:class:`BatchChannel`, the same rules as :class:`zswarm.sim.channel.FaultyChannel` with each run's own
seeded generator, so each run is the run :func:`zswarm.sim.simulator.simulate` makes alone, up to the
order of floating-point sums (``tests/test_batch.py`` holds every position within 1e-9 at every step).

Only the metrics a search needs are kept per run (:class:`BatchOutcome`): capture time, the closest
two agents came, collisions (onsets, as :class:`zswarm.model.metrics.Summary` counts them), the
closest an agent came to an obstacle, obstacle contacts and the final distance to the prey.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from zswarm.model import body as bodies
from zswarm.model import prey as prey_motion
from zswarm.model.faults import FaultModel
from zswarm.model.metrics import components
from zswarm.model.formation import pair_gain
from zswarm.model.neighbour_law import DensePairs, NeighbourLaw, neighbour_force, neighbour_law, unit_toward
from zswarm.model.params import PotentialParams
from zswarm.model.potentials import (
    Combination,
    goal_terms,
    obstacle_offsets,
    obstacle_terms,
    saturate,
)
from zswarm.model.prey import PreyMotion
from zswarm.model.scenarios import Scenario
from zswarm.sim.batch_channel import BatchChannel

#: Dense pairs cost B N^2 memory per step; beyond this N use :func:`zswarm.sim.simulator.simulate`.
MAX_AGENTS = 1000


@dataclass(frozen=True)
class Member:
    """One run of a batch: what :func:`zswarm.sim.simulator.simulate` would be called with."""

    scenario: Scenario
    seed: int
    faults: FaultModel | None = None
    combination: Combination | None = None

    @property
    def faulty(self) -> bool:
        return self.faults is not None and self.faults.active


@dataclass(frozen=True)
class BatchOutcome:
    """What one run of a batch measured (the matching keys of ``simulate(...).summary``)."""

    capture_time: float | None
    min_pair_distance: float
    collisions: int
    min_obstacle_clearance: float | None
    obstacle_collisions: int
    final_centroid_goal_distance: float
    final_components: int  # groups of the sensing graph at the end
    final_median_nearest: float | None  # median distance to the nearest neighbour within R, at the end

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _column(values: list[float], dims: int) -> np.ndarray:
    """(B,) values shaped (B, 1, ..., 1) to broadcast against (B, ...) arrays of ``dims`` axes."""
    return np.asarray(values, dtype=float).reshape((-1,) + (1,) * (dims - 1))


class _Potentials:
    """Each run's potential parameters as columns (B, 1, ...) that broadcast against (B, ...) arrays of
    ``dims`` axes: what the functions of :mod:`zswarm.model.potentials` take in place of one set."""

    def __init__(self, params: list[PotentialParams], dims: int) -> None:
        for name in ("l_o", "l_g", "l_a", "l_r", "c_o", "c_g", "c_a", "c_r", "c_a_prime"):
            setattr(self, name, _column([getattr(p, name) for p in params], dims))


def _variant_groups(scen: list[Scenario]) -> list[tuple[np.ndarray, NeighbourLaw, _Potentials]]:
    """The runs whose interaction is not the paper's, grouped by interaction and k; each group's gate
    distance, sensing radius and potentials as columns (b, 1, 1) over its pairs."""
    groups: dict[tuple[str, int], list[int]] = {}
    laws = [neighbour_law(s.params) for s in scen]
    for r, law in enumerate(laws):
        if scen[r].formation and not law.interaction.is_paper:
            groups.setdefault((law.interaction.name, law.k_nearest), []).append(r)
    out = []
    for rows in groups.values():
        first = laws[rows[0]]
        law = NeighbourLaw(first.interaction, _column([laws[r].sensing_radius for r in rows], 3),
                           _column([laws[r].gate_out for r in rows], 3), first.k_nearest)
        out.append((np.array(rows), law, _Potentials([scen[r].params.potential for r in rows], 3)))
    return out


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
        pots = [s.params.potential for s in scen]
        self.per_agent, self.per_pair = _Potentials(pots, 2), _Potentials(pots, 3)  # (B, N) and (B, N, N|M)
        self.multiplicative = np.array([(m.combination or m.scenario.combination) == "multiplicative"
                                        for m in members])[:, None]
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
                                     self.radius[self.faulty], dims=self.dims) if len(self.faulty) else None)
        self.off_diagonal = ~np.eye(self.n, dtype=bool)
        self.step_index = 0
        self.variants = _variant_groups(scen)

    # -- the control law -------------------------------------------------------------------------------

    def velocities(self) -> np.ndarray:
        """Every agent's commanded velocity (B, N, 2) from what it senses now (eqs 12-15, 25-28, 36)."""
        x, pa, pp = self.positions, self.per_agent, self.per_pair
        goal = np.broadcast_to(self.prey[:, None, :], x.shape)
        psi_f = x[:, :, None, :] - x[:, None, :, :]  # (B, N, N, 2): P_i - P_j
        r2 = np.einsum("bijk,bijk->bij", psi_f, psi_f)
        near = (r2 <= np.square(self.radius)[:, None, None]) & self.off_diagonal
        blind = None
        if self.channel is not None:  # the faulty runs use what reached them instead
            f_idx = self.faulty
            believed, sensed, heard_goal = self.channel.step(self.step_index, x[f_idx], self.prey[f_idx])
            blind = np.zeros(x.shape[:2], dtype=bool)
            blind[f_idx] = np.isnan(heard_goal[..., 0])
            goal = goal.copy()
            goal[f_idx] = np.where(blind[f_idx, :, None], x[f_idx], heard_goal)
            psi_f = psi_f.copy()
            psi_f[f_idx] = x[f_idx][:, :, None, :] - believed
            r2 = r2.copy()
            r2[f_idx] = np.einsum("bijk,bijk->bij", psi_f[f_idx], psi_f[f_idx])
            near = near.copy()
            near[f_idx] = sensed
        near &= self.formation > 0
        # the interaction of each run (eqs 26-28, or a variant of zswarm.model.neighbour_law)
        paper = np.ones(len(x), dtype=bool)
        f_n, goal_weight = np.zeros_like(x), np.ones(x.shape[:2])
        for rows, law, pots in self.variants:
            paper[rows] = False
            f_n[rows], goal_weight[rows] = neighbour_force(DensePairs(), psi_f[rows], near[rows],
                                                           unit_toward(x[rows] - goal[rows]), pots, law)
        u_g, f_g = goal_terms(x - goal, pa)  # eqs 7-8
        f_g = goal_weight[..., None] * f_g
        # obstacles (eqs 9-11): the sensed ones, |P - C| - rho within the sensing radius
        d = x[:, :, None, :] - self.centers[:, None, :, :]
        dist = np.sqrt(np.einsum("bimk,bimk->bim", d, d))
        sensed_o = self.has_obstacle[:, None, :] & (dist - self.radii[:, None, :] <= self.radius[:, None, None])
        psi_o = obstacle_offsets(x[:, :, None, :], self.centers[:, None, :, :], self.radii[:, None, :])
        e_o, f_o = obstacle_terms(psi_o, pp)
        u_o = np.where(sensed_o, e_o, 0.0).sum(axis=2)
        f_o = np.where(sensed_o[..., None], f_o, 0.0).sum(axis=2)
        # combination (eqs 13 and 15), each run its own
        mult = self.multiplicative[..., None]
        f = np.where(mult, (u_g / pa.c_g)[..., None] * f_o + (1.0 + u_o / pa.c_g)[..., None] * f_g, f_o + f_g)
        # formation (eqs 26-28): F = -g(|psi|) psi per sensed pair, or the run's variant
        f_f = np.where(near[..., None], -pair_gain(r2, pp)[..., None] * psi_f, 0.0).sum(axis=2)
        f = f + np.where(paper[:, None, None], f_f, f_n)
        v = saturate(f, self.v_max[:, None])
        if blind is not None:
            v[blind] = 0.0
        return v

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    def advance(self, v: np.ndarray) -> None:
        """Move each run's prey (from the agents' current positions), then the agents' bodies under the
        commands ``v``."""
        self.prey = self._prey_step()
        x, u, h = self.state.position.copy(), self.state.velocity.copy(), self.state.heading.copy()
        for rows, spec in self.bodies:
            moved = bodies.step(spec, bodies.BodyState(x[rows], u[rows], h[rows]), v[rows], self.dt)
            x[rows], u[rows], h[rows] = moved
        self.state = bodies.BodyState(x, u, h)
        self.step_index += 1

    def _prey_step(self) -> np.ndarray:
        """:func:`zswarm.model.prey.step` for every run, vectorized over the runs that share a motion."""
        out, dt = self.prey.copy(), self.dt
        if self.dims == 3:  # the reference's own step, run by run (the 3-D motions are not vectorized here)
            for motion, rows in self.motions.items():
                for r in rows.nonzero()[0]:
                    out[r] = prey_motion.step(motion, self.prey[r], dt, self.positions[r])
            return out
        for motion, rows in self.motions.items():
            prey = self.prey[rows]
            if motion.kind == "static" or motion.speed == 0.0:
                continue
            if motion.kind == "straight":
                h = math.radians(motion.heading_deg)
                out[rows] = prey + motion.speed * dt * np.array([math.cos(h), math.sin(h)])
            elif motion.kind == "circle":
                c = np.asarray(motion.center, dtype=float)
                rel = prey - c
                angle = np.arctan2(rel[:, 1], rel[:, 0]) + motion.speed * dt / motion.radius
                out[rows] = c + motion.radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
            else:  # evasive: flee the nearest agent within sense_radius, stay inside the bounds
                away = prey[:, None, :] - self.positions[rows]
                dist = np.sqrt(np.einsum("bij,bij->bi", away, away))
                k = np.argmin(dist, axis=1)
                nearest = dist[np.arange(len(k)), k]
                flee = (nearest <= motion.sense_radius) & (nearest > 0.0)
                step = motion.speed * dt * away[np.arange(len(k)), k] / np.where(flee, nearest, 1.0)[:, None]
                x0, y0, x1, y1 = motion.bounds
                moved = np.stack([np.clip(prey[:, 0] + step[:, 0], x0, x1), np.clip(prey[:, 1] + step[:, 1], y0, y1)],
                                 axis=1)
                out[rows] = np.where(flee[:, None], moved, prey)
        return out


class _Tally:
    """The per-run metrics of :class:`BatchOutcome`, folded step by step (as Summary folds them)."""

    def __init__(self, sim: BatchSimulator) -> None:
        b, n = sim.positions.shape[:2]
        self.sim = sim
        self.capture_radius = np.array([m.scenario.capture_radius for m in sim.members])
        self.robot = np.array([m.scenario.params.swarm.robot_radius for m in sim.members])
        self.capture_step = np.full(b, -1)
        self.min_pair = np.full(b, np.inf)
        self.min_clearance = np.full(b, np.inf)
        self.collisions = np.zeros(b, dtype=np.int64)
        self.contacts = np.zeros(b, dtype=np.int64)
        self.upper = np.triu(np.ones((n, n), dtype=bool), 1)
        self.was_close = np.zeros((b, n, n), dtype=bool)
        self.was_touching = np.zeros(sim.radii.shape[:1] + (n,) + sim.radii.shape[1:], dtype=bool)
        self.centroid_distance = np.zeros(b)

    def observe(self) -> None:
        sim, x = self.sim, self.sim.positions
        self.centroid_distance = np.linalg.norm(x.mean(axis=1) - sim.prey, axis=1)
        caught = (self.capture_step < 0) & (self.centroid_distance <= self.capture_radius)
        self.capture_step[caught] = sim.step_index
        d = x[:, :, None, :] - x[:, None, :, :]
        dist = np.sqrt(np.einsum("bijk,bijk->bij", d, d))
        self.min_pair = np.minimum(self.min_pair, np.where(self.upper, dist, np.inf).min(axis=(1, 2)))
        within = dist <= sim.radius[:, None, None]  # Summary counts pairs of the sensing graph
        close = within & self.upper & (dist < 2.0 * self.robot[:, None, None])
        self.collisions += (close & ~self.was_close).sum(axis=(1, 2))
        self.was_close = close
        o = x[:, :, None, :] - sim.centers[:, None, :, :]
        dist_o = np.sqrt(np.einsum("bimk,bimk->bim", o, o))
        rho = sim.radii[:, None, :]
        sensed = sim.has_obstacle[:, None, :] & (dist_o - rho <= sim.radius[:, None, None])
        clearance = np.where(sensed, dist_o - rho, np.inf)
        self.min_clearance = np.minimum(self.min_clearance, clearance.min(axis=(1, 2), initial=np.inf))
        touching = clearance < self.robot[:, None, None]
        self.contacts += (touching & ~self.was_touching).sum(axis=(1, 2))
        self.was_touching = touching

    def final_shape(self) -> tuple[list[int], list[float | None]]:
        """Groups of the sensing graph and median nearest-neighbour distance of each run, now."""
        x, radius = self.sim.positions, self.sim.radius
        groups, nearest = [], []
        for r in range(len(x)):
            d = np.linalg.norm(x[r][:, None] - x[r][None], axis=-1)
            np.fill_diagonal(d, np.inf)
            i, j = np.nonzero(d <= radius[r])
            groups.append(len(np.unique(components(len(d), i, j))))
            near = np.where(d <= radius[r], d, np.inf).min(axis=1)
            nearest.append(float(np.median(near[np.isfinite(near)])) if np.isfinite(near).any() else None)
        return groups, nearest

    def outcomes(self) -> list[BatchOutcome]:
        dt = self.sim.dt
        groups, nearest = self.final_shape()
        return [BatchOutcome(
            capture_time=None if s < 0 else s * dt, min_pair_distance=float(self.min_pair[r]),
            collisions=int(self.collisions[r]),
            min_obstacle_clearance=float(self.min_clearance[r]) if math.isfinite(self.min_clearance[r]) else None,
            obstacle_collisions=int(self.contacts[r]),
            final_centroid_goal_distance=float(self.centroid_distance[r]),
            final_components=groups[r], final_median_nearest=nearest[r])
            for r, s in enumerate(self.capture_step)]


@dataclass
class BatchResult:
    outcomes: list[BatchOutcome]
    trajectory: np.ndarray | None = None  # (steps + 1, B, N, 2) when kept
    prey_trajectory: np.ndarray | None = None  # (steps + 1, B, 2)


def simulate_batch(members: list[Member], steps: int, keep_trajectory: bool = False) -> BatchResult:
    """Run every member for ``steps`` steps (the loop of :func:`zswarm.sim.simulator.simulate`)."""
    sim = BatchSimulator(members)
    tally = _Tally(sim)
    traj = np.empty((steps + 1, *sim.positions.shape)) if keep_trajectory else None
    prey_traj = np.empty((steps + 1, *sim.prey.shape)) if keep_trajectory else None
    for k in range(steps + 1):
        v = sim.velocities()
        if traj is not None:
            traj[k], prey_traj[k] = sim.positions, sim.prey
        tally.observe()
        if k < steps:
            sim.advance(v)
    return BatchResult(tally.outcomes(), traj, prey_traj)
