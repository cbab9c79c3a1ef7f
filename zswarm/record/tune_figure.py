"""The figure of a tune (``DIR/tune.png`` or ``.svg``): how the search went, for a reader or a paper.

Left: the objective of every simulated candidate against its evaluation number, the best so far, and
the starting set's objective on the same seeds. Right: each tuned parameter's path, ln(value / start),
with the chosen set (the finalists' validation winner) marked.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any


def save_figure(path: Path, records: list[dict[str, Any]], start_values: dict[str, float],
                start_objective: float | None, qualified_below: float, title: str,
                chosen: tuple[int, int] | None = None) -> None:
    """``chosen``: (generation, slot) of the set the finalists' validation picked (marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    done = [r for r in records if "objective" in r]
    n = np.arange(1, len(done) + 1)
    values = np.array([r["objective"] for r in done], dtype=float)
    ok = values < qualified_below
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    left.scatter(n[ok], values[ok], s=12, color="tab:blue", label="candidate")
    if (~ok).any():
        top = values[ok].max() if ok.any() else qualified_below
        left.scatter(n[~ok], np.full((~ok).sum(), top), s=12, marker="x", color="tab:red",
                     label="disqualified (collision or contact), drawn at the top")
    if ok.any():
        best = np.minimum.accumulate(np.where(ok, values, np.inf))
        shown = np.isfinite(best)
        left.step(n[shown], best[shown], where="post", color="black", label="best so far")
    keys = [(r["gen"], r["slot"]) for r in done]
    best_i = keys.index(chosen) if chosen in keys else (int(np.argmin(np.where(ok, values, np.inf))) if ok.any() else None)
    if best_i is not None:
        left.plot(n[best_i], values[best_i], "o", markersize=9, markerfacecolor="none", color="tab:green")
        left.annotate(f"chosen {values[best_i]:.2f} s", (n[best_i], values[best_i]), textcoords="offset points",
                      xytext=(6, 6), color="tab:green")
    if start_objective is not None and start_objective < qualified_below:
        left.axhline(start_objective, color="tab:gray", linestyle="--", label=f"start set {start_objective:.2f} s")
    left.set_xlabel("simulated candidate (evaluation)")
    left.set_ylabel("objective: mean capture time over the tuning seeds (s)")
    left.set_title("objective")
    left.grid(alpha=0.3)
    left.legend(fontsize=8)
    for name, start in start_values.items():
        path_values = [math.log(r["values"][name] / start) for r in done]
        (line,) = right.plot(n, path_values, linewidth=1, label=name)
        if best_i is not None:
            right.plot(n[best_i], path_values[best_i], "o", color=line.get_color())
    right.axhline(0.0, color="tab:gray", linewidth=0.8)
    right.set_xlabel("simulated candidate (evaluation)")
    right.set_ylabel("ln(value / start value)")
    right.set_title("parameter paths (dots: the chosen set)")
    right.grid(alpha=0.3)
    right.legend(fontsize=8, ncol=3)
    fig.suptitle(title, fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
