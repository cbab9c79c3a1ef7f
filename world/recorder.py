"""The world's recording: a Rerun file per segment, the optional trajectory file, and recovery of
what a killed predecessor recorded.

A world that replaces one that died (``--resume``) leaves the earlier segments as they are (a killed
writer's file is first given its footer), folds every step they hold into its own observer, and
records the rest of the run into the next segment, ``RUN.segN.rrd``, under the same recording id.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.errors import UsageError
from zswarm.files import write_json
from zswarm.swarm.observer import SwarmObserver

TRAIL = 400  # prey positions drawn behind it
GRAPH_MAX_AGENTS = 100  # the sensing graph is drawn by default up to this N


@dataclass(frozen=True)
class Resumed:
    """Where a restarted world goes on from."""

    segment: int
    step: int  # the last recorded step (-1: nothing was recorded)
    t: float
    prey: np.ndarray | None
    frames_recovered: int

    def to_dict(self) -> dict[str, Any]:
        return {"segment": self.segment, "step": self.step, "t": self.t, "frames_recovered": self.frames_recovered}


class WorldRecorder:
    """Writes what the world observes: the ``.rrd`` (if ``record``), the ``.npz`` trajectory (if
    ``trajectory``) and the summary JSON (if ``summary``)."""

    def __init__(self, record: Path | None, summary: Path | None, trajectory: Path | None, n_agents: int,
                 dt: float, viewer=None, sensing_graph: bool | None = None) -> None:
        self.record_path, self.summary_path, self.trajectory_path = record, summary, trajectory
        self.viewer = viewer  # a zswarm.record.live.Viewer: stream live as well (or instead of a file)
        self.sensing_graph = sensing_graph if sensing_graph is not None else n_agents <= GRAPH_MAX_AGENTS
        self.thresholds: dict[str, float] = {}
        self.graph_radius: float | None = None
        self.n_agents, self.dt = n_agents, dt
        self.rec = None
        self.series = None  # the rows of self.rec's steps (swarm_log.Series), sent as columns every few steps
        self.labels = None  # which agents its map was last labelled for (swarm_log.Labels)
        self.segment = 0
        self.trail: deque[np.ndarray] = deque(maxlen=TRAIL)
        self.traj: list[np.ndarray] = []
        self.traj_prey: list[np.ndarray] = []

    # --- start ----------------------------------------------------------------------------------------

    def recover(self, run: str, observer: SwarmObserver) -> Resumed | None:
        """Read what the previous worlds recorded (every segment; a killed writer's file is repaired
        first), fold it into ``observer`` and say where to go on from. None: nothing to resume."""
        from zswarm.record.replay import fold_frames, load_run, segments
        from zswarm.record.salvage import seal

        if self.record_path is None or not self.record_path.exists():
            return None
        for part in segments(self.record_path):
            if seal(part):
                print(f"world: {part} had no footer (its world was killed); rewritten whole", flush=True)
        prior = load_run(self.record_path, require_states=False)
        if prior.config.get("run") != run:
            raise UsageError(f"--resume: {self.record_path} records run {prior.config.get('run')!r}, not "
                             f"{run!r}; give the same --run or another --record")
        self.segment = len(prior.segments)
        if not prior.frames:  # its predecessor died before its first step: start from the beginning
            return Resumed(self.segment, -1, 0.0, None, 0)
        fold_frames(observer, prior.frames)
        self.trail.extend(f.prey for f in prior.frames[-TRAIL:] if f.prey is not None)
        for f in prior.frames:
            self.keep_trajectory(f.ids, f.positions,
                                 f.prey if f.prey is not None else np.full(f.positions.shape[-1], np.nan))
        last = prior.frames[-1]
        print(f"world: resuming run {run!r} after step {last.step} (t = {last.t:.2f} s) from "
              f"{len(prior.segments)} segment(s); writing segment {self.segment}", flush=True)
        return Resumed(self.segment, last.step, last.t, None if last.prey is None else last.prey.copy(),
                       len(prior.frames))

    @property
    def recording(self) -> bool:
        return self.rec is not None

    def open(self, run: str, config: dict[str, Any], centers: np.ndarray, radii: np.ndarray,
             thresholds: dict[str, float] | None = None, sensing_radius: float | None = None,
             arena: tuple[float, float, float, float] | None = None, dimensions: int = 2) -> None:
        """Open this world's segment and write what never changes; flushed at once, so that a
        successor finds the run's identity even if this world dies at its first step. ``dimensions``
        3: the map is a 3-D view."""
        if self.record_path is None and not (self.viewer is not None and self.viewer.wanted):
            return
        from zswarm.record import swarm_log
        from zswarm.record.recording import open_recording
        from zswarm.record.replay import segment_path

        path = None if self.record_path is None else segment_path(self.record_path, self.segment)
        self.rec = open_recording(path, "zswarm-world", swarm_log.blueprint(network=True, arena=arena, dimensions=dimensions),
                                  recording_id=run, viewer=self.viewer)
        self.thresholds = thresholds or {}
        self.graph_radius = sensing_radius if self.sensing_graph and sensing_radius else None
        swarm_log.log_config(self.rec, config)
        swarm_log.log_obstacles(self.rec, centers, radii)
        swarm_log.log_threshold_styles(self.rec, self.thresholds)
        self.series = swarm_log.Series(self.rec, live=self.viewer is not None and self.viewer.wanted)
        self.labels = swarm_log.Labels()
        self.rec.flush()

    # --- every step -----------------------------------------------------------------------------------

    def log_step(self, step: int, t: float, ids: np.ndarray, pos: np.ndarray, vel: np.ndarray, prey: np.ndarray,
                 metrics: dict[str, float], heading: np.ndarray | None = None,
                 safety: tuple[np.ndarray, float] | None = None, stamps: np.ndarray | None = None) -> None:
        """``safety``: what the filter did to each agent's command (its pose's flag) and the ring radius;
        ``stamps``: when each agent sent the pose it holds (a free clock's snapshot mixes times)."""
        self.keep_trajectory(ids, pos, prey)
        if self.rec is None:
            return
        from zswarm.record import swarm_log

        swarm_log.set_time(self.rec, step, t, self.series)
        if not self.trail or not np.array_equal(prey, self.trail[-1]):  # a goal that stays draws no trail
            self.trail.append(prey.copy())
        swarm_log.log_swarm(self.series, t, ids, pos, vel, headings=heading, stamps=stamps, labels=self.labels)
        if safety is not None:
            swarm_log.log_safety(self.series, pos, *safety)
        swarm_log.log_prey(self.series, prey, np.array(self.trail))
        swarm_log.log_metrics(self.series, metrics, self.thresholds)
        if self.graph_radius is not None:
            swarm_log.log_sensing_graph(self.series, pos, self.graph_radius)

    def log_network(self, step: int, t: float, figures: dict[str, float | None]) -> None:
        if self.rec is None:
            return
        from zswarm.record import swarm_log

        swarm_log.set_time(self.rec, step, t)
        swarm_log.log_network(self.rec, figures)

    def log_event(self, step: int, t: float, text: str) -> None:
        if self.rec is None:
            return
        import rerun as rr

        from zswarm.record import swarm_log

        swarm_log.set_time(self.rec, step, t)
        self.rec.log("run/events", rr.TextLog(text))

    def keep_trajectory(self, ids: np.ndarray, pos: np.ndarray, prey: np.ndarray) -> None:
        """One row of the trajectory file: positions by agent id (NaN for the absent)."""
        if self.trajectory_path is None:
            return
        full = np.full((self.n_agents, pos.shape[-1]), np.nan)
        inside = ids < self.n_agents
        full[ids[inside]] = pos[inside]
        self.traj.append(full)
        self.traj_prey.append(prey.copy())

    # --- end ------------------------------------------------------------------------------------------

    def close(self, result: dict[str, Any]) -> None:
        """Store the summary in the recording and beside it, close the recording, save the trajectory."""
        if self.rec is not None:
            from zswarm.record import swarm_log
            from zswarm.record.recording import close_recording

            self.series.flush()
            swarm_log.log_summary(self.rec, result)
            close_recording(self.rec)
        if self.trajectory_path is not None and self.traj:
            np.savez(self.trajectory_path, positions=np.array(self.traj), prey=np.array(self.traj_prey), dt=self.dt)
        if self.summary_path is not None:
            write_json(self.summary_path, result)
