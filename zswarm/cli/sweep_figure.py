"""The figure of a sweep (``DIR/sweep.png``): capture time and clearance against latency x dropout.

Left: the mean capture time of each cell against the injected latency, one line per dropout, the
distributed runs solid and the reference simulator's dashed, the spread over repeats as error bars
(a cell where nothing was caught is left out; the capture rate is printed beside each point).
Right: the closest any agent came to an obstacle in each cell, with d_m^ro marked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def save_figure(rows: list[dict[str, Any]], path: Path, scenario: str, d_m_ro: float | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.6), constrained_layout=True)
    dropouts = sorted({r["dropout"] for r in rows})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for source, style in (("distributed", "-"), ("simulated", "--")):
        for k, drop in enumerate(dropouts):
            cells = sorted((r for r in rows if r["source"] == source and r["dropout"] == drop),
                           key=lambda r: r["latency_ms"])
            if not cells:
                continue
            color = colors[k % len(colors)]
            caught = [r for r in cells if r.get("capture_time_mean") is not None]
            label = f"{source}, dropout {drop:g}"
            if caught:
                left.errorbar([r["latency_ms"] for r in caught], [r["capture_time_mean"] for r in caught],
                              yerr=[r.get("capture_time_std") or 0.0 for r in caught], linestyle=style, marker="o",
                              color=color, capsize=3, label=label)
                for r in caught:
                    left.annotate(f"{r['capture_rate']:.0%}", (r["latency_ms"], r["capture_time_mean"]),
                                  textcoords="offset points", xytext=(4, 4), fontsize=7, color=color)
            clear = [r for r in cells if r.get("min_obstacle_clearance") is not None]
            if clear:
                right.plot([r["latency_ms"] for r in clear], [r["min_obstacle_clearance"] for r in clear],
                           linestyle=style, marker="o", color=color, label=label)
    left.set_xlabel("injected latency (ms)")
    left.set_ylabel("capture time, mean over repeats (s)")
    left.set_title("capture time (labels: share of runs that caught the prey)")
    left.grid(alpha=0.3)
    left.legend(fontsize=8)
    if d_m_ro is not None:
        right.axhline(d_m_ro, color="tab:red", linestyle=":", label=f"d_m^ro = {d_m_ro:g}")
    right.set_xlabel("injected latency (ms)")
    right.set_ylabel("closest approach to an obstacle (min over repeats)")
    right.set_title("clearance")
    right.grid(alpha=0.3)
    right.legend(fontsize=8)
    fig.suptitle(f"zswarm sweep: {scenario}", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
