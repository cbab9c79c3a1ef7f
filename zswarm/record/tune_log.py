"""A tune's search history as a Rerun recording: the objective and every parameter's path.

Timeline ``evaluation``: the n-th simulated candidate. ``search/objective`` is its objective (the
disqualified ones are left out: they would flatten the plot), ``search/best`` the best so far, and
``params/<name>`` its ln(value / start), so every parameter's path fits one plot with 0 at the start.
Timeline ``candidate`` (every candidate judged): ``design/violation``, 0 for a set that passes.
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

OBJECTIVE: Final = "search/objective"
BEST: Final = "search/best"
START: Final = "search/start"
PARAMS: Final = "params"
VIOLATION: Final = "design/violation"
CONFIG: Final = "config"


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.TimeSeriesView(name="objective (s) per simulated candidate", origin="search"),
                rrb.TimeSeriesView(name="ln(value / start) per simulated candidate", origin=PARAMS),
                rrb.TimeSeriesView(name="design violation per candidate (0 = passes)", origin="design"),
            ),
            rrb.TextDocumentView(origin=CONFIG, name="tune"),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(expanded=False),
        collapse_panels=True,
    )


def save_search(path: Path, config: dict[str, Any], records: list[dict[str, Any]], start_values: dict[str, float],
                start_objective: float | None, qualified_below: float) -> None:
    """Write the whole search (``records`` in the order judged) to ``path``."""
    rec = open_recording(path, "zswarm-tune", blueprint())
    text = json.dumps(config, indent=2, sort_keys=True, default=str)
    rec.log(CONFIG, rr.TextDocument(f"```json\n{text}\n```", media_type=rr.MediaType.MARKDOWN), static=True)
    judged = np.arange(len(records))
    rec.send_columns(VIOLATION, indexes=[rr.TimeColumn("candidate", sequence=judged)],
                     columns=rr.Scalars.columns(scalars=[r["violation"] for r in records]))
    done = [r for r in records if "objective" in r]
    if done:
        n = np.arange(1, len(done) + 1)
        index = [rr.TimeColumn("evaluation", sequence=n)]
        values = np.array([r["objective"] for r in done])
        ok = values < qualified_below
        if ok.any():
            rec.send_columns(OBJECTIVE, indexes=[rr.TimeColumn("evaluation", sequence=n[ok])],
                             columns=rr.Scalars.columns(scalars=values[ok]))
        best = np.minimum.accumulate(values)
        shown = best < qualified_below
        if shown.any():
            rec.send_columns(BEST, indexes=[rr.TimeColumn("evaluation", sequence=n[shown])],
                             columns=rr.Scalars.columns(scalars=best[shown]))
        if start_objective is not None and start_objective < qualified_below:
            rec.send_columns(START, indexes=index, columns=rr.Scalars.columns(scalars=np.full(len(n), start_objective)))
        for name, start in start_values.items():
            path_values = [math.log(r["values"][name] / start) for r in done]
            rec.send_columns(f"{PARAMS}/{name}", indexes=index, columns=rr.Scalars.columns(scalars=path_values))
    close_recording(rec)
