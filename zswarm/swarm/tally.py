"""The one step loop (:func:`drive`) and the one per-step tally of a study's runs
(:class:`OutcomeTally`): B runs, a single run being B = 1; each key as
:class:`zswarm.swarm.metrics.Summary` defines it (docs/architecture.md, "One loop and one tally"). An
engine gives, each step, its positions (B, N, D), its prey (B, D) and what each run senses
(:class:`Sensed`)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any, Callable, Protocol

import numpy as np

from zswarm.control import safety as sf
from zswarm.control.step import Stepped
from zswarm.paper.neighbours import obstacle_clearance
from zswarm.swarm import metrics


@dataclass(frozen=True)
class Sensed:
    """What every run senses now: pairs (run, i, j) with i < j within the sensing radius and their
    distance; sensed obstacles (run, agent, obstacle) with the clearance |P - C| - rho."""

    run: np.ndarray
    i: np.ndarray
    j: np.ndarray
    distance: np.ndarray
    obstacle_run: np.ndarray
    agent: np.ndarray
    obstacle: np.ndarray
    clearance: np.ndarray

    @classmethod
    def of_pairs(cls, x: np.ndarray, i: np.ndarray, j: np.ndarray, a: np.ndarray, m: np.ndarray, obstacles) -> Sensed:
        """What one swarm at ``x`` (N, D) senses: its pairs (i, j) within the sensing radius (each both ways)
        and its sensed obstacles (agent ``a``, obstacle ``m`` of ``obstacles``, an
        :class:`~zswarm.paper.neighbours.ObstacleIndex`)."""
        keep = i < j
        i, j = i[keep], j[keep]
        d = x[i] - x[j]
        clearance = obstacle_clearance(x[a], obstacles.centers[m], obstacles.radii[m])
        zero = np.zeros(len(i), dtype=np.intp)
        return cls(zero, i, j, np.sqrt(np.einsum("ij,ij->i", d, d)), np.zeros(len(a), dtype=np.intp), a, m, clearance)


class Engine(Protocol):
    """What :func:`drive` steps: the batched simulator, or one run seen as a batch of one."""

    step_index: int
    dt: float

    @property
    def positions(self) -> np.ndarray: ...  # (B, N, D)

    @property
    def prey(self) -> np.ndarray: ...  # (B, D)

    def command(self) -> Stepped: ...  # every agent's step from what it senses now (zswarm.control.step)

    def advance(self, stepped: Stepped) -> None: ...  # the prey moves, then the bodies as stepped says

    def sensed(self) -> Sensed: ...

    def safety_counts(self) -> np.ndarray: ...  # (B, 3): interventions, stalled, braked agent-steps


@dataclass(frozen=True)
class Outcome:
    """What one run measured (the matching keys of ``simulate(...).summary``)."""

    capture_time: float | None
    min_pair_distance: float
    collisions: int
    min_obstacle_clearance: float | None
    obstacle_collisions: int
    final_centroid_goal_distance: float
    final_components: int  # groups of the sensing graph at the end
    final_median_nearest: float | None  # median distance to the nearest neighbour within R, at the end
    safety_interventions: int = 0  # agent-steps the safety filter changed (zswarm.swarm.tally)
    safety_stalled_ticks: int = 0
    safety_braked_ticks: int = 0
    max_components: int | None = None  # the most groups the sensing graph split into (when tallied)
    observed_dropout: float | None = None  # through the simulated faulty channel
    observed_latency_ms: float | None = None
    groups: tuple[dict, ...] = ()  # a mixed swarm's groups (zswarm.swarm.metrics.GroupTally)

    def to_dict(self) -> dict:
        out = asdict(self)
        out["groups"] = list(self.groups)
        return out


class OutcomeTally:
    """The per-run outcome of B runs of N agents, folded step by step."""

    def __init__(self, b: int, n: int, dt: float, capture_radius: np.ndarray, robot_radius: np.ndarray,
                 components: bool = False, scenarios: list | None = None) -> None:
        """``components``: tally the groups of the sensing graph at every step (an N-node label pass per
        step), not only at the end; ``scenarios`` (one per run): a mixed swarm's groups are tallied too."""
        self.b, self.n, self.dt = b, n, dt
        self.components = np.zeros(b, dtype=np.int64) if components else None
        self.group, self.group_names, self.groups = None, None, None
        if scenarios is not None and any(len(s.members()) > 1 for s in scenarios):
            ids = np.arange(n)
            self.group = np.stack([s.group_of(ids) for s in scenarios])
            self.group_names = [[metrics.group_names(ids[self.group[r] == g], choice, body)
                                 if (self.group[r] == g).any() else None for g, (choice, body) in enumerate(s.groups())]
                                if len(s.members()) > 1 else [] for r, s in enumerate(scenarios)]
            self.groups = metrics.GroupTally(b, max(len(s.groups()) for s in scenarios))
        self.capture_radius = np.asarray(capture_radius, dtype=float)
        self.robot = np.asarray(robot_radius, dtype=float)
        self.capture_step = np.full(b, -1)
        self.min_pair = np.full(b, np.inf)
        self.min_clearance = np.full(b, np.inf)
        self.collisions = np.zeros(b, dtype=np.int64)
        self.contacts = np.zeros(b, dtype=np.int64)
        self.close, self.touch = metrics.Onsets(), metrics.Onsets()
        self.centroid_distance = np.zeros(b)
        self.last: Sensed | None = None

    def observe(self, step: int, positions: np.ndarray, prey: np.ndarray, s: Sensed) -> None:
        self.last = s
        self.centroid_distance = metrics.centroid_goal_distance(positions, prey)
        now = (self.capture_step < 0) & metrics.caught(self.centroid_distance, self.capture_radius)
        self.capture_step[now] = step
        np.minimum.at(self.min_pair, s.run, s.distance)
        np.minimum.at(self.min_clearance, s.obstacle_run, s.clearance)
        close = metrics.too_close(s.distance, self.robot[s.run])
        fresh = self.close.fresh(metrics.pair_keys((s.run * self.n + s.i)[close], s.j[close]))
        self.collisions += np.bincount(s.run[close][fresh], minlength=self.b)
        if self.groups is not None:
            self.groups.observe(self.group, s.run, s.i, s.j, s.distance,
                                np.linalg.norm(positions - prey[:, None, :], axis=-1))
            self.groups.collided(self.group, s.run[close][fresh], s.i[close][fresh], s.j[close][fresh])
        if self.components is not None:
            np.maximum(self.components, self._groups_now(s), out=self.components)
        touch = metrics.touching(s.clearance, self.robot[s.obstacle_run])
        fresh = self.touch.fresh(metrics.pair_keys((s.obstacle_run * self.n + s.agent)[touch], s.obstacle[touch]))
        self.contacts += np.bincount(s.obstacle_run[touch][fresh], minlength=self.b)

    def _groups_now(self, s: Sensed) -> np.ndarray:
        """(B,): the groups of each run's sensing graph now."""
        n = self.n
        labels = metrics.components(self.b * n, np.concatenate([s.run * n + s.i, s.run * n + s.j]),
                                    np.concatenate([s.run * n + s.j, s.run * n + s.i]))
        first = labels == np.arange(self.b * n)  # each group's smallest node labels it
        return np.bincount(np.arange(self.b * n)[first] // n, minlength=self.b)

    @property
    def collided(self) -> bool:
        return bool(self.collisions.any())

    def final_shape(self) -> tuple[list[int], list[float | None]]:
        """Groups of the sensing graph and median nearest-neighbour distance of each run, at the last
        observed step."""
        s, n = self.last, self.n
        node_i, node_j = s.run * n + s.i, s.run * n + s.j
        labels = metrics.components(self.b * n, np.concatenate([node_i, node_j]), np.concatenate([node_j, node_i]))
        nearest = np.full(self.b * n, np.inf)
        np.minimum.at(nearest, node_i, s.distance)
        np.minimum.at(nearest, node_j, s.distance)
        groups, medians = [], []
        for r in range(self.b):
            groups.append(len(np.unique(labels[r * n:(r + 1) * n])))
            median = metrics.median_nearest(nearest[r * n:(r + 1) * n])
            medians.append(None if math.isnan(median) else median)
        return groups, medians

    def outcomes(self, safety_counts: np.ndarray, channel: Any = None, faulty: np.ndarray | None = None) -> list[Outcome]:
        """Each run's outcome; ``channel`` (a :class:`zswarm.sim.batch_channel.BatchChannel` of the runs
        ``faulty``): what it observed of each of them."""
        groups, nearest = self.final_shape()
        seen: dict[int, tuple[float | None, float | None]] = {}
        if channel is not None:
            seen = {int(r): (channel.observed_dropout(k), channel.observed_latency_ms(k)) for k, r in enumerate(faulty)}
        return [Outcome(
            capture_time=None if s < 0 else float(s * self.dt), min_pair_distance=float(self.min_pair[r]),
            collisions=int(self.collisions[r]),
            min_obstacle_clearance=float(self.min_clearance[r]) if math.isfinite(self.min_clearance[r]) else None,
            obstacle_collisions=int(self.contacts[r]),
            final_centroid_goal_distance=float(self.centroid_distance[r]),
            final_components=groups[r], final_median_nearest=nearest[r],
            safety_interventions=int(safety_counts[r, 0]), safety_stalled_ticks=int(safety_counts[r, 1]),
            safety_braked_ticks=int(safety_counts[r, 2]),
            max_components=None if self.components is None else int(self.components[r]),
            observed_dropout=seen.get(r, (None, None))[0], observed_latency_ms=seen.get(r, (None, None))[1],
            groups=() if self.groups is None else tuple(self.groups.result(r, self.group_names[r])))
            for r, s in enumerate(self.capture_step)]


def drive(engine: Engine, steps: int, tally: OutcomeTally | None = None, stop_at_collision: bool = False,
          watch: Callable[[int, Stepped], None] | None = None) -> None:
    """The one step loop of every simulation: at each step k = 0..steps, the tally of the positions,
    every agent's step from what it senses, ``watch(k, stepped)`` (a recording, the trajectories), then
    (k < steps) the move. ``stop_at_collision``: end at the first step any run collides (a study that
    only asks whether a set collides need not simulate a crushed swarm to its end). Without a watcher,
    the last step's commands, which move nothing, are not computed."""
    for k in range(steps + 1):
        if tally is not None:
            tally.observe(engine.step_index, engine.positions, engine.prey, engine.sensed())
            if stop_at_collision and tally.collided:
                return
        if k == steps and watch is None:
            return
        stepped = engine.command()
        if watch is not None:
            watch(k, stepped)
        if k < steps:
            engine.advance(stepped)


class SafetyTally:
    """What the safety filter did over one run, step by step (the counts every engine reports):

    - ``safety_interventions``: agent-steps (ticks) whose command the filter changed;
    - ``safety_stalled_ticks``: agent-steps it left under a tenth of the law's speed (a deadlock shows as a
      run of these), ``safety_stalled_agents`` the agents stalled for at least a second in a row at some
      point, ``safety_stalled_at_end`` those stalled at the last step;
    - ``safety_braked_ticks``: agent-steps stopped because a neighbour's data was older than the bound.

    An agent process counts the same per tick (``agents.counters``); the world sums them."""

    def __init__(self, dt: float = 0.05) -> None:
        self.steps = 0
        self.interventions = self.stalled_steps = self.braked_steps = 0
        self.stalled_now = np.zeros(0, dtype=bool)
        self.run = np.zeros(0, dtype=np.int64)
        self.long = np.zeros(0, dtype=bool)
        self.second = max(int(round(1.0 / dt)), 1)

    def add(self, f: sf.Filtered) -> None:
        if len(self.run) != len(f.acted):
            self.run = np.zeros(len(f.acted), dtype=np.int64)
            self.long = np.zeros(len(f.acted), dtype=bool)
        self.steps += 1
        self.interventions += int(f.acted.sum())
        self.stalled_steps += int(f.stalled.sum())
        self.braked_steps += int(f.braked.sum())
        self.run = np.where(f.stalled, self.run + 1, 0)
        self.long |= self.run >= self.second
        self.stalled_now = f.stalled

    def result(self) -> dict[str, Any]:
        if self.steps == 0:
            return {}
        return {"safety_interventions": self.interventions, "safety_stalled_ticks": self.stalled_steps,
                "safety_stalled_at_end": int(self.stalled_now.sum()), "safety_stalled_agents": int(self.long.sum()),
                "safety_braked_ticks": self.braked_steps}
