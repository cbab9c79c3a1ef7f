"""A tune's search history as a Rerun recording: the objective and every parameter's path.

One timeline, ``candidate``: the n-th candidate judged. ``design/violation`` is how far it fails the
design checks (0: it passes); ``search/objective`` is the objective of those that were simulated (the
disqualified ones are left out: they would flatten the plot), ``search/best`` the best so far, and
``params/<name>`` their ln(value / start), so every parameter's path fits one plot with 0 at the
start. The text panel holds the outcome (the chosen set, the held-out comparison) and the settings.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Final

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from zswarm.record.recording import close_recording, open_recording

TIMELINE: Final = "candidate"
OBJECTIVE: Final = "search/objective"
BEST: Final = "search/best"
START: Final = "search/start"
PARAMS: Final = "params"
VIOLATION: Final = "design/violation"
REPORT: Final = "report"


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.TimeSeriesView(name="objective (s): candidates, best so far, start set", origin="search"),
                rrb.TimeSeriesView(name="ln(value / start) of each simulated candidate", origin=PARAMS),
                rrb.TimeSeriesView(name="design violation of each candidate (0 = passes)", origin="design"),
            ),
            rrb.TextDocumentView(origin=REPORT, name="tune"),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(expanded=False),
        collapse_panels=True,
    )


def _series(rec: rr.RecordingStream, path: str, at: np.ndarray, values: np.ndarray) -> None:
    if len(at):
        rec.send_columns(path, indexes=[rr.TimeColumn(TIMELINE, sequence=at)],
                         columns=rr.Scalars.columns(scalars=values))


def save_search(path: Path, config: dict[str, Any], records: list[dict[str, Any]], start_values: dict[str, float],
                start_objective: float | None, qualified_below: float, report_md: str = "") -> None:
    """Write the whole search (``records`` in the order judged) to ``path``."""
    rec = open_recording(path, "zswarm-tune", blueprint())
    settings = json.dumps(config, indent=2, sort_keys=True, default=str)
    rec.log(REPORT, rr.TextDocument(f"{report_md}\n\n### settings\n```json\n{settings}\n```",
                                    media_type=rr.MediaType.MARKDOWN), static=True)
    rec.log(OBJECTIVE, rr.SeriesPoints(names="candidate", markers="circle", marker_sizes=2.5), static=True)
    rec.log(BEST, rr.SeriesLines(names="best so far", widths=2.0), static=True)
    rec.log(START, rr.SeriesLines(names="start set", widths=1.0, colors=(150, 150, 150)), static=True)
    rec.log(VIOLATION, rr.SeriesPoints(names="violation", markers="circle", marker_sizes=2.0), static=True)
    index = np.arange(1, len(records) + 1)
    _series(rec, VIOLATION, index, np.array([r["violation"] for r in records], dtype=float))
    simulated = np.array(["objective" in r for r in records], dtype=bool)
    at = index[simulated]
    values = np.array([r["objective"] for r in records if "objective" in r], dtype=float)
    ok = values < qualified_below
    _series(rec, OBJECTIVE, at[ok], values[ok])
    best = np.minimum.accumulate(np.where(ok, values, np.inf)) if len(values) else values
    shown = np.isfinite(best)
    _series(rec, BEST, at[shown], best[shown])
    if start_objective is not None and start_objective < qualified_below and len(at):
        _series(rec, START, at[[0, -1]], np.full(2, start_objective))
    done = [r for r in records if "objective" in r]
    for name, start in start_values.items():
        _series(rec, f"{PARAMS}/{name}", at, np.array([math.log(r["values"][name] / start) for r in done]))
    close_recording(rec)
