"""``zswarm replay RUN.rrd`` and ``zswarm compare A.rrd B.rrd``: metrics recomputed from recordings.

Replay reads the exact float64 agent states a run logged, recomputes every per-step metric with the
same code the simulator and the world use, folds them into a summary, and checks it against the
summary stored in the recording.
"""

from __future__ import annotations

import argparse
import json
import sys
import math
from pathlib import Path
from typing import Any

COMPARED = ("capture_time", "collisions", "min_pair_distance", "min_obstacle_clearance",
            "obstacle_collisions", "max_components", "final_components", "max_cohesion",
            "final_centroid_goal_distance", "final_mean_goal_distance", "epsilon")


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def run_replay(args: argparse.Namespace) -> int:
    from zswarm.record.replay import load_run, recompute

    run = load_run(args.recording)
    metrics = recompute(run)
    stored = run.summary or {}
    mismatches = {k: {"recomputed": metrics[k], "stored": stored.get(k)} for k in metrics
                  if k in stored and not _same(metrics[k], stored[k])}
    out = {**{k: v for k, v in stored.items() if k not in metrics}, **metrics,
           "replay": {"frames": len(run.frames), "matches_stored_summary": not mismatches and bool(stored),
                      "mismatches": mismatches}}
    if args.json:
        print(json.dumps(out, sort_keys=True))
    else:
        for k in metrics:
            print(f"{k:>32}: {metrics[k]}" + (f"   (stored: {stored.get(k)})" if k in mismatches else ""))
        print(f"{len(run.frames)} frames; " + ("matches the stored summary" if not mismatches and stored
                                                else "no stored summary" if not stored else
                                                f"{len(mismatches)} values differ from the stored summary"))
    return 0 if not mismatches else 1


def differences(a: dict, b: dict) -> list[str]:
    """What two recordings' configurations were asked to do differently, in words ("dimensions 2 and 3")."""
    def facts(c: dict) -> dict:
        law = c.get("law")
        return {"scenario": c.get("scenario"), "agents": c.get("n_agents"),
                "dimensions": (c.get("scenario_definition") or {}).get("params", {}).get("dimensions"),
                "law": law.get("name") if isinstance(law, dict) else "apf"}
    fa, fb = facts(a), facts(b)
    return [f"{k} {fa[k]} and {fb[k]}" for k in fa if fa[k] != fb[k] and None not in (fa[k], fb[k])]


def run_compare(args: argparse.Namespace) -> int:
    from zswarm.record.replay import load_run, recompute

    runs = [(Path(p), load_run(p)) for p in (args.a, args.b)]
    cols = [(p, {**(r.summary or {}), **recompute(r)}) for p, r in runs]
    differ = differences(runs[0][1].config or {}, runs[1][1].config or {})
    if differ:  # said, not refused: comparing two settings is what compare is for, but it must be seen
        print(f"warning: the two runs differ in {', '.join(differ)}: their metrics are not like for like",
              file=sys.stderr)
    if args.json:
        print(json.dumps({str(p): {k: s.get(k) for k in COMPARED} for p, s in cols}))
        return 0
    w = max(len(str(p)) for p, _ in cols) + 2
    print(f"{'metric':>30}  " + "".join(f"{str(p):>{w}}" for p, _ in cols) + f"{'difference':>14}")
    for k in COMPARED:
        a, b = (s.get(k) for _, s in cols)
        diff = (b - a) if isinstance(a, (int, float)) and isinstance(b, (int, float)) else ""
        fmt = lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)  # noqa: E731
        print(f"{k:>30}  {fmt(a):>{w}}{fmt(b):>{w}}{fmt(diff) if diff != '' else '':>14}")
    return 0


def add_arguments(sub) -> None:
    replay = sub.add_parser("replay", help="recompute a run's metrics from its recording",
                            description="Recompute the metrics from a recording's logged states and check them "
                                        "against the summary stored in it (exit 1 if they differ).")
    replay.add_argument("recording", type=Path)
    replay.add_argument("--json", action="store_true")
    replay.set_defaults(run=run_replay)
    compare = sub.add_parser("compare", help="two recordings' metrics side by side")
    compare.add_argument("a", type=Path)
    compare.add_argument("b", type=Path)
    compare.add_argument("--json", action="store_true")
    compare.set_defaults(run=run_compare)
