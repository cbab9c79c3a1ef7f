"""Rerun logging of a swarm run: used by the simulator and by the world process.

One batched entity per kind (the viewer slows down with hundreds of entities): all agents are one
``Points2D``, all velocities one ``Arrows2D``. Positions are also logged as float64 ``AnyValues``
(``Points2D`` stores float32), so that metrics can be recomputed exactly from a recording.
"""

from __future__ import annotations

import json
from typing import Any, Final, Iterable

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

MAP: Final = "map"
AGENTS: Final = "map/agents"
VELOCITIES: Final = "map/velocities"
SENSING: Final = "map/sensing"
OBSTACLES: Final = "map/obstacles"
PREY: Final = "map/prey"
PREY_TRAIL: Final = "map/prey_trail"
STATE: Final = "state/agents"  # float64 x, y, vx, vy, id per agent
PREY_STATE: Final = "state/prey"
METRICS: Final = "metrics"
CONFIG: Final = "run/config"
SUMMARY: Final = "run/summary"
TIMELINE: Final = "sim_time"

PLOTS = (("distance to prey", ("mean_goal_distance", "centroid_goal_distance")),
         ("safety", ("min_pair_distance", "min_obstacle_clearance")),
         ("cohesion and components", ("cohesion", "components")),
         ("order and union", ("order", "union")),
         ("energy (Lyapunov trace)", ("energy",)))


def blueprint(extra_plots: Iterable[tuple[str, tuple[str, ...]]] = ()) -> rrb.Blueprint:
    plots = [rrb.TimeSeriesView(name=title, origin=METRICS,
                                contents=[f"{METRICS}/{name}" for name in names])
             for title, names in (*PLOTS, *extra_plots)]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin=MAP, name="swarm"),
            rrb.Vertical(*plots),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(expanded=False),
        collapse_panels=True,
    )


def log_config(rec: rr.RecordingStream, config: dict[str, Any]) -> None:
    """What the run was asked to do (scenario, parameters, seed, versions), as static data."""
    text = json.dumps(config, indent=2, sort_keys=True, default=str)
    rec.log(CONFIG, rr.TextDocument(f"```json\n{text}\n```", media_type=rr.MediaType.MARKDOWN),
            rr.AnyValues(config_json=text), static=True)


def log_obstacles(rec: rr.RecordingStream, centers: np.ndarray, radii: np.ndarray) -> None:
    if len(centers):
        rec.log(OBSTACLES, rr.Points2D(centers, radii=np.maximum(radii, 0.03), colors=(150, 150, 150)),
                static=True)


def set_time(rec: rr.RecordingStream, step: int, t: float) -> None:
    rec.set_time("step", sequence=step)
    rec.set_time(TIMELINE, duration=t)


def log_swarm(rec: rr.RecordingStream, t: float, ids: np.ndarray, positions: np.ndarray,
              velocities: np.ndarray, sensing_radius: float | None = None) -> None:
    """Agents (with id labels), their velocity arrows, optional sensing discs and exact float64 state."""
    labels = [str(int(i)) for i in ids]
    rec.log(AGENTS, rr.Points2D(positions, radii=0.05, labels=labels, class_ids=ids,
                                show_labels=len(ids) <= 30))
    rec.log(VELOCITIES, rr.Arrows2D(origins=positions, vectors=velocities))
    if sensing_radius is not None:
        rec.log(SENSING, rr.Points2D(positions, radii=sensing_radius, colors=(120, 160, 255, 25)))
    rec.log(STATE, rr.AnyValues(t=np.array([t], dtype=np.float64), id=np.asarray(ids, dtype=np.int64),
                                x=positions[:, 0].astype(np.float64),
                                y=positions[:, 1].astype(np.float64), vx=velocities[:, 0].astype(np.float64),
                                vy=velocities[:, 1].astype(np.float64)))


def log_prey(rec: rr.RecordingStream, prey: np.ndarray, trail: np.ndarray) -> None:
    rec.log(PREY, rr.Points2D([prey], radii=0.08, colors=(255, 60, 60), labels=["prey"]))
    if len(trail) > 1:
        rec.log(PREY_TRAIL, rr.LineStrips2D([trail], colors=(255, 120, 120)))
    rec.log(PREY_STATE, rr.AnyValues(x=np.array([prey[0]], np.float64), y=np.array([prey[1]], np.float64)))


def log_metrics(rec: rr.RecordingStream, metrics: dict[str, float]) -> None:
    for name, value in metrics.items():
        if np.isfinite(value):
            rec.log(f"{METRICS}/{name}", rr.Scalars(value))


def log_summary(rec: rr.RecordingStream, summary: dict[str, Any]) -> None:
    text = json.dumps(summary, indent=2, sort_keys=True)
    rec.log(SUMMARY, rr.TextDocument(f"```json\n{text}\n```", media_type=rr.MediaType.MARKDOWN),
            rr.AnyValues(summary_json=text), static=True)
