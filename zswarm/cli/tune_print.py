"""What ``zswarm tune`` prints: its progress line and its result."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from zswarm.tune.pipeline import Plan, _fmt, faults_text


class Bar:
    """One progress line on stderr, redrawn in place on a terminal (a line per generation otherwise)."""

    def __init__(self, quiet: bool, seeds: int = 0, miss_s: float | None = None) -> None:
        self.quiet, self.tty = quiet, sys.stderr.isatty()
        self.head = None if miss_s is None else (  # what "best" is, said once the search is under way
            f"objective: the mean capture time over {seeds} tuning seeds, lower is better; a seed whose swarm never "
            f"catches the prey counts {miss_s:g} s (duration + --miss-penalty)")

    def __call__(self, p) -> None:
        if self.quiet:
            return
        if self.head:
            print(self.head, file=sys.stderr, flush=True)
            self.head = None
        width = 24
        filled = int(width * min(p.evaluated / p.budget, 1.0))
        eta = "ETA " + _clock(p.eta) if p.eta is not None else "ETA -"
        best = f"best {p.best:.2f} s" if p.best is not None else "best -"
        over = p.checked - p.rejected - p.evaluated  # passed the checks once the budget was spent
        line = (f"[{'#' * filled}{'.' * (width - filled)}] {p.evaluated}/{p.budget} simulated  gen {p.generation}  "
                f"{p.checked} checked: {p.rejected} failed the design checks"
                + (f", {over} passed but the budget was spent" if over else "") + f"  {best}  {eta}")
        print(("\r" + line) if self.tty else line, end="" if self.tty else "\n", file=sys.stderr, flush=True)

    def done(self) -> None:
        if self.tty and not self.quiet:
            print(file=sys.stderr)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 60}m{seconds % 60:02d}s"


def _replayed(out: dict[str, Any]) -> str:
    return f" ({out['replayed']} of them taken from the history of an earlier run)" if out["replayed"] else ""


def print_failure(out: dict[str, Any], args: argparse.Namespace) -> None:
    if args.json:
        print(json.dumps(out, default=str))
        return
    print(f"no set was found: {out['stop']} ({out['checked']} candidates checked, {out['evaluated']} simulated)")
    print("candidates failing each check: " + ", ".join(f"{k} {n}" for k, n in out["failed_checks"].items())
          + " (the swarm squeeze runs only for a set that passes every other check)")
    closest = out.get("closest")
    if closest:
        print(f"closest to passing: fails {', '.join(closest['failures']) or '-'} (violation {closest['violation']:.3g}): "
              + "  ".join(f"{k}={v:.4g}" for k, v in closest["values"].items()))
    print(f"the starting set fails: {', '.join(out['start']['design_failures']) or 'nothing'}; "
          "see zswarm design, and --waive for a check your setting cannot meet")


def print_result(out: dict[str, Any], plan: Plan, faults) -> None:
    b = out["best"]
    print(f"{out['evaluated']} candidates simulated ({out['checked']} checked, {out['rejected']} rejected by the design "
          f"checks) in {out['seconds']:.0f} s{_replayed(out)}; stopped: {out['stop']}")
    print("candidates failing each check: " + (", ".join(f"{k} {n}" for k, n in out["failed_checks"].items()) or "none")
          + (f" (waived: {', '.join(out['waived'])})" if out["waived"] else ""))
    fin = out["finalists"]
    print(f"the {len(fin)} best re-run on {len(plan.validation)} validation seeds: chosen the search's #{fin[0]['search_rank'] + 1} "
          f"(validation {fin[0]['validation_objective']:.3f} s; "
          f"{sum(r['validation_disqualified'] > 0 for r in fin)} of {len(fin)} finalists collided there)")
    print(f"best objective {b['objective']:.3f} s on the tuning seeds (start {_fmt(out['start']['objective'], '.3f')} s); "
          f"design: {design_line(out)}")
    kept = out["recommended"] == "tuned"
    print(("best set: " if kept else "the search's best (not kept: best.toml keeps the start, below): ")
          + "  ".join(f"{k}={v:.4g}" for k, v in b["values"].items()))
    sections = [("as_tuned", faults_text(faults))] + ([("fault_free", "none")] if "fault_free" in out["comparison"] else [])
    for key, text in sections:
        print(f"\nheld-out seeds {plan.holdout[0]}..{plan.holdout[-1]}, simulated, faults {text}:")
        _table(out["comparison"][key])
    if "confirm" in out:
        print(f"\ndistributed (zswarm run), faults {faults_text(faults)}:")
        _table(out["confirm"])
    print(f"\nwrote {plan.out}/best.toml ({'the best set' if kept else 'the START set'}; use: --params "
          f"{plan.out}/best.toml), design.txt, comparison.json, tune.png, tune.rrd, result.json")


def _table(rows: dict[str, dict[str, Any]]) -> None:
    print(f"  {'set':<7} {'captured':>9} {'mean capture':>13} {'collisions':>11} {'contacts':>9} "
          f"{'min clearance':>14} {'disqualified':>13}")
    for label, r in rows.items():
        print(f"  {label:<7} {r['captured']:>4}/{r['runs']:<4} {_fmt(r['mean_capture_time'], '.2f'):>12}s "
              f"{r['collisions']:>11} {r['obstacle_collisions']:>9} {_fmt(r['min_obstacle_clearance']):>14} "
              f"{r['disqualified']:>13}")


def design_line(out: dict) -> str:
    """What the design checks say of the best set (a law other than apf has none: the filter kept it apart)."""
    from zswarm.design.guidelines import has_guidelines

    law = out.get("law", "apf")
    if not has_guidelines(law):
        return f"no analytical guidelines for law {law}; simulated behind the safety filter"
    failures = out["best"]["design_failures"]
    return "all checks hold" if not failures else "fails " + ", ".join(failures)
