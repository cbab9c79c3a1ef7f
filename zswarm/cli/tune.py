"""``zswarm tune``: the parameters the design guidelines allow that catch the prey fastest on a network.

CMA-ES searches the potential parameters in log space (:mod:`zswarm.tune.search`); every candidate
that fails ``zswarm design`` is rejected before it is simulated; the others run on K seeds under the
given faults in the batched simulator. What it writes in ``--out DIR``:

- ``best.toml``: the best set (``--params DIR/best.toml`` for every other command);
- ``design.json`` / ``design.txt``: its design report;
- ``comparison.json``: the best set against the starting set on held-out seeds it never tuned on
  (under the tune's faults, and fault-free when those are not);
- ``tune.rrd`` and ``tune.png``: the search (objective and parameter paths) as a Rerun recording and a
  figure; ``history.jsonl`` / ``tune.json``: every candidate and the settings, from which an
  interrupted tune resumes; ``result.json``: all of it; with ``--confirm``, ``confirm.json`` and the
  distributed runs' recordings under ``confirm/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

from zswarm.args import add_param_args, positive_float, positive_int, seed_arg
from zswarm.errors import UsageError
from zswarm.files import write_json
from zswarm.model.params import FIELDS, Params, parse_assignments
from zswarm.model.potentials import COMBINATIONS
from zswarm.model.scenarios import SCENARIOS, get_scenario
from zswarm.tune.feasibility import CHECKS
from zswarm.tune.space import TUNABLE

HOLDOUT_OFFSET = 10_000  # held-out seeds: seed + 10000 + i, far from the tuning seeds seed + i
VALIDATION_OFFSET = 5_000  # validation seeds of the finalists: seed + 5000 + i

DESCRIPTION = (
    "Search the potential parameters (CMA-ES, in log space) for the set that catches the prey fastest "
    "under the given network faults, with the paper's design guidelines as hard constraints. "
    "Objective: the mean over --seeds K runs of the capture time, a run that never catches the prey "
    "counting as its duration plus --miss-penalty. A set whose runs have any collision (agents closer "
    "than 2 d^r), obstacle contact, or clearance below d_m^ro is disqualified; a set that fails zswarm "
    "design (Props 1-5, formation, contact, swarm squeeze; see --waive) is never simulated. "
    "Resumes from --out DIR after an interruption; deterministic for a given --seed. "
    "Exit 0 with a best set, 1 when no set passed, 2 on a usage error.")


def non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from zswarm.net.runspec import add_fault_args

    parser.add_argument("--scenario", default="moving-prey-blocked",
                        help=f"a registered scenario ({', '.join(SCENARIOS)}) or a .toml file "
                             "(default moving-prey-blocked)")
    add_param_args(parser)
    parser.add_argument("--tune", default=",".join(TUNABLE), metavar="NAMES",
                        help=f"comma-separated potential parameters to search (default: all, {','.join(TUNABLE)}); "
                             "the others keep the scenario's (or --set) value")
    parser.add_argument("--seeds", type=positive_int, default=4, metavar="K",
                        help="runs per candidate, seeds SEED..SEED+K-1 (default 4)")
    parser.add_argument("--holdout", type=positive_int, default=8, metavar="H",
                        help=f"held-out seeds for the final comparison, SEED+{HOLDOUT_OFFSET}... (default 8)")
    parser.add_argument("--finalists", type=positive_int, default=16, metavar="F",
                        help="the F best candidates of the search are re-run on --validate seeds and the best "
                             "there is chosen (default 16)")
    parser.add_argument("--validate", type=positive_int, default=32, metavar="V",
                        help=f"validation seeds for the finalists, SEED+{VALIDATION_OFFSET}... (default 32)")
    parser.add_argument("--budget", type=positive_int, default=300, metavar="EVALS",
                        help="simulated candidates (each K runs); rejected ones do not count (default 300)")
    parser.add_argument("--seed", type=seed_arg, default=0, help="seeds the search and the runs (default 0)")
    parser.add_argument("--popsize", type=positive_int, default=None,
                        help="candidates per generation (default: CMA-ES's, 4 + 3 ln(dimension))")
    parser.add_argument("--sigma", type=positive_float, default=0.3,
                        help="initial step in ln units (default 0.3, about 35 %%)")
    parser.add_argument("--waive", action="append", choices=CHECKS, default=[], metavar="CHECK",
                        help=f"do not require this design check (repeatable; one of {', '.join(CHECKS)})")
    parser.add_argument("--miss-penalty", type=non_negative, default=30.0, metavar="SECONDS",
                        help="added to the duration for a run that never catches the prey (default 30)")
    parser.add_argument("--duration", type=positive_float, default=None, help="simulated seconds per run "
                        "(default: the scenario's)")
    parser.add_argument("--potential", choices=COMBINATIONS, default=None,
                        help="obstacle-goal combination (default: the scenario's)")
    add_fault_args(parser)
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="where the results and the history go (reused to resume)")
    parser.add_argument("--confirm", action="store_true",
                        help="also run the best and the starting set as distributed swarms (zswarm run) on "
                             "the first --confirm-seeds held-out seeds, with the same faults")
    parser.add_argument("--confirm-seeds", type=positive_int, default=3, metavar="C")
    parser.add_argument("--json", action="store_true", help="print result.json instead of the tables")


@dataclasses.dataclass(frozen=True)
class Plan:
    """The checked settings of a tune."""

    scenario_name: str
    overrides: dict[str, float | int]
    names: list[str]
    seeds: tuple[int, ...]
    validation: tuple[int, ...]
    holdout: tuple[int, ...]
    out: Path

    def config(self, args: argparse.Namespace, task, faults) -> dict[str, Any]:
        return {"scenario": self.scenario_name, "scenario_definition": task.scenario.to_dict(),
                "overrides": self.overrides, "tune": self.names, "seeds": list(self.seeds),
                "validation": list(self.validation), "finalists": args.finalists,
                "holdout": list(self.holdout), "faults": faults.requested(), "potential": args.potential,
                "miss_penalty": args.miss_penalty, "waive": sorted(set(args.waive)), "sigma": args.sigma,
                "popsize": args.popsize, "seed": args.seed, "budget": args.budget}


def _plan(args: argparse.Namespace):
    from zswarm.net.runspec import faults_from_args
    from zswarm.sim.batch import MAX_AGENTS
    from zswarm.tune.objective import Task
    from zswarm.tune.space import Space

    if args.popsize is not None and args.popsize < 2:
        raise UsageError(f"--popsize must be >= 2: CMA-ES ranks candidates against each other (got {args.popsize})")
    if not str(args.out).strip() or str(args.out) == ".":
        raise UsageError("--out needs a directory of its own for the search's files (e.g. --out tune-run)")
    overrides = parse_assignments(args.assignments)
    scenario = get_scenario(args.scenario, overrides)
    if args.duration is not None:
        scenario = dataclasses.replace(scenario, duration=args.duration)
    if scenario.n_agents > MAX_AGENTS:
        raise UsageError(f"tune simulates at most {MAX_AGENTS} agents per run (got {scenario.n_agents})")
    names = [n.strip() for n in args.tune.split(",") if n.strip()]
    space = Space.build(names, scenario.params)
    faults = faults_from_args(args)
    seeds = tuple(range(args.seed, args.seed + args.seeds))
    validation = tuple(range(args.seed + VALIDATION_OFFSET, args.seed + VALIDATION_OFFSET + args.validate))
    holdout = tuple(range(args.seed + HOLDOUT_OFFSET, args.seed + HOLDOUT_OFFSET + args.holdout))
    task = Task(scenario, seeds, faults, args.potential, args.miss_penalty)
    plan = Plan(args.scenario, overrides, names, seeds, validation, holdout, args.out)
    return plan, space, task, faults


class Bar:
    """One progress line on stderr, redrawn in place on a terminal (a line per generation otherwise)."""

    def __init__(self, quiet: bool) -> None:
        self.quiet, self.tty = quiet, sys.stderr.isatty()

    def __call__(self, p) -> None:
        if self.quiet:
            return
        width = 24
        filled = int(width * min(p.evaluated / p.budget, 1.0))
        eta = "ETA " + _clock(p.eta) if p.eta is not None else "ETA -"
        best = f"best {p.best:.2f}" if p.best is not None else "best -"
        line = (f"[{'#' * filled}{'.' * (width - filled)}] {p.evaluated}/{p.budget} simulated  gen {p.generation}  "
                f"{p.checked} checked ({p.rejected} rejected)  {best}  {eta}")
        print(("\r" + line) if self.tty else line, end="" if self.tty else "\n", file=sys.stderr, flush=True)

    def done(self) -> None:
        if self.tty and not self.quiet:
            print(file=sys.stderr)


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 60}m{seconds % 60:02d}s"


def write_best_toml(path: Path, params: Params, plan: Plan, objective: float, command: str,
                    kept_start: bool = False) -> None:
    flat = params.flat()
    keep = [n for n in TUNABLE] + [n for n in plan.overrides if FIELDS[n].group != "potential"]
    swarm = " ".join(f"--set {n}={flat[n]:g}" for n in ("n_agents", "sensing_radius", "v_max", "robot_radius"))
    what = (f"the START set for {plan.scenario_name}: the best set found (validation objective {objective:.4g} s) did "
            "not beat it on the held-out seeds (comparison.json)" if kept_start else
            f"the best set found for {plan.scenario_name} (validation objective {objective:.4g} s)")
    lines = [f"# zswarm tune: {what}",
             f"# command: {command}", "# use it with --params FILE (zswarm run, sim, design, launch.py);",
             f"# its design report (design.txt) is: zswarm design --params FILE {swarm}", "",
             "[params]"]
    lines += [f"{n} = {flat[n]!r}" for n in keep]
    tmp = Path(f"{path}.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)


def run(args: argparse.Namespace) -> int:
    from zswarm.cli.design import render
    from zswarm.cli.tune_compare import confirm, held_out
    from zswarm.cli.tune_figure import save_figure
    from zswarm.model.design import check
    from zswarm.provenance import versions
    from zswarm.record.tune_log import save_search
    from zswarm.tune.finalists import finalists, validate
    from zswarm.tune.history import History
    from zswarm.tune.objective import describe, evaluate
    from zswarm.tune.search import Settings, search

    plan, space, task, faults = _plan(args)
    config = plan.config(args, task, faults)
    history = History(plan.out, config)
    bar = Bar(quiet=args.json)
    settings = Settings(budget=args.budget, seed=args.seed, popsize=args.popsize, sigma0=args.sigma,
                        waived=frozenset(args.waive))
    started = time.monotonic()
    try:
        result = search(space, task, history, settings, bar)
    finally:
        history.close()
        bar.done()
    start_params = space.base
    start_failures = check(start_params).failures()  # the whole report, the squeeze included
    qualified_below = 10.0 * (task.duration + task.miss_penalty)
    start_objective = evaluate(task, [start_params])[0][0]
    command = "zswarm tune " + " ".join(sys.argv[2:] if sys.argv[1:2] == ["tune"] else sys.argv[1:])
    out: dict[str, Any] = {
        "scenario": plan.scenario_name, "tuned": plan.names, "budget": args.budget,
        "evaluated": result.progress.evaluated, "checked": result.progress.checked,
        "replayed": result.progress.evaluated - result.progress.computed,
        "rejected": result.progress.rejected, "generations": result.progress.generation, "stop": result.stop,
        "seconds": time.monotonic() - started, "faults": faults.requested(), "waived": sorted(set(args.waive)),
        "seeds": list(plan.seeds), "holdout": list(plan.holdout), **describe(),
        "failed_checks": _failure_counts(result.records),
        "start": {"values": space.values(space.start), "design_failures": start_failures,
                  "objective": start_objective},
        "versions": versions(), "command": command,
    }
    title = (f"zswarm tune {plan.scenario_name}: {result.progress.evaluated} simulated candidates x {len(plan.seeds)} "
             f"seeds, faults {_faults_text(faults)}")
    chosen = finalists(result.records, args.finalists, qualified_below)
    if not chosen:
        closest = result.closest
        out["best"] = None
        out["closest"] = None if closest is None else {k: closest[k] for k in ("values", "violation", "failures")}
        save_search(plan.out / "tune.rrd", config, result.records, space.values(space.start), start_objective,
                    qualified_below, "### no set found\n" + out["stop"])
        write_json(plan.out / "result.json", out)
        _print_failure(out, args)
        return 1
    validation = validate(task, space, chosen, plan.validation)
    best = validation[0]
    best_params = space.params(best["x"])
    save_figure(plan.out / "tune.png", result.records, space.values(space.start), start_objective,
                qualified_below, title, chosen=(best["gen"], best["slot"]))
    sets = {"tuned": best_params, "start": start_params}
    comparison = {"as_tuned": held_out(task, sets, plan.holdout)}
    tuned_wins = _beats(comparison["as_tuned"]["tuned"], comparison["as_tuned"]["start"])
    recommended = best_params if tuned_wins else start_params
    report = check(recommended)  # the full report, waived checks included, for the reader
    write_best_toml(plan.out / "best.toml", recommended, plan, best["validation_objective"], command,
                    kept_start=not tuned_wins)
    write_json(plan.out / "design.json", report.to_json())
    (plan.out / "design.txt").write_text(render(report) + "\n")
    if faults.active:
        comparison["fault_free"] = held_out(dataclasses.replace(task, faults=dataclasses.replace(faults, latency=0.0,
                                            jitter=0.0, dropout=0.0, distance_loss=0.0)), sets, plan.holdout)
    write_json(plan.out / "comparison.json", comparison)
    out.update(best={"values": best["values"], "objective": best["search_objective"],
                     "validation_objective": best["validation_objective"], "generation": best["gen"],
                     "slot": best["slot"], "design_failures": list(report.failures())},
               finalists=[{k: v for k, v in row.items() if k != "x"} for row in validation], comparison=comparison,
               recommended="tuned" if tuned_wins else "start")
    if args.confirm:
        try:
            out["confirm"] = confirm(plan, args, sets, faults, quiet=args.json)
        except RuntimeError as exc:  # a distributed run failed: say which, keep what was written
            write_json(plan.out / "result.json", out)
            print(f"zswarm tune: {exc}", file=sys.stderr)
            return 1
        write_json(plan.out / "confirm.json", out["confirm"])
    save_search(plan.out / "tune.rrd", config, result.records, space.values(space.start), start_objective,
                qualified_below, _report_md(out))
    write_json(plan.out / "result.json", out)
    if args.json:
        print(json.dumps(out, default=str))
    else:
        _print_result(out, plan, faults)
    if not tuned_wins:
        t, st = comparison["as_tuned"]["tuned"], comparison["as_tuned"]["start"]
        print(f"zswarm tune: the chosen set does not beat the start on the held-out seeds (objective "
              f"{t['objective']:.2f} s, caught {t['captured']}/{t['runs']}, against {st['objective']:.2f} s, "
              f"{st['captured']}/{st['runs']}): {plan.out}/best.toml keeps the start; a larger --budget or more "
              f"--seeds may find better", file=sys.stderr)
        return 1
    return 0


def _beats(tuned: dict[str, Any], start: dict[str, Any]) -> bool:
    """Whether the tuned set is better than the start on the held-out seeds (lower objective: mean
    capture time with misses and disqualifications penalised)."""
    return tuned["objective"] is not None and (start["objective"] is None or tuned["objective"] < start["objective"])


def _report_md(out: dict[str, Any]) -> str:
    """The outcome as markdown, for the recording's text panel."""
    b = out["best"]
    lines = [f"### chosen set (validation objective {b['validation_objective']:.3f} s)", "",
             "| parameter | start | chosen |", "|---|---|---|"]
    lines += [f"| {k} | {out['start']['values'][k]:.4g} | {v:.4g} |" for k, v in b["values"].items()]
    lines += ["", f"design: {'all checks hold' if not b['design_failures'] else 'fails ' + ', '.join(b['design_failures'])}"
              + (f" (waived: {', '.join(out['waived'])})" if out["waived"] else ""), ""]
    tables = [(f"held-out seeds, simulated, {key.replace('_', ' ')}", rows) for key, rows in out["comparison"].items()]
    if "confirm" in out:
        tables.append(("held-out seeds, distributed (zswarm run)", out["confirm"]))
    for title, rows in tables:
        lines += [f"### {title}", "",
                  "| set | captured | mean capture (s) | collisions | contacts | min clearance | disqualified |",
                  "|---|---|---|---|---|---|---|"]
        lines += [f"| {label} | {r['captured']}/{r['runs']} | {_fmt(r['mean_capture_time'], '.2f')} | {r['collisions']} | "
                  f"{r['obstacle_collisions']} | {_fmt(r['min_obstacle_clearance'])} | {r['disqualified']} |"
                  for label, r in rows.items()]
        lines.append("")
    return "\n".join(lines)


def _replayed(out: dict[str, Any]) -> str:
    return f" ({out['replayed']} of them taken from the history of an earlier run)" if out["replayed"] else ""


def _failure_counts(records: list[dict[str, Any]]) -> dict[str, int]:
    """How many candidates failed each check (a candidate may fail several; the squeeze runs only for
    one that passes every other check)."""
    return {k: n for k in CHECKS if (n := sum(k in r["failures"] for r in records))}


def _faults_text(faults) -> str:
    if not faults.active:
        return "none"
    return f"{faults.latency * 1000:g} ms latency, {faults.jitter * 1000:g} ms jitter, {faults.dropout:g} loss"


def _fmt(v: Any, spec: str = ".3g") -> str:
    return "-" if v is None else format(v, spec)


def _print_failure(out: dict[str, Any], args: argparse.Namespace) -> None:
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


def _print_result(out: dict[str, Any], plan: Plan, faults) -> None:
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
          f"design: {'all checks hold' if not b['design_failures'] else 'fails ' + ', '.join(b['design_failures'])}")
    print("best set: " + "  ".join(f"{k}={v:.4g}" for k, v in b["values"].items()))
    sections = [("as_tuned", _faults_text(faults))] + ([("fault_free", "none")] if "fault_free" in out["comparison"] else [])
    for key, text in sections:
        print(f"\nheld-out seeds {plan.holdout[0]}..{plan.holdout[-1]}, simulated, faults {text}:")
        _table(out["comparison"][key])
    if "confirm" in out:
        print(f"\ndistributed (zswarm run), faults {_faults_text(faults)}:")
        _table(out["confirm"])
    print(f"\nwrote {plan.out}/best.toml (use: --params {plan.out}/best.toml), design.txt, comparison.json, "
          f"tune.png, tune.rrd, result.json")


def _table(rows: dict[str, dict[str, Any]]) -> None:
    print(f"  {'set':<7} {'captured':>9} {'mean capture':>13} {'collisions':>11} {'contacts':>9} "
          f"{'min clearance':>14} {'disqualified':>13}")
    for label, r in rows.items():
        print(f"  {label:<7} {r['captured']:>4}/{r['runs']:<4} {_fmt(r['mean_capture_time'], '.2f'):>12}s "
              f"{r['collisions']:>11} {r['obstacle_collisions']:>9} {_fmt(r['min_obstacle_clearance']):>14} "
              f"{r['disqualified']:>13}")
