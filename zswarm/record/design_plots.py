"""Rerun plots of the design checks: Fig 9 (alpha and the c_g/c_o bound) and the pair force."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Final

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from zswarm.model.design import DesignReport, alpha, prop1_curve, prop2_curve
from zswarm.model.formation import pair_gain
from zswarm.record.recording import close_recording, open_recording

FIG9: Final = "fig9"
PROP2: Final = "prop2"
PAIR: Final = "pair_force"
REPORT: Final = "report"


def _strip(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    keep = np.isfinite(y)
    return np.column_stack([x[keep], y[keep]])


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(origin=FIG9, name="Fig 9: alpha and c_g/c_o bound vs |psi_g|"),
            rrb.Spatial2DView(origin=PROP2, name="Prop 2: c_g/c_o bound vs |psi_o|"),
            rrb.Spatial2DView(origin=PAIR, name="pair force -g(r) r vs r"),
            rrb.TextDocumentView(origin=REPORT, name="verdicts"),
        ),
        collapse_panels=True,
    )


def save_design(report: DesignReport, path: Path) -> None:
    """Write the curves as line strips (x = distance, y = value) plus the report as text."""
    p, m = report.params.potential, report.params.margins
    rec = open_recording(path, "zswarm-design", blueprint())
    x = np.linspace(1e-4, 0.6, 600)
    ratio = p.c_g / p.c_o if p.c_o else np.nan
    rec.log(f"{FIG9}/alpha", rr.LineStrips2D([_strip(x, alpha(x, m.d_m_go, p) / 100.0)],
                                             labels=["alpha / 100 (eq 20)"], colors=[(80, 160, 255)]),
            static=True)
    rec.log(f"{FIG9}/bound", rr.LineStrips2D([_strip(x, prop1_curve(x, m.d_m_go, p))],
                                             labels=["c_g/o bound (eq 18)"], colors=[(255, 120, 60)]),
            static=True)
    rec.log(f"{PROP2}/bound", rr.LineStrips2D([_strip(x, prop2_curve(x, m.d_m_go, p))],
                                              labels=["c_g/o bound (eq 24)"], colors=[(255, 120, 60)]),
            static=True)
    for entity in (FIG9, PROP2):
        rec.log(f"{entity}/ratio", rr.LineStrips2D([[[0.0, ratio], [0.6, ratio]]], labels=["c_g/c_o"],
                                                   colors=[(120, 220, 120)]), static=True)
    r = np.linspace(0.0, 4.0 * max(p.l_a, p.l_r), 800)
    rec.log(f"{PAIR}/force", rr.LineStrips2D([_strip(r, -pair_gain(r * r, p) * r)],
                                             labels=["repulsive > 0 (eq 28)"]), static=True)
    rec.log(f"{PAIR}/zero", rr.LineStrips2D([[[0.0, 0.0], [float(r[-1]), 0.0]]]), static=True)
    rec.log(REPORT, rr.TextDocument("```json\n" + json.dumps(report.to_json(), indent=2) + "\n```",
                                    media_type=rr.MediaType.MARKDOWN), static=True)
    close_recording(rec)
