"""Many independent runs stepped together as one array program: the batched reference simulator.

B runs (each its own scenario, seed, parameter set, combination and faults; all with the same N, dt
and dimension D) are held as (B, N, D) arrays and stepped by the one control step
(:mod:`zswarm.control.step`: each group's law once for all the runs that share it, their parameters as
columns; the filter; each group's body), the one prey motion (:func:`zswarm.swarm.prey.step`,
vectorized over the runs that share a motion), as :mod:`zswarm.sim.simulator` steps a batch of one.
What each agent senses is dense (every other agent of its run, masked by the sensing radius) instead
of a cell grid: for the swarm sizes a tuning search simulates (N of 10 to a few hundred) one dense
program over all runs costs far less than B grid searches. Faults go through :class:`BatchChannel`,
the same rules as :class:`zswarm.sim.channel.FaultyChannel` with each run's own seeded generator, so
each run is the run :func:`zswarm.sim.simulator.simulate` makes alone, up to the order of
floating-point sums (``tests/test_batch.py`` holds every position within 1e-9 at every step).

Each run's outcome is folded by the one step loop and tally (:mod:`zswarm.swarm.tally`) that a single
run of :func:`zswarm.sim.outcome.run_outcome` goes through as a batch of one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zswarm.control.step import Barrier, Guard, Stepped, ahead, control_step
from zswarm.laws.contract import Observations
from zswarm.paper.potentials import Combination
from zswarm.sim.batch_channel import BatchChannel
from zswarm.swarm.tally import Outcome, OutcomeTally, Sensed, drive
from zswarm.swarm import metrics
from zswarm.swarm import prey as prey_motion
from zswarm.swarm.faults import FaultModel
from zswarm.swarm.prey import PreyMotion
from zswarm.swarm.scenarios import Scenario

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
        self.control = control_step(scen, [m.combination for m in members], [m.safety for m in members])
        self.radius = np.array([s.params.swarm.sensing_radius for s in scen])
        self.v_max = np.array([s.params.swarm.v_max for s in scen])
        positions = np.stack([s.initial_positions(np.random.default_rng(m.seed)) for s, m in zip(scen, members)])
        self.prey = np.array([s.prey_start for s in scen], dtype=float)
        self.state = self.control.start(positions, self.prey[:, None, :])
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
        barrier = self.control.filter
        self._headed = isinstance(barrier, Barrier) and bool(np.any(barrier.lookahead))  # guarded points ahead
        self.channel = (BatchChannel(self.n, [members[r].faults for r in self.faulty], self.dt,
                                     self.radius[self.faulty], self.v_max[self.faulty], dims=self.dims,
                                     velocities=self.control.hears_velocities or self.control.guards_inertia,
                                     headings=self._headed)
                        if len(self.faulty) else None)
        self.off_diagonal = ~np.eye(self.n, dtype=bool)
        self._geometry: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.upper = np.triu(np.ones((self.n, self.n), dtype=bool), 1)
        self.step_index = 0
        self.counts = np.zeros((b, 3), dtype=np.int64)  # interventions, stalled, braked (agent-steps)
        self._pending_counts: np.ndarray | None = None

    def _within(self, x: np.ndarray) -> np.ndarray:
        """(B, N, N): agent j within the sensing radius of agent i (i != j), on dense blocks."""
        return (_squared_distances(x) <= np.square(self.radius)[:, None, None]) & self.off_diagonal

    def _now(self) -> tuple[np.ndarray, np.ndarray]:
        """The squared distances between the agents (B, N, N) and each agent's clearance to each obstacle
        (B, N, M) at this step: found once, for what the agents sense and for the tally."""
        x = self.positions
        if self._geometry is None or self._geometry[0] is not x:  # new positions: a step, or a state set
            clearance = metrics.obstacle_clearance(x[:, :, None, :], self.centers[:, None, :, :], self.radii[:, None, :])
            self._geometry = (x, _squared_distances(x), clearance)
        return self._geometry[1:]

    def sensed_now(self) -> tuple[Observations, Guard | None]:
        """What every agent of every run senses now, on dense blocks: every other agent within the sensing
        radius (or, through the faulty channel, what reached it, with the velocity and age it came with),
        the obstacles within it, the target; and, behind a filter, what it guards against (exact, or the
        newest it heard of each, with its age)."""
        x, v = self.state.position, self.state.velocity
        b, n, dims = x.shape
        r2, clearance = self._now()
        near = (r2 <= np.square(self.radius)[:, None, None]) & self.off_diagonal
        nb_pos = np.broadcast_to(x[:, None, :, :], (b, n, n, dims))
        nb_vel = np.broadcast_to(v[:, None, :, :], (b, n, n, dims))
        nb_age = np.zeros((b, n, n))
        goal = np.broadcast_to(self.prey[:, None, :], x.shape)
        if self.channel is not None:  # the faulty runs use what reached them instead
            f, k = self.faulty, self.step_index
            believed, heard, heard_goal = self.channel.step(k, x[f], self.prey[f], v[f], self.state.heading[f])
            velocity, age = self.channel.heard_motion(k)
            nb_pos, near, goal = nb_pos.copy(), near.copy(), goal.copy()
            nb_pos[f], nb_age[f], near[f], goal[f] = believed, age, heard, heard_goal
            if self.channel.velocities:  # (a law that reads none is given the true ones, unread)
                nb_vel = nb_vel.copy()
                nb_vel[f] = velocity
        m = self.centers.shape[1]
        obs = Observations(
            position=x, velocity=v, neighbour_position=nb_pos, neighbour_velocity=nb_vel, neighbour_age=nb_age,
            neighbour_mask=near, obstacle_centre=np.broadcast_to(self.centers[:, None], (b, n, m, dims)),
            obstacle_radius=np.broadcast_to(self.radii[:, None], (b, n, m)),
            obstacle_mask=self.has_obstacle[:, None, :] & (clearance <= self.radius[:, None, None]),
            target=goal, v_max=self.v_max[:, None], dt=self.dt, state=np.zeros((b, n, 0)))
        barrier = self.control.filter
        if barrier is None:
            return obs, None
        points = barrier.points(self.state) if isinstance(barrier, Barrier) else x
        mask = near if points is x and self.channel is None else self._within(points)
        point, age = np.broadcast_to(points[:, None, :, :], (b, n, n, dims)), np.zeros((b, n, n))
        look = np.broadcast_to(np.asarray(barrier.lookahead if isinstance(barrier, Barrier) else 0.0), (b, n))
        if self.channel is not None:
            f = self.faulty
            heard, believed, heard_age = self.channel.known(self.step_index, x[f])
            if self._headed:  # each one's point ahead of its axle, as last heard
                believed = ahead(believed, self.channel.belief_heading, look[f][:, None, :])
            point, mask = point.copy(), mask.copy()
            point[f], age[f], mask[f] = believed, heard_age, heard & self.off_diagonal
        if not (isinstance(barrier, Barrier) and barrier.inertial):
            return obs, Guard(point, age, mask, look[:, None, :])
        velocity = np.broadcast_to(v[:, None, :, :], (b, n, n, dims))
        if self.channel is not None:  # each one's velocity as last heard
            velocity = velocity.copy()
            velocity[self.faulty] = self.channel.heard_motion(self.step_index)[0]
        accel = np.broadcast_to(np.asarray(barrier.accel, dtype=float), (b, n))[:, None, :]
        return obs, Guard(point, age, mask, look[:, None, :], velocity=velocity, accel=accel)

    def command(self) -> Stepped:
        """Every agent's step (:mod:`zswarm.control.step`) from what it senses now."""
        obs, guard = self.sensed_now()
        stepped = self.control(obs, guard, self.state, when=f"at t = {self.step_index * self.dt:.2f} s of a batch")
        if stepped.filtered is not None:
            f = stepped.filtered
            self._pending_counts = np.stack([f.acted, f.stalled, f.braked], axis=-1).reshape(
                len(self.members), self.n, 3).sum(axis=1)
        return stepped

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    def advance(self, stepped: Stepped) -> None:
        """Move each run's prey (from the agents' current positions), then the agents' bodies as
        ``stepped`` says."""
        if self._pending_counts is not None:  # counted when applied, as the simulator and the agents do
            self.counts += self._pending_counts
            self._pending_counts = None
        self.prey = self._prey_step()
        self.state = stepped.state
        self.step_index += 1

    def safety_counts(self) -> np.ndarray:
        """(B, 3): the agent-steps each run's filter changed, stalled and braked (applied steps)."""
        return self.counts

    def sensed(self) -> Sensed:
        """What every run senses now, for the tally: the pairs of its sensing graph (dense) and its
        sensed obstacles."""
        r2, clearance = self._now()
        r, i, j = np.nonzero((r2 <= np.square(self.radius)[:, None, None]) & self.upper)
        ro, a, m = np.nonzero(self.has_obstacle[:, None, :] & (clearance <= self.radius[:, None, None]))
        return Sensed(r, i, j, np.sqrt(r2[r, i, j]), ro, a, m, clearance[ro, a, m])

    def _prey_step(self) -> np.ndarray:
        """:func:`zswarm.swarm.prey.step` for every run, one call per motion the runs share."""
        out = self.prey.copy()
        for motion, rows in self.motions.items():
            out[rows] = prey_motion.step(motion, self.prey[rows], self.dt, self.positions[rows])
        return out


def _squared_distances(x: np.ndarray) -> np.ndarray:
    """|P_i - P_j|^2 of every pair of every run (B, N, N)."""
    d = x[:, :, None, :] - x[:, None, :, :]
    return np.einsum("bijk,bijk->bij", d, d)


@dataclass
class BatchResult:
    outcomes: list[Outcome]
    trajectory: np.ndarray | None = None  # (steps + 1, B, N, D) when kept
    prey_trajectory: np.ndarray | None = None  # (steps + 1, B, D)


def simulate_batch(members: list[Member], steps: int, keep_trajectory: bool = False,
                   components: bool = False) -> BatchResult:
    """Run every member for ``steps`` steps through the one step loop (:func:`zswarm.swarm.tally.drive`);
    ``components``: tally the sensing graph's groups at every step (``max_components``)."""
    sim = BatchSimulator(members)
    tally = OutcomeTally(len(members), sim.n, sim.dt, np.array([m.scenario.capture_radius for m in members]),
                         np.array([m.scenario.params.swarm.robot_radius for m in members]), components,
                         [m.scenario for m in members])
    traj = np.empty((steps + 1, *sim.positions.shape)) if keep_trajectory else None
    prey_traj = np.empty((steps + 1, *sim.prey.shape)) if keep_trajectory else None

    def keep(k: int, stepped: Stepped) -> None:
        traj[k], prey_traj[k] = sim.positions, sim.prey

    drive(sim, steps, tally, watch=keep if keep_trajectory else None)
    return BatchResult(tally.outcomes(sim.safety_counts(), sim.channel, sim.faulty), traj, prey_traj)
