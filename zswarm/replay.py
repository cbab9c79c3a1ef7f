"""Reading a run back from its ``.rrd`` with rerun-sdk's own reader.

The simulator and the world log exact float64 agent states (``state/agents``: id, x, y, vx, vy per
step), the prey (``state/prey``), what the run was asked to do (``run/config``) and its summary
(``run/summary``). :func:`load_run` returns them in step order.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.cli_util import UsageError
from zswarm.swarm_log import CONFIG, PREY_STATE, STATE, SUMMARY


@dataclass
class Frame:
    step: int
    t: float
    ids: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    prey: np.ndarray | None


@dataclass
class RunRecord:
    config: dict[str, Any]
    summary: dict[str, Any] | None
    frames: list[Frame]


def _seconds(column: Any) -> np.ndarray:
    """A duration column (nanoseconds) as float seconds."""
    return np.asarray(column.to_numpy(zero_copy_only=False)).astype("timedelta64[ns]").astype(np.int64) / 1e9


def load_run(path: Path) -> RunRecord:
    from rerun.chunk import RrdReader

    path = Path(path)
    if not path.is_file():
        raise UsageError(f"recording {path} does not exist")
    try:
        chunks = RrdReader(str(path)).stream().to_chunks()
    except Exception as exc:
        raise UsageError(f"cannot read {path} as a Rerun recording: {str(exc).splitlines()[0]}") from None
    config: dict[str, Any] = {}
    summary = None
    states: dict[int, tuple[float, np.ndarray, np.ndarray, np.ndarray]] = {}
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
                xy = np.column_stack([rb.column("x")[row].as_py(), rb.column("y")[row].as_py()])
                vel = np.column_stack([rb.column("vx")[row].as_py(), rb.column("vy")[row].as_py()])
                states[step] = (t, ids, xy.reshape(-1, 2), vel.reshape(-1, 2))
        elif entity == PREY_STATE:
            for row in range(rb.num_rows):
                step = int(rb.column("step")[row].as_py())
                prey[step] = np.array([rb.column("x")[row].as_py()[0], rb.column("y")[row].as_py()[0]])
    if not states:
        raise UsageError(f"{path} holds no agent states (is it a zswarm run recording?)")
    frames = [Frame(step, t, ids, xy, vel, prey.get(step)) for step, (t, ids, xy, vel) in sorted(states.items())]
    return RunRecord(config=config, summary=summary, frames=frames)
