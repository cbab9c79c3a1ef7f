"""The figure of ``zswarm bench guidelines`` (``DIR/guidelines.png``): the checker's verdict against
what the swarm did.

Left: for each scenario and N, the sets stacked by verdict and outcome: passed and clean, passed and
collided (false-safe, red: the number to keep at 0), failed and collided, failed but clean (how
conservative the checker is). Right: the closest two agents came in each set's runs against N, passed
sets in green and failed ones in grey, with the collision distance 2 d^r marked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

CATEGORIES = (("passed_clean", "passed, no collision", "tab:green"),
              ("false_safe", "passed, collided (false-safe)", "tab:red"),
              ("failed_collided", "failed, collided", "dimgray"),
              ("conservative", "failed, no collision (conservative)", "lightgray"))


def save_figure(table: list[dict[str, Any]], sets: list[dict[str, Any]], path: Path,
                collision_distance: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = [r for r in table if r["scenario"] != "all"]
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.8), constrained_layout=True)
    labels = [f"{r['scenario']}\nN={r['n']}" for r in rows]
    bottom = np.zeros(len(rows))
    for key, label, color in CATEGORIES:
        values = np.array([r[key] for r in rows], dtype=float)
        left.bar(range(len(rows)), values, bottom=bottom, color=color, label=label, edgecolor="white")
        bottom += values
    left.set_xticks(range(len(rows)), labels, fontsize=7)
    left.set_ylabel("parameter sets")
    total = next(r for r in table if r["scenario"] == "all")
    left.set_title(f"verdict against outcome: false-safe {total['false_safe']} of {total['passed']} passed sets, "
                   f"{total['conservative']} of {total['sets'] - total['passed']} failed sets never collided",
                   fontsize=9)
    left.set_ylim(0, 1.4 * float(bottom.max()))  # room above the bars for the legend
    left.legend(fontsize=8, loc="upper center", ncols=2)
    rng = np.random.default_rng(0)
    for ok, color, label in ((False, "gray", "failed zswarm design"), (True, "tab:green", "passed zswarm design")):
        chosen = [s for s in sets if s["design_ok"] is ok]
        if chosen:
            x = np.array([s["n"] for s in chosen], dtype=float) * np.exp(rng.uniform(-0.08, 0.08, len(chosen)))
            y = np.maximum([s["min_pair_distance"] for s in chosen], 1e-6)
            right.scatter(x, y, s=12, color=color, alpha=0.7, label=label)
    right.axhline(collision_distance, color="tab:red", linestyle=":", label=f"2 d^r = {collision_distance:g}")
    right.set_xscale("log")
    ns = sorted({s["n"] for s in sets})
    right.set_xticks(ns, [str(n) for n in ns])
    right.minorticks_off()
    right.set_yscale("log")
    right.set_xlabel("N (agents)")
    right.set_ylabel("closest two agents came (min over the set's runs)")
    right.set_title("closest two agents came, per set (a run stops at its first collision)", fontsize=9)
    right.grid(alpha=0.3)
    right.legend(fontsize=8)
    fig.suptitle("zswarm bench guidelines: do the design checks predict the swarm?", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
