"""The figure of a sweep (``DIR/sweep.png``): capture time, collisions and clearance against latency x
dropout x safety filter.

Left: the mean capture time of each cell against the injected latency, one line per dropout and
safety mode, the
distributed runs solid with filled circles and the reference simulator's dashed with open squares,
nudged apart so neither hides the other, the spread over repeats as error bars (a cell where nothing
was caught is left out, and a panel with no capture at all says so; the capture rate is printed beside
each point). Middle: the mean collisions of each cell (the filter's point: none with it). Right: the
closest any agent came to an obstacle in each cell, with d_m^ro marked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def save_figure(rows: list[dict[str, Any]], path: Path, scenario: str, d_m_ro: float | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams["svg.fonttype"] = "none"  # text stays text in an SVG: searchable, editable
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(17, 4.8), constrained_layout=True)
    lines = sorted({(r["dropout"], r.get("safety", "off")) for r in rows})
    latencies = sorted({r["latency_ms"] for r in rows}) or [0.0]
    span = latencies[-1] - latencies[0]
    pad = max(0.08 * span, 10.0)  # one latency still gets a readable axis, not +-0.04 ms
    nudge = {"distributed": -0.012 * (span + 2 * pad), "simulated": 0.012 * (span + 2 * pad)}
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for source, style, marker, face in (("distributed", "-", "o", None), ("simulated", "--", "s", "none")):
        for k, (drop, safety) in enumerate(lines):
            cells = sorted((r for r in rows if r["source"] == source and r["dropout"] == drop
                            and r.get("safety", "off") == safety), key=lambda r: r["latency_ms"])
            if not cells:
                continue
            color = colors[k % len(colors)]
            mark = {"marker": marker, "color": color, "markerfacecolor": face or color}
            caught = [r for r in cells if r.get("capture_time_mean") is not None]
            label = f"{source}, dropout {drop:g}, safety {safety}"
            hits = [r for r in cells if r.get("collisions_mean") is not None]
            if hits:
                middle.plot([r["latency_ms"] + nudge[source] for r in hits], [r["collisions_mean"] for r in hits],
                            linestyle=style, label=label, **mark)
            if caught:
                xs = [r["latency_ms"] + nudge[source] for r in caught]
                left.errorbar(xs, [r["capture_time_mean"] for r in caught],
                              yerr=[r.get("capture_time_std") or 0.0 for r in caught], linestyle=style, capsize=3,
                              label=label, **mark)
                for x, r in zip(xs, caught):
                    left.annotate(f"{r['capture_rate']:.0%}", (x, r["capture_time_mean"]),
                                  textcoords="offset points", xytext=(4, 4 if source == "distributed" else -11),
                                  fontsize=7, color=color)
            clear = [r for r in cells if r.get("min_obstacle_clearance") is not None]
            if clear:
                right.plot([r["latency_ms"] + nudge[source] for r in clear],
                           [r["min_obstacle_clearance"] for r in clear], linestyle=style, label=label, **mark)
    if not left.get_legend_handles_labels()[0]:
        left.text(0.5, 0.5, "no run caught the prey", transform=left.transAxes, ha="center", va="center",
                  fontsize=12, color="gray")
    if d_m_ro is not None:
        right.axhline(d_m_ro, color="tab:red", linestyle=":", label=f"d_m^ro = {d_m_ro:g}")
    for ax in (left, middle, right):
        ax.set_xlim(latencies[0] - pad, latencies[-1] + pad)
        ax.set_xticks(latencies)
        ax.set_xlabel("injected latency (ms)")
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    left.set_ylabel("capture time, mean over repeats (s)")
    left.set_title("capture time (labels: share of runs that caught the prey)")
    top = max([r.get("collisions_mean") or 0.0 for r in rows] + [0.0])
    middle.set_ylim(-0.05 * max(top, 1.0), 1.1 * max(top, 1.0))  # none at all still reads as 0, not +-0.04
    middle.set_ylabel("collisions, mean over repeats")
    middle.set_title("collisions (pairs closer than 2 d^r)")
    right.set_ylabel("closest approach to an obstacle (min over repeats)")
    right.set_title("clearance")
    fig.suptitle(f"zswarm sweep: {scenario}", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
