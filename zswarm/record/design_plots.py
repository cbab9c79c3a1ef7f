"""The design view as a Rerun recording (``zswarm design --save``): the design figure and the verdicts.

The figure is :mod:`zswarm.record.design_figure`'s (Fig 9, the Prop 2 bound and the pair force with
labelled axes and the exact bounds marked), logged as an image: Rerun's own plots have no numeric
x axis for a function of distance. Beside it the verdicts as a markdown table, and the whole report
as JSON (``report/json``) for a program to read back.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Final

import rerun as rr
import rerun.blueprint as rrb

from zswarm.design.guidelines import DesignReport
from zswarm.record.design_figure import render_png, verdict_rows
from zswarm.record.recording import close_recording, open_recording

FIGURE: Final = "design/figure"
VERDICTS: Final = "design/verdicts"
REPORT: Final = "report/json"


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin=FIGURE, name="design: Fig 9, Prop 2, pair force"),
            rrb.Vertical(rrb.TextDocumentView(origin=VERDICTS, name="verdicts"),
                         rrb.TextDocumentView(origin=REPORT, name="report (JSON)"), row_shares=[2, 3]),
            column_shares=[3, 1],
        ),
        collapse_panels=True,
    )


def verdict_markdown(report: DesignReport) -> str:
    lines = ["| check | verdict | bound |", "|---|---|---|"]
    lines += [f"| {name} | **{verdict}** | {bound} |" for name, verdict, bound in verdict_rows(report)]
    lines += ["", "all guidelines hold" if report.ok else "guidelines fail: " + ", ".join(report.failures())]
    return "\n".join(lines)


def save_design(report: DesignReport, path: Path) -> None:
    """Write the design view to ``path``."""
    rec = open_recording(path, "zswarm-design", blueprint())
    rec.log(FIGURE, rr.Image(render_png(report)), static=True)
    rec.log(VERDICTS, rr.TextDocument(verdict_markdown(report), media_type=rr.MediaType.MARKDOWN), static=True)
    rec.log(REPORT, rr.TextDocument("```json\n" + json.dumps(report.to_json(), indent=2) + "\n```",
                                    media_type=rr.MediaType.MARKDOWN), static=True)
    close_recording(rec)
