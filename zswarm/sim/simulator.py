"""The centralized reference simulator: the same equations, vectorized over the whole swarm.

Each step (explicit Euler, step ``dt``):

    v_k     = sat(-grad U_i(P_k), v_max)      (eq 5 / eq 36 with the speed limit)
    P_{k+1} = P_k + dt v_k                    (the point body; another body moves as
                                               :mod:`zswarm.model.body` says)
    prey_{k+1} = prey.step(prey_k, P_k)

where agent i's potential uses only the obstacles and neighbours within its sensing radius, found with
a cell grid (:mod:`zswarm.model.neighbours`). Every quantity agent i uses is what a distributed agent would
have sensed at step k, so a lockstep distributed run reproduces these trajectories.
Deterministic: the same scenario and seed give the same trajectories, bit for bit.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from zswarm.laws.bound import LawFailed
from zswarm.laws.contract import Observations
from zswarm.laws.registry import bind
from zswarm.model import body as bodies
from zswarm.model import prey as prey_motion
from zswarm.model.faults import FaultModel
from zswarm.model.metrics import Summary, obstacle_clearance
from zswarm.model.law import compile_law, swarm_field
from zswarm.model.neighbours import ObstacleIndex, pairs_within
from zswarm.model.safety import judged
from zswarm.model.observer import SwarmObserver
from zswarm.model.potentials import Combination, saturate
from zswarm.model import safety as sf
from zswarm.model.safety_tally import SafetyTally, safety_of
from zswarm.model.scenarios import Scenario
from zswarm.provenance import versions
from zswarm.sim.channel import FaultyChannel
from zswarm.sim.tally import Sensed, drive


class Simulator:
    """State of a simulated swarm and its step function."""

    def __init__(self, scenario: Scenario, seed: int, combination: Combination | None = None,
                 faults: FaultModel | None = None, safety: str = "off") -> None:
        self.scenario = scenario
        self.seed = seed
        self.combination: Combination = combination or scenario.combination
        p = scenario.params
        self.law = compile_law(p, self.combination, scenario.formation)  # once, shared with the observer
        self.bound = bind(scenario, self.combination)  # the law the agents run (apf: self.law, on flat pairs)
        self.law_state = self.bound.start_state((scenario.n_agents,))
        self.rng = np.random.default_rng(seed)
        self.body = bodies.body_spec(p)
        self.state = bodies.start(self.body, scenario.initial_positions(self.rng), np.asarray(scenario.prey_start))
        self.ids = np.arange(len(self.state.position))
        self.prey = np.array(scenario.prey_start, dtype=float)
        centers, radii = scenario.obstacle_arrays()
        self.obstacles = ObstacleIndex(centers, radii, p.swarm.sensing_radius)
        self.step_index = 0
        self.channel = (FaultyChannel(len(self.positions), faults, scenario.dt, p.swarm.sensing_radius,
                                      p.swarm.v_max, seed=faults.seed, dims=scenario.dimensions,
                                      velocities=not self.bound.is_apf)
                        if faults is not None and faults.active else None)
        self.safety = safety_of(scenario, safety, faulted=self.channel is not None)
        self.filtered: sf.Filtered | None = None  # what the filter did at the last step
        self.tally = SafetyTally(scenario.dt)

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    @property
    def headings(self) -> np.ndarray | None:
        """Each body's heading, for a body that has one."""
        return self.state.heading if self.body.headed else None

    @property
    def t(self) -> float:
        return self.step_index * self.scenario.dt

    def potential_and_velocity(self, positions: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
        """Every agent's U_i (apf; None for another law) and commanded velocity from what it senses at
        ``positions``."""
        if not self.bound.is_apf:
            return None, self.law_velocity(positions, goal)
        pairs, blind, exact = None, None, None
        if self.channel is not None:  # what each agent believes, through the faulty channel
            i, _, believed, goal = self.channel.step(self.step_index, positions, goal)
            blind = np.isnan(goal[:, 0])  # no prey heard yet: it does not move
            goal = np.where(blind[:, None], positions, goal)
            pairs = (i, positions[i] - believed)
        elif self.safety is not None and not self.body.headed:  # one search for the law and the filter
            i, j = pairs_within(positions, self.scenario.params.swarm.sensing_radius)
            pairs = (i, positions[i] - positions[j])
            exact = (*pairs, np.zeros(len(i)))
        u, f = swarm_field(self.law, self.obstacles, positions, goal, pairs)
        v = saturate(f, self.scenario.params.swarm.v_max)
        if blind is not None:
            v[blind] = 0.0
        if self.safety is not None:
            v = self.filter(positions, v, exact)
        return u, v

    def law_velocity(self, positions: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """A law other than apf through the contract: each agent's observation (its neighbours within
        the sensing radius, exactly or through the faulty channel with their velocities and ages; the
        obstacles within it; the target), the law's batched form on the swarm, then the filter."""
        velocities, radius = self.state.velocity, self.scenario.params.swarm.sensing_radius
        blind = None
        if self.channel is not None:
            i, j, believed, goal = self.channel.step(self.step_index, positions, goal, velocities)
            heard_velocity, age = self.channel.heard_motion(self.step_index, i, j)
            blind = np.isnan(goal[:, 0])
            goal = np.where(blind[:, None], positions, goal)
            pairs = (i, believed, heard_velocity, age)
        else:
            i, j = pairs_within(positions, radius)
            pairs = (i, positions[j], velocities[j], np.zeros(len(i)))
        a, m = self.obstacles.sensed(positions)
        obs = Observations.of_swarm(positions, velocities, np.broadcast_to(goal, positions.shape),
                                    self.scenario.params.swarm.v_max, self.scenario.dt, self.law_state, pairs,
                                    (a, self.obstacles.centers[m], self.obstacles.radii[m]))
        try:
            v, state = self.bound.decide_batch(obs)
        except Exception as exc:  # noqa: BLE001 - a user's law may raise anything: said in one line
            raise LawFailed.of(self.bound.name, exc, f"at t = {self.t:.2f} s of the simulation") from None
        v, self.law_state = v[0], state[0]
        if blind is not None:
            v[blind] = 0.0
        if self.safety is not None:
            exact = None if self.channel is not None else (i, positions[i] - positions[j], np.zeros(len(i)))
            v = self.filter(positions, v, exact)
        return v

    def filter(self, positions: np.ndarray, v: np.ndarray,
               pairs: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """The safety filter (:mod:`zswarm.model.safety`) on every agent's command, from what it senses:
        exact neighbour positions (``pairs`` as (i, psi, age), when already found), or, through the
        faulty channel, the newest it heard and its age."""
        if self.channel is not None:
            pairs = self.channel.known(self.step_index, positions)
        points = bodies.tracked_point(positions, self.headings, self.body.lookahead if self.body.headed else 0.0)
        self.filtered = sf.apply(v, sf.swarm_rows(self.safety, self.obstacles, points, pairs))
        return self.filtered.command

    def moving(self, commands: np.ndarray) -> np.ndarray:
        """The velocity each body moves with this step under ``commands`` (the point body: the commands)."""
        return bodies.velocity(self.body, self.state, commands, self.scenario.dt)

    def advance(self, commands: np.ndarray) -> None:
        """Move the prey (from the agents' current positions), then the agents' bodies under ``commands``."""
        dt = self.scenario.dt
        if self.filtered is not None:  # counted when applied, as an agent counts its ticks
            self.tally.add(self.filtered)
            self.filtered = None
        self.prey = prey_motion.step(self.scenario.prey, self.prey, dt, self.positions)
        self.state = bodies.step(self.body, self.state, commands, dt)
        self.step_index += 1


Shield = Callable[["Simulator", np.ndarray], np.ndarray]


class OneRun:
    """The reference simulator seen as a batch of one (:class:`zswarm.sim.tally.Engine`): (1, N, D)
    arrays, its sensing graph from the cell grid. ``shield``: another filter of the commands, whose
    changes are counted as the filter's are."""

    def __init__(self, sim: Simulator, shield: Shield | None = None) -> None:
        self.sim, self.shield = sim, shield
        self.dt = sim.scenario.dt
        self.shielded = SafetyTally(self.dt) if shield is not None else None
        self.energy: np.ndarray | None = None  # each agent's U_i at the last command (apf)

    @property
    def step_index(self) -> int:
        return self.sim.step_index

    @property
    def positions(self) -> np.ndarray:
        return self.sim.positions[None]

    @property
    def prey(self) -> np.ndarray:
        return self.sim.prey[None]

    def velocities(self) -> np.ndarray:
        self.energy, v = self.sim.potential_and_velocity(self.sim.positions, self.sim.prey)
        if self.shield is not None:
            wanted, v = v, self.shield(self.sim, v)
            self.shielded.add(judged(wanted, v, np.zeros(len(v), dtype=bool)))
        return v[None]

    def advance(self, v: np.ndarray) -> None:
        self.sim.advance(v[0])

    def sensed(self) -> Sensed:
        x, radius = self.sim.positions, self.sim.scenario.params.swarm.sensing_radius
        i, j = pairs_within(x, radius)
        keep = i < j
        i, j = i[keep], j[keep]
        d = x[i] - x[j]
        a, m = self.sim.obstacles.sensed(x)
        clearance = obstacle_clearance(x[a], self.sim.obstacles.centers[m], self.sim.obstacles.radii[m])
        zero = np.zeros(len(i), dtype=np.intp)
        return Sensed(zero, i, j, np.sqrt(np.einsum("ij,ij->i", d, d)), np.zeros(len(a), dtype=np.intp), a, m,
                      clearance)

    def safety_counts(self) -> np.ndarray:
        t = self.shielded if self.shielded is not None else self.sim.tally
        return np.array([[t.interventions, t.stalled_steps, t.braked_steps]], dtype=np.int64)


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
    ``safety``: "barrier" filters every command (:mod:`zswarm.model.safety`).
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

    def watch(k: int, command: np.ndarray) -> None:
        v = sim.moving(command[0])
        if traj is not None:
            traj[k], prey_traj[k] = sim.positions, sim.prey
        if k % metrics_every == 0 or k == steps:
            # the energy of the true configuration: the agents' own sum when they sense it exactly
            energy = float(run.energy.sum()) if sim.channel is None and run.energy is not None else None
            metrics = observer.observe(sim.t, sim.ids, sim.positions, v, sim.prey, energy)
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
    if sim.safety is not None and sim.filtered is not None:
        swarm_log.log_safety(series, sim.positions, sim.filtered.flags(), sim.scenario.params.swarm.robot_radius)
    swarm_log.log_prey(series, sim.prey, np.array(trail[-400:]))
    swarm_log.log_metrics(series, metrics, thresholds)
    if graph_radius is not None:
        swarm_log.log_sensing_graph(series, sim.positions, graph_radius)
