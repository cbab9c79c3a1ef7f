"""Reading a run back from its ``.rrd`` with rerun-sdk's own reader.

The simulator and the world log exact float64 agent states (``state/agents``: id, x, y, vx, vy per
step), the prey (``state/prey``), what the run was asked to do (``run/config``) and its summary
(``run/summary``). :func:`load_run` returns them in step order.

A world that was restarted mid-run (``--resume``) leaves its first recording untouched and writes
the rest into segments beside it: ``run.rrd``, ``run.seg1.rrd``, ``run.seg2.rrd``...
:func:`load_run` reads them all as one run (open them together in the viewer: ``rerun run*.rrd``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.errors import UsageError
from zswarm.swarm.observer import SwarmObserver
from zswarm.swarm.scenarios import Scenario
from zswarm.record.swarm_log import CONFIG, PREY_STATE, STATE, SUMMARY


@dataclass
class Frame:
    step: int
    t: float
    ids: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    prey: np.ndarray | None
    headings: np.ndarray | None = None  # radians, NaN where none; None: no agent had a heading
    stamps: np.ndarray | None = None  # a world's frame: when each agent sent the pose it held (wall s)


@dataclass
class RunRecord:
    config: dict[str, Any]
    summary: dict[str, Any] | None
    frames: list[Frame]
    segments: tuple[Path, ...] = ()


def segment_path(path: Path, k: int) -> Path:
    """Segment ``k`` of the recording ``path`` (0 is ``path`` itself)."""
    path = Path(path)
    return path if k == 0 else path.with_name(f"{path.stem}.seg{k}{path.suffix}")


def segments(path: Path) -> list[Path]:
    """``path`` and the segments a restarted world wrote after it, in order."""
    out, k = [], 0
    while segment_path(path, k).is_file():
        out.append(segment_path(path, k))
        k += 1
    return out


def _seconds(column: Any) -> np.ndarray:
    """A duration column (nanoseconds) as float seconds."""
    return np.asarray(column.to_numpy(zero_copy_only=False)).astype("timedelta64[ns]").astype(np.int64) / 1e9


def load_run(path: Path, require_states: bool = True) -> RunRecord:
    """A run from ``path`` and its segments: the first segment's configuration, the last summary
    stored, and every step (a later segment wins where two hold the same step). A zswarm recording
    with no step yet (its world died at once) is an error unless ``require_states`` is off."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"recording {path} is a directory; give a .rrd file")
    if not path.is_file():
        raise UsageError(f"recording {path} does not exist")
    paths = segments(path)
    parts = [load_segment(p) for p in paths]
    config = parts[0].config
    for p, part in zip(paths[1:], parts[1:]):
        if part.config.get("run") != config.get("run"):
            raise UsageError(f"{p} belongs to run {part.config.get('run')!r}, not {config.get('run')!r}; "
                             f"move it away from {path}")
    by_step = {f.step: f for part in parts for f in part.frames}
    if not by_step and require_states:
        raise UsageError(f"{path} holds no agent states (its world stopped before the first step?)")
    summary = next((part.summary for part in reversed(parts) if part.summary is not None), None)
    return RunRecord(config, summary, [by_step[k] for k in sorted(by_step)], tuple(paths))


def fold_frames(observer: SwarmObserver, frames: list[Frame]) -> None:
    """Observe every recorded frame (replay, and a restarted world recovering what its predecessor
    observed): the summary is the one the live observer would have made."""
    for f in frames:
        if f.prey is None or len(f.ids) == 0:
            continue
        observer.observe(f.t, f.ids, f.positions, f.velocities, f.prey)


def scenario_of(run: RunRecord) -> Scenario:
    """The scenario a recording was made with (its ``run/config`` stores the full definition)."""
    d = run.config.get("scenario_definition")
    if not d:
        raise UsageError("the recording has no scenario definition in run/config (recorded by an older zswarm?)")
    return Scenario.from_dict(d)


def observer_of(run: RunRecord) -> SwarmObserver:
    """A fresh observer of the recorded run's scenario and potential."""
    scenario = scenario_of(run)
    return SwarmObserver(scenario, run.config.get("potential", scenario.combination))


def recompute(run: RunRecord) -> dict[str, Any]:
    """The run's summary metrics recomputed from its recorded states."""
    observer = observer_of(run)
    fold_frames(observer, run.frames)
    return observer.summary.result()


def _axes(rb: Any, row: int) -> tuple[str, ...]:
    """The coordinates a state row holds: x, y, and z in a 3-D run."""
    return ("x", "y", "z") if "z" in rb.schema.names and rb.column("z")[row].as_py() is not None else ("x", "y")


def load_segment(path: Path) -> RunRecord:
    import warnings

    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # a file whose writer was killed has no footer: scanned whole
            warnings.simplefilter("ignore")
            chunks = RrdReader(str(path)).stream().to_chunks()
    except Exception as exc:
        raise UsageError(f"cannot read {path} as a Rerun recording: {str(exc).splitlines()[0]}") from None
    config: dict[str, Any] = {}
    summary = None
    states: dict[int, tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]] = {}
    prey: dict[int, np.ndarray] = {}
    for chunk in chunks:
        entity = str(chunk.entity_path).lstrip("/")
        if entity not in (STATE, PREY_STATE, CONFIG, SUMMARY):
            continue
        rb = chunk.to_record_batch()
        cols = rb.schema.names
        if entity == CONFIG and "config_json" in cols:
            config = json.loads(rb.column("config_json")[0].as_py()[0])
        elif entity == SUMMARY and "summary_json" in cols:
            summary = json.loads(rb.column("summary_json")[0].as_py()[0])
        elif entity == STATE:
            times = _seconds(rb.column("sim_time"))
            for row in range(rb.num_rows):
                step = int(rb.column("step")[row].as_py())
                t = float(rb.column("t")[row].as_py()[0]) if "t" in cols else float(times[row])
                ids = np.asarray(rb.column("id")[row].as_py(), dtype=np.int64)
                axes = _axes(rb, row)
                xy = np.column_stack([rb.column(a)[row].as_py() for a in axes])
                vel = np.column_stack([rb.column(f"v{a}")[row].as_py() for a in axes])
                heading = (np.asarray(rb.column("heading")[row].as_py(), dtype=float)
                           if "heading" in cols and rb.column("heading")[row].as_py() is not None else None)
                stamps = (np.asarray(rb.column("stamp")[row].as_py(), dtype=float)
                          if "stamp" in cols and rb.column("stamp")[row].as_py() is not None else None)
                states[step] = (t, ids, xy.reshape(-1, len(axes)), vel.reshape(-1, len(axes)), heading, stamps)
        elif entity == PREY_STATE:
            for row in range(rb.num_rows):
                step = int(rb.column("step")[row].as_py())
                prey[step] = np.array([rb.column(a)[row].as_py()[0] for a in _axes(rb, row)])
    if not states and not config:
        raise UsageError(f"{path} holds no agent states (is it a zswarm run recording?)")
    frames = [Frame(step, t, ids, xy, vel, prey.get(step), heading, stamps)
              for step, (t, ids, xy, vel, heading, stamps) in sorted(states.items())]
    return RunRecord(config=config, summary=summary, frames=frames)
