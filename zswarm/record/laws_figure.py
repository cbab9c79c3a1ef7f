"""The figure of ``zswarm bench laws`` (docs/images/laws.png): for each law and latency, the collisions
with the filter off and on (left, log scale: none with the filter shows at the floor) and the median
time to catch the prey or reach the goal with the filter on (right; the share of runs that did is
printed above each bar)."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def save_figure(rows: list[dict[str, Any]], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    laws = list(dict.fromkeys(r["law"] for r in rows))
    latencies = sorted({r["latency"] for r in rows})
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.6), constrained_layout=True)
    width = 0.8 / max(len(latencies), 1)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, lat in enumerate(latencies):
        for safety, hatch, shift in (("off", None, 0.0), ("barrier", "//", 0.5)):
            xs, ys = [], []
            for i, law in enumerate(laws):
                r = next((r for r in rows if r["law"] == law and r["latency"] == lat and r["safety"] == safety), None)
                if r is not None:
                    xs.append(i + (k - (len(latencies) - 1) / 2) * width + (shift - 0.25) * width)
                    ys.append(r["collisions"] + 0.5)
            left.bar(xs, ys, width / 2, bottom=0.5, color=colors[k % len(colors)], hatch=hatch, edgecolor="black",
                     linewidth=0.4, label=f"{lat * 1000:g} ms, filter {safety}")
        xs, ys, notes = [], [], []
        for i, law in enumerate(laws):
            r = next((r for r in rows if r["law"] == law and r["latency"] == lat and r["safety"] == "barrier"), None)
            if r is not None:
                xs.append(i + (k - (len(latencies) - 1) / 2) * width)
                ys.append(r["capture_median"] or 0.0)
                notes.append(f"{r['reached']}/{r['runs']}")
        bars = right.bar(xs, ys, width * 0.9, color=colors[k % len(colors)], label=f"{lat * 1000:g} ms")
        for bar, note in zip(bars, notes):
            right.annotate(note, (bar.get_x() + bar.get_width() / 2, bar.get_height()), ha="center", va="bottom",
                           fontsize=8)
    left.set_yscale("log")
    left.set_ylabel("collisions over the seeds + 0.5 (log)")
    left.set_title("collisions: the law alone (plain) and behind the filter (hatched)")
    right.set_ylabel("median time to catch / reach (s), filter on")
    right.set_title("capture: runs that caught the prey above each bar")
    for ax in (left, right):
        ax.set_xticks(range(len(laws)), laws)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)
