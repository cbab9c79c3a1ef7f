"""Swarm metrics, per step (:func:`step_metrics`) and summarized (:class:`Summary`, the keys of
``zswarm sim --json``): the same code for the simulator, the world and replay. What each one
measures: docs/simulation.md."""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zswarm.paper.neighbours import ObstacleIndex, obstacle_clearance, pairs_within

FIEDLER_MAX_N = 400


@dataclass(frozen=True)
class MetricContext:
    robot_radius: float
    sensing_radius: float
    spacing: float | None  # the design's d^f
    obstacles: ObstacleIndex


def components(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Component label of every node (the smallest index in its component); vectorized."""
    labels = np.arange(n)
    while True:
        new = labels.copy()
        np.minimum.at(new, i, labels[j])
        new = new[new]
        if np.array_equal(new, labels):
            return labels
        labels = new


def algebraic_connectivity(n: int, i: np.ndarray, j: np.ndarray, n_components: int | None = None) -> float:
    """The Fiedler value lambda_2 of the sensing graph's Laplacian. It is 0 exactly when the graph is
    disconnected, so with ``n_components`` > 1 known no O(N^3) eigensolve is done."""
    if n < 2 or n > FIEDLER_MAX_N:
        return math.nan
    if n_components is not None and n_components > 1:
        return 0.0
    lap = np.zeros((n, n))
    lap[i, j] = -1.0
    np.fill_diagonal(lap, -lap.sum(axis=1))
    return float(np.linalg.eigvalsh(lap)[1])


# -- each metric's definition, once: vectorized over any leading axes (a run, or a batch of runs); the
# per-step metrics below and the batched simulator's tally (zswarm.sim.batch) both use these


def centroid_goal_distance(positions: np.ndarray, prey: np.ndarray) -> np.ndarray:
    """|centroid - prey| of each run: positions (..., N, D), prey (..., D) -> (...)."""
    return np.linalg.norm(positions.mean(axis=-2) - prey, axis=-1)


def caught(centroid_distance: np.ndarray | float, capture_radius: np.ndarray | float) -> np.ndarray:
    """The prey is caught when the swarm's centroid is within the capture radius of it."""
    return np.asarray(centroid_distance) <= capture_radius


def too_close(distance: np.ndarray, robot_radius: np.ndarray | float) -> np.ndarray:
    """A collision: two bodies of radius d^r closer than 2 d^r (counted on pairs of the sensing graph)."""
    return distance < 2.0 * np.asarray(robot_radius)


def touching(clearance: np.ndarray, robot_radius: np.ndarray | float) -> np.ndarray:
    """An obstacle contact: the clearance below the robot's radius."""
    return clearance < np.asarray(robot_radius)


def pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One int64 key per pair (a, b) of non-negative integers below 2^31 (agent ids, obstacle indices)."""
    return (np.asarray(a, dtype=np.int64) << 32) | np.asarray(b, dtype=np.int64)


class Onsets:
    """Contacts counted as onsets: a pair (two agents, or an agent and an obstacle) counts when it is in
    contact now and was not at the previous observation. The one rule of every collision count."""

    def __init__(self) -> None:
        self.was = np.empty(0, dtype=np.int64)

    def fresh(self, keys: np.ndarray) -> np.ndarray:
        """Which of this observation's contacts (:func:`pair_keys`) began since the last one."""
        keys = np.asarray(keys, dtype=np.int64)
        out = ~np.isin(keys, self.was) if len(keys) and len(self.was) else np.ones(len(keys), dtype=bool)
        self.was = keys
        return out

    def count(self, pairs: np.ndarray) -> int:
        """How many of this observation's contacts, rows (a, b) of ``pairs``, began since the last one."""
        if not len(pairs):  # most steps: nobody in contact (nothing to look up)
            self.was = self.was[:0]
            return 0
        pairs = np.asarray(pairs)
        return int(self.fresh(pair_keys(pairs[:, 0], pairs[:, 1])).sum())


def group_names(ids: np.ndarray, choice: Any, body: str) -> dict[str, Any]:
    """How a summary names a group: its agents (a range of ids), its law and its body."""
    ids = np.asarray(ids)
    return {"agents": f"{ids.min()}-{ids.max()}" if len(ids) > 1 else str(ids[0]), "count": int(len(ids)),
            "law": choice.law, "body": body}


class GroupTally:
    """Each group of a mixed swarm, B runs, folded step by step: its collisions (onsets of pairs with a
    member: a pair of two groups counts for both), its closest pair with a member and, at the last step
    observed, its members' mean distance to the goal."""

    def __init__(self, b: int, groups: int) -> None:
        self.b, self.g = b, groups
        self.collisions = np.zeros((b, groups), dtype=np.int64)
        self.min_pair = np.full((b, groups), np.inf)
        self.goal = np.full((b, groups), np.nan)

    def collided(self, group: np.ndarray, run: np.ndarray, i: np.ndarray, j: np.ndarray) -> None:
        """The pairs (run, i, j) that began colliding now; ``group`` (B, N): each agent's group."""
        gi, gj = group[run, i], group[run, j]
        np.add.at(self.collisions, (run, gi), 1)
        other = gi != gj
        np.add.at(self.collisions, (run[other], gj[other]), 1)

    def observe(self, group: np.ndarray, run: np.ndarray, i: np.ndarray, j: np.ndarray, distance: np.ndarray,
                to_goal: np.ndarray) -> None:
        """One step: ``group`` (B, N) each agent's group; the pairs (run, i, j) of the sensing graph with
        their ``distance`` (each pair once); ``to_goal`` (B, N) each agent's distance to the goal."""
        gi, gj = group[run, i], group[run, j]
        np.minimum.at(self.min_pair, (run, gi), distance)
        np.minimum.at(self.min_pair, (run, gj), distance)
        flat = (np.arange(self.b)[:, None] * self.g + group).ravel()
        total = np.bincount(flat, weights=to_goal.ravel(), minlength=self.b * self.g)
        count = np.bincount(flat, minlength=self.b * self.g)
        self.goal = np.divide(total, count, out=np.full(len(total), np.nan), where=count > 0).reshape(self.b, self.g)

    def result(self, r: int, names: list[dict[str, Any]]) -> list[dict[str, Any]]:
        """Run r's groups: each one's ``names`` entry (who, which law and body; None: a group without
        agents, left out) with its outcome."""
        return [{**name, "collisions": int(self.collisions[r, g]), "min_pair_distance": _num(self.min_pair[r, g]),
                 "final_mean_goal_distance": _num(self.goal[r, g])} for g, name in enumerate(names) if name is not None]


def median_nearest(nearest: np.ndarray) -> float:
    """The median nearest-neighbour distance over the agents that have one within R (inf: none); NaN
    when no agent has one."""
    has = np.isfinite(nearest)
    return float(np.median(nearest[has])) if has.any() else math.nan


def _min_pair_distance(positions: np.ndarray, i: np.ndarray, j: np.ndarray) -> float:
    if len(i):
        d = positions[i] - positions[j]
        return float(np.sqrt(np.einsum("ij,ij->i", d, d).min()))
    n = len(positions)
    if n < 2:
        return math.inf
    best = math.inf
    for start in range(0, n, 512):  # nobody within the sensing radius: exact, chunked brute force
        d = np.linalg.norm(positions[start:start + 512, None] - positions[None], axis=-1)
        d[np.arange(len(d)), np.arange(start, start + len(d))] = np.inf
        best = min(best, float(d.min()))
    return best


def step_metrics(positions: np.ndarray, velocities: np.ndarray, prey: np.ndarray, ctx: MetricContext,
                 energy: float = math.nan, pairs: tuple[np.ndarray, np.ndarray] | None = None,
                 ) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
    """Metrics of one step, plus the colliding agent pairs (i < j) and agent-obstacle contacts.
    ``pairs``: ``pairs_within(positions, ctx.sensing_radius)``, when the caller has it already."""
    n = len(positions)
    i, j = pairs if pairs is not None else pairs_within(positions, ctx.sensing_radius)
    centroid = positions.mean(axis=0)
    to_goal = np.linalg.norm(positions - prey, axis=1)
    labels = components(n, i, j)
    n_comp = len(np.unique(labels))
    d_ij = np.linalg.norm(positions[i] - positions[j], axis=1)
    close = too_close(d_ij, ctx.robot_radius) & (i < j)
    colliding = np.stack([i[close], j[close]], axis=1)

    a, m = ctx.obstacles.sensed(positions)
    clearance = obstacle_clearance(positions[a], ctx.obstacles.centers[m], ctx.obstacles.radii[m])
    touch = touching(clearance, ctx.robot_radius)
    contacts = np.stack([a[touch], m[touch]], axis=1)

    spacing_error = nearest_median = math.nan
    if len(i):
        nearest = np.full(n, np.inf)
        np.minimum.at(nearest, i, d_ij)
        has = np.isfinite(nearest)
        nearest_median = median_nearest(nearest)
        if ctx.spacing is not None:
            spacing_error = float(np.mean(np.abs(nearest[has] - ctx.spacing)))
    speed = np.linalg.norm(velocities, axis=1).sum()
    out = {
        "mean_goal_distance": float(to_goal.mean()),
        "centroid_goal_distance": float(centroid_goal_distance(positions, prey)),
        "min_pair_distance": float(d_ij.min()) if len(i) else _min_pair_distance(positions, i, j),
        "colliding_pairs": float(len(colliding)),
        "min_obstacle_clearance": float(clearance.min()) if len(clearance) else math.inf,
        "obstacle_contacts": float(len(contacts)),
        "cohesion": float(np.linalg.norm(positions - centroid, axis=1).max()),
        "components": float(n_comp),
        "union": (n - n_comp) / (n - 1) if n > 1 else 1.0,
        "algebraic_connectivity": algebraic_connectivity(n, i, j, n_comp),
        "spacing_error": spacing_error,
        "median_nearest": nearest_median,
        "order": float(np.linalg.norm(velocities.sum(axis=0)) / speed) if speed > 0 else 0.0,
        "energy": float(energy),
    }
    return out, colliding, contacts


METRIC_NAMES = ("mean_goal_distance", "centroid_goal_distance", "min_pair_distance", "colliding_pairs",
                "min_obstacle_clearance", "obstacle_contacts", "cohesion", "components", "union",
                "algebraic_connectivity", "spacing_error", "median_nearest", "order", "energy")


@dataclass
class Summary:
    """Folds per-step metrics into a run summary; collision counts are onsets (a pair entering contact)."""

    capture_radius: float
    epsilon: float
    # float64 arrays, not lists of Python floats: 8 bytes a value, so hours of steps stay small
    times: array = field(default_factory=lambda: array("d"))
    series: dict[str, array] = field(default_factory=lambda: {k: array("d") for k in METRIC_NAMES})
    collisions: int = 0
    obstacle_collisions: int = 0
    groups: list[dict[str, Any]] | None = None  # a mixed swarm's groups (who, law, body) and their tally
    group_tally: GroupTally | None = None
    _pairs: Onsets = field(default_factory=Onsets)
    _contacts: Onsets = field(default_factory=Onsets)

    def add(self, t: float, metrics: dict[str, float], colliding: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """One step; returns which ``colliding`` pairs began colliding now."""
        self.times.append(float(t))
        for k in METRIC_NAMES:
            self.series[k].append(metrics[k])
        if len(colliding):
            fresh = self._pairs.fresh(pair_keys(colliding[:, 0], colliding[:, 1]))
        else:
            self._pairs.count(colliding)
            fresh = np.zeros(0, dtype=bool)
        self.collisions += int(fresh.sum())
        self.obstacle_collisions += self._contacts.count(contacts)
        return fresh

    def capture_time(self) -> float | None:
        d = np.asarray(self.series["centroid_goal_distance"])
        hit = np.flatnonzero(caught(d, self.capture_radius))
        return self.times[int(hit[0])] if len(hit) else None

    def result(self) -> dict[str, Any]:
        """The summary keys; a run that observed no step (no agent ever showed up) has no values."""
        if not self.times:
            return {**{k: None for k in SUMMARY_KEYS}, "collisions": 0, "obstacle_collisions": 0,
                    "epsilon": _num(self.epsilon), "steps_observed": 0}
        s = {k: np.asarray(v, dtype=float) for k, v in self.series.items()}
        capture = self.capture_time()
        comps = s["components"]
        joined = np.flatnonzero(comps == 1)
        split_after_joined = int(np.max(comps[joined[0]:])) if len(joined) else None
        lag = None
        if capture is not None:
            after = np.asarray(self.times) >= capture
            lag = _num(np.max(s["centroid_goal_distance"][after]))
        return {
            "final_mean_goal_distance": _num(s["mean_goal_distance"][-1]),
            "final_centroid_goal_distance": _num(s["centroid_goal_distance"][-1]),
            "capture_time": capture,
            "max_lag_after_capture": lag,
            "min_pair_distance": _num(np.min(s["min_pair_distance"])),
            "collisions": self.collisions,
            "min_obstacle_clearance": _num(np.min(s["min_obstacle_clearance"])),
            "obstacle_collisions": self.obstacle_collisions,
            "max_components": int(np.max(s["components"])),
            "max_components_after_joined": split_after_joined,
            "final_components": int(s["components"][-1]),
            "max_cohesion": _num(np.max(s["cohesion"])),
            "final_cohesion": _num(s["cohesion"][-1]),
            "epsilon": _num(self.epsilon),
            "final_union": _num(s["union"][-1]),
            "final_algebraic_connectivity": _num(s["algebraic_connectivity"][-1]),
            "final_spacing_error": _num(s["spacing_error"][-1]),
            "final_median_nearest": _num(s["median_nearest"][-1]),
            "final_order": _num(s["order"][-1]),
            "final_energy": _num(s["energy"][-1]),
            "steps_observed": len(self.times),
            **({"groups": self.group_tally.result(0, self.groups)} if self.group_tally is not None else {}),
        }


SUMMARY_KEYS = ("final_mean_goal_distance", "final_centroid_goal_distance", "capture_time", "max_lag_after_capture",
                "min_pair_distance", "collisions", "min_obstacle_clearance", "obstacle_collisions", "max_components",
                "max_components_after_joined", "final_components", "max_cohesion", "final_cohesion", "epsilon",
                "final_union", "final_algebraic_connectivity", "final_spacing_error", "final_median_nearest", "final_order",
                "final_energy")


def _num(x: float) -> float | None:
    """JSON-safe float: NaN and infinities (e.g. no obstacle ever sensed) become null."""
    x = float(x)
    return x if math.isfinite(x) else None
