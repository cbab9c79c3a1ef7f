"""The centralized reference simulator: the same equations, vectorized over the whole swarm.

Each step (explicit Euler, step ``dt``):

    v_k     = sat(-grad U_i(P_k), v_max)      (eq 5 / eq 36 with the speed limit)
    P_{k+1} = P_k + dt v_k                    (the point body; another body moves as
                                               :mod:`zswarm.control.body` says)
    prey_{k+1} = prey.step(prey_k, P_k)

where agent i's potential uses only the obstacles and neighbours within its sensing radius, found with
a cell grid (:mod:`zswarm.paper.neighbours`). Every quantity agent i uses is what a distributed agent would
have sensed at step k, so a lockstep distributed run reproduces these trajectories.
Deterministic: the same scenario and seed give the same trajectories, bit for bit.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.errors import UsageError
from zswarm.control.step import Barrier, BodyState, Filter, Guard, Stepped, ahead, control_step
from zswarm.laws.contract import Observations
from zswarm.paper.field import compile_law
from zswarm.paper.neighbours import ObstacleIndex, pairs_within
from zswarm.paper.potentials import Combination
from zswarm.provenance import versions
from zswarm.sim.channel import FaultyChannel
from zswarm.swarm.tally import SafetyTally, Sensed, drive
from zswarm.swarm import prey as prey_motion
from zswarm.swarm.faults import FaultModel
from zswarm.swarm.metrics import Summary
from zswarm.swarm.observer import SwarmObserver
from zswarm.swarm.scenarios import Scenario


class Simulator:
    """State of a simulated swarm and its step: what every agent senses, built from the cell grid (or
    the faulty channel), through the one control step (:mod:`zswarm.control.step`). ``shield``: another
    filter in the safety filter's place (``zswarm bench safety`` puts ORCA there)."""

    def __init__(self, scenario: Scenario, seed: int, combination: Combination | None = None,
                 faults: FaultModel | None = None, safety: str = "off", shield: Filter | None = None) -> None:
        self.scenario = scenario
        self.seed = seed
        self.combination: Combination = combination or scenario.combination
        p = scenario.params
        self.law = compile_law(p, self.combination, scenario.formation)  # the observer's (energy, spacing)
        faulted = faults is not None and faults.active
        self.control = control_step([scenario], [self.combination], safety, probe=True)
        if shield is not None:
            self.control.filter = shield
        self.rng = np.random.default_rng(seed)
        start = self.control.start(scenario.initial_positions(self.rng)[None], np.asarray(scenario.prey_start))
        self.state = BodyState(start.position[0], start.velocity[0], start.heading[0])
        self.ids = np.arange(len(self.state.position))
        self.prey = np.array(scenario.prey_start, dtype=float)
        centers, radii = scenario.obstacle_arrays()
        self.obstacles = ObstacleIndex(centers, radii, p.swarm.sensing_radius)
        self.step_index = 0
        self.channel = (FaultyChannel(len(self.positions), faults, scenario.dt, p.swarm.sensing_radius,
                                      p.swarm.v_max, seed=faults.seed, dims=scenario.dimensions,
                                      velocities=self.control.hears_velocities or self.control.guards_inertia,
                                      headings=self.headings is not None and self.control.filter is not None)
                        if faulted else None)
        self.filtered = None  # what the filter did at the last step
        self._near: tuple | None = None
        self.tally = SafetyTally(scenario.dt)

    @property
    def bound(self):
        """The scenario's own law (in a mixed swarm, the law of the agents beyond the listed groups)."""
        own = self.scenario.params.law.law
        return next((g.law for g in self.control.groups if g.law.name == own), self.control.groups[0].law)

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    @property
    def headings(self) -> np.ndarray | None:
        """Each body's heading, for a swarm where some body has one."""
        return self.state.heading if any(g.body.headed for g in self.control.groups) else None

    @property
    def t(self) -> float:
        return self.step_index * self.scenario.dt

    def near(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Who senses whom now, (i, j) within the sensing radius, and which obstacles, (agent, obstacle):
        found once a step, for what the agents sense and for the tally."""
        x = self.state.position
        if self._near is None or self._near[0] is not x:  # new positions: a step, or a state set
            self._near = (x, *pairs_within(x, self.scenario.params.swarm.sensing_radius), *self.obstacles.sensed(x))
        return self._near[1:]

    def sensed(self) -> tuple[Observations, Guard | None]:
        """What every agent senses now: its observation (its neighbours within the sensing radius, exactly
        or through the faulty channel with their velocities and ages; the obstacles within it; the
        target) and, behind a filter, its guard (exact neighbours, or the newest each heard, with its age)."""
        x, v, n = self.state.position, self.state.velocity, len(self.state.position)
        p, k = self.scenario.params.swarm, self.step_index
        if self.channel is not None:
            i, j, believed, goal = self.channel.step(k, x, self.prey, v, self.state.heading)
            heard_velocity, age = self.channel.heard_motion(k, i, j)
            pairs = (i, believed, heard_velocity, age)
        else:
            goal = np.broadcast_to(self.prey, x.shape)
            i, j, _, _ = self.near()
            pairs = (i, j)
        _, _, a, m = self.near()
        obs = Observations.of_swarm(x, v, goal, p.v_max, self.scenario.dt, np.zeros((n, 0)), pairs,
                                    (a, self.obstacles.centers[m], self.obstacles.radii[m]), self.control.hears_velocities)
        barrier = self.control.filter
        if barrier is None:
            return obs, None
        if not isinstance(barrier, Barrier):  # another filter (a shield): the exact neighbours
            return obs, Guard.of_pairs(n, i, x[j], np.zeros(len(i)))
        look = np.broadcast_to(np.asarray(barrier.lookahead, dtype=float), (1, n))[0]
        accel = np.broadcast_to(np.asarray(barrier.accel, dtype=float), (1, n))[0]
        if self.channel is not None:  # the newest each heard, at its point ahead of its axle as heard
            gi, gj, points, age = self.channel.known(k, x)
            if self.channel.headings is not None:
                points = ahead(points, self.channel.headings[gi, gj], look[gj])
            heard = self.channel.heard_motion(k, gi, gj)[0] if barrier.inertial else None
            return obs, Guard.of_pairs(n, gi, points, age, look[gj], heard, accel[gj])
        points = barrier.points(BodyState(x[None], v[None], self.state.heading[None]))[0]
        if points is not x:
            i, j = pairs_within(points, p.sensing_radius)
        return obs, Guard.of_pairs(n, i, points[j], np.zeros(len(i)), look[j], v[j] if barrier.inertial else None,
                                   accel[j])

    def command(self) -> Stepped:
        """Every agent's step from what it senses now (the bodies' next states: :meth:`advance`)."""
        obs, guard = self.sensed()
        one = self.state
        stepped = self.control(obs, guard, BodyState(one.position[None], one.velocity[None], one.heading[None]),
                               when=f"at t = {self.t:.2f} s of the simulation")
        self.filtered = stepped.filtered
        return stepped

    def advance(self, stepped: Stepped) -> None:
        """Move the prey (from the agents' current positions), then the agents' bodies as ``stepped`` says."""
        if self.filtered is not None:  # counted when applied, as an agent counts its ticks
            self.tally.add(self.filtered)
            self.filtered = None
        self.prey = prey_motion.step(self.scenario.prey, self.prey, self.scenario.dt, self.positions)
        nxt = stepped.state
        self.state = BodyState(nxt.position[0], nxt.velocity[0], nxt.heading[0])
        self.step_index += 1


class OneRun:
    """The reference simulator seen as a batch of one (:class:`zswarm.swarm.tally.Engine`): (1, N, D)
    arrays, its sensing graph from the cell grid."""

    def __init__(self, sim: Simulator) -> None:
        self.sim = sim
        self.dt = sim.scenario.dt

    @property
    def step_index(self) -> int:
        return self.sim.step_index

    @property
    def positions(self) -> np.ndarray:
        return self.sim.positions[None]

    @property
    def prey(self) -> np.ndarray:
        return self.sim.prey[None]

    def command(self) -> Stepped:
        return self.sim.command()

    def advance(self, stepped: Stepped) -> None:
        self.sim.advance(stepped)

    def sensed(self) -> Sensed:
        return Sensed.of_pairs(self.sim.positions, *self.sim.near(), self.sim.obstacles)

    def safety_counts(self) -> np.ndarray:
        t = self.sim.tally
        return np.array([[t.interventions, t.stalled_steps, t.braked_steps]], dtype=np.int64)


#: What a simulated agent-step costs at most, metrics included: measured 15-26 us for 3,000 to 100,000
#: agents on 2 cores (``zswarm sim --agents N --duration 2``, less the start); memory is no limit (100,000
#: agents: 0.4 GB).
AGENT_STEP_S = 30e-6
TOO_LONG_S, NOTE_S = 600.0, 30.0


def cost_note(scenario: Scenario, duration: float) -> str | None:
    """Refuse, in one line (:class:`~zswarm.errors.UsageError`), a run this machine would spend more than
    :data:`TOO_LONG_S` on (its estimate); the line to say before one over :data:`NOTE_S` starts."""
    estimate = scenario.n_agents * round(duration / scenario.dt) * AGENT_STEP_S
    if estimate > TOO_LONG_S:
        raise UsageError(f"{scenario.n_agents} agents for {duration:g} s would take about {estimate / 60:.0f} minutes "
                         f"here ({AGENT_STEP_S * 1e6:g} us an agent-step): give fewer --agents or a shorter --duration")
    if estimate > NOTE_S:
        return f"note: about {estimate:.0f} s to simulate ({scenario.n_agents} agents, {duration:g} s)"
    return None



@dataclass
class RunResult:
    summary: dict[str, Any]
    metrics: Summary
    trajectory: np.ndarray | None = None  # (steps + 1, N, 2) when kept
    prey_trajectory: np.ndarray | None = None
    extra: dict[str, Any] = field(default_factory=dict)


def simulate(scenario: Scenario, seed: int, *, combination: Combination | None = None,
             duration: float | None = None, record: Path | None = None, record_every: int = 1,
             metrics_every: int = 1, keep_trajectory: bool = False, sensing_discs: bool = False,
             argv: list[str] | None = None, faults: FaultModel | None = None, viewer=None,
             sensing_graph: bool | None = None, safety: str = "off") -> RunResult:
    """Run a scenario to its end; optionally record it to Rerun (a file, and/or live to ``viewer``, a
    :class:`zswarm.record.live.Viewer`) and keep the trajectories.

    ``sensing_graph``: draw who senses whom in the recording (None: for N <= 100).
    ``faults``: pass neighbour and prey data through a seeded faulty channel (:mod:`zswarm.sim.channel`).
    ``safety``: "barrier" filters every command (:mod:`zswarm.control.safety`).
    """
    sim = Simulator(scenario, seed, combination, faults, safety)
    p = scenario.params
    steps = int(round((duration if duration is not None else scenario.duration) / scenario.dt))
    observer = SwarmObserver(scenario, law=sim.law)
    traj = np.empty((steps + 1, *sim.positions.shape)) if keep_trajectory else None
    prey_traj = np.empty((steps + 1, len(sim.prey))) if keep_trajectory else None
    header = {"scenario": scenario.name, "n_agents": int(len(sim.positions)), "seed": seed,
              "potential": sim.combination, "duration": steps * scenario.dt, "steps": steps,
              "dt": scenario.dt, "safety": safety, "law": sim.bound.describe()}
    rec = None
    if record is not None or (viewer is not None and viewer.wanted):
        from zswarm.record import swarm_log
        from zswarm.record.recording import open_recording

        rec = open_recording(record, "zswarm-sim", swarm_log.blueprint(arena=scenario.arena(),
                                                                       dimensions=scenario.dimensions),
                             recording_id=f"sim-{scenario.name}-{seed}", viewer=viewer)
        swarm_log.log_config(rec, {**header, "scenario_definition": scenario.to_dict(),
                                   "versions": versions(), "argv": argv or sys.argv})
        swarm_log.log_obstacles(rec, sim.obstacles.centers, sim.obstacles.radii)
        swarm_log.log_threshold_styles(rec, observer.thresholds())
        series = swarm_log.Series(rec, live=viewer is not None and viewer.wanted)
        labels = swarm_log.Labels()
    graph = sensing_graph if sensing_graph is not None else len(sim.positions) <= 100
    trail: list[np.ndarray] = []
    run = OneRun(sim)

    def watch(k: int, stepped: Stepped) -> None:
        v = stepped.state.velocity[0]  # the velocity each body moves with this step
        if traj is not None:
            traj[k], prey_traj[k] = sim.positions, sim.prey
        if k % metrics_every == 0 or k == steps:
            metrics = observer.observe(sim.t, sim.ids, sim.positions, v, sim.prey)
            if rec is not None and (k % record_every == 0 or k == steps):
                _log_step(rec, series, labels, sim, v, metrics, trail,
                          p.swarm.sensing_radius if sensing_discs else None, observer.thresholds(),
                          p.swarm.sensing_radius if graph else None)

    drive(run, steps, watch=watch)
    result = {**header, **observer.summary.result(), **sim.tally.result()}
    if sim.channel is not None:
        result["requested_faults"] = faults.requested()
        result["observed_dropout"] = sim.channel.observed_dropout
        result["observed_latency_ms"] = sim.channel.observed_latency_ms
    if rec is not None:
        from zswarm.record import swarm_log
        from zswarm.record.recording import close_recording

        series.flush()
        swarm_log.log_summary(rec, result)
        close_recording(rec, hold=viewer is not None and viewer.serve)
    return RunResult(result, observer.summary, traj, prey_traj)


def _log_step(rec, series, labels, sim: Simulator, v: np.ndarray, metrics: dict[str, float],
              trail: list[np.ndarray], sensing_radius: float | None, thresholds: dict[str, float],
              graph_radius: float | None) -> None:
    from zswarm.record import swarm_log

    swarm_log.set_time(rec, sim.step_index, sim.t, series)
    trail.append(sim.prey.copy())
    swarm_log.log_swarm(series, sim.t, sim.ids, sim.positions, v, sensing_radius, sim.headings, labels=labels)
    if sim.filtered is not None:
        swarm_log.log_safety(series, sim.positions, sim.filtered.flags(), sim.scenario.params.swarm.robot_radius)
    swarm_log.log_prey(series, sim.prey, np.array(trail[-400:]))
    swarm_log.log_metrics(series, metrics, thresholds)
    if graph_radius is not None:
        swarm_log.log_sensing_graph(series, sim.positions, graph_radius)
