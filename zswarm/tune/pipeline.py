"""The tune's pipeline after its settings are checked: :func:`search_phase` (CMA-ES,
:mod:`zswarm.tune.search`), :func:`choose` (finalists on validation seeds, the best against the start
on held-out seeds) and :func:`finish`; ``zswarm tune`` (:mod:`zswarm.cli.tune`) adds the distributed
confirmation between the last two. What it writes: docs/tuning.md."""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from zswarm.design.guidelines import has_guidelines
from zswarm.files import write_json
from zswarm.paper.params import FIELDS, Params
from zswarm.tune.feasibility import CHECKS
from zswarm.tune.space import TUNABLE

HOLDOUT_OFFSET = 10_000  # held-out seeds: seed + 10000 + i, far from the tuning seeds seed + i
VALIDATION_OFFSET = 5_000  # validation seeds of the finalists: seed + 5000 + i


@dataclass(frozen=True)
class Plan:
    """The checked settings of a tune."""

    scenario_name: str
    overrides: dict[str, float | int]
    names: list[str]
    seeds: tuple[int, ...]
    validation: tuple[int, ...]
    holdout: tuple[int, ...]
    out: Path

    @classmethod
    def of(cls, scenario_name: str, overrides: dict[str, float | int], names: list[str], seed: int, seeds: int,
           validate: int, holdout: int, out: Path) -> Plan:
        """Tuning seeds seed.., validation seeds seed + 5000.., held-out seeds seed + 10000..."""
        return cls(scenario_name, overrides, names, tuple(range(seed, seed + seeds)),
                   tuple(range(seed + VALIDATION_OFFSET, seed + VALIDATION_OFFSET + validate)),
                   tuple(range(seed + HOLDOUT_OFFSET, seed + HOLDOUT_OFFSET + holdout)), out)

    def config(self, args: argparse.Namespace, task, faults) -> dict[str, Any]:
        return {"scenario": self.scenario_name, "scenario_definition": task.scenario.to_dict(),
                "overrides": self.overrides, "tune": self.names, "seeds": list(self.seeds),
                "validation": list(self.validation), "finalists": args.finalists,
                "holdout": list(self.holdout), "faults": faults.requested(), "potential": args.potential,
                "miss_penalty": args.miss_penalty, "waive": sorted(set(args.waive)), "sigma": args.sigma,
                "popsize": args.popsize, "seed": args.seed, "budget": args.budget}


@dataclass
class Searched:
    """What the search left: its result, the starting set's objective and the result being built."""

    config: dict[str, Any]
    result: Any  # zswarm.tune.search.SearchResult
    start_params: Params
    start_values: dict[str, float]
    start_objective: float
    qualified_below: float
    title: str
    out: dict[str, Any] = field(default_factory=dict)
    chosen: list[dict[str, Any]] = field(default_factory=list)


def search_phase(plan: Plan, space, task, faults, args: argparse.Namespace, progress: Callable,
                 command: str) -> Searched:
    """Run (or resume) the search and judge the starting set; ``out`` holds what result.json reports."""
    from zswarm.provenance import versions
    from zswarm.tune.finalists import finalists
    from zswarm.tune.history import History
    from zswarm.tune.objective import describe, evaluate
    from zswarm.tune.search import Settings, search

    config = plan.config(args, task, faults)
    history = History(plan.out, config)
    settings = Settings(budget=args.budget, seed=args.seed, popsize=args.popsize, sigma0=args.sigma,
                        waived=frozenset(args.waive))
    started = time.monotonic()
    try:
        result = search(space, task, history, settings, progress)
    finally:
        history.close()
    start_params = space.base
    start_failures = design_failures(start_params)  # the whole report, the squeeze included
    start_objective = evaluate(task, [start_params])[0][0]
    qualified_below = 10.0 * (task.duration + task.miss_penalty)
    p = result.progress
    out: dict[str, Any] = {
        "scenario": plan.scenario_name, "law": task.scenario.params.law.law, "safety": task.safety,
        "tuned": plan.names, "budget": args.budget,
        "evaluated": p.evaluated, "checked": p.checked, "replayed": p.evaluated - p.computed,
        "rejected": p.rejected, "generations": p.generation, "stop": result.stop,
        "seconds": time.monotonic() - started, "faults": faults.requested(), "waived": sorted(set(args.waive)),
        "seeds": list(plan.seeds), "holdout": list(plan.holdout), **describe(),
        "failed_checks": failure_counts(result.records),
        "start": {"values": space.values(space.start), "design_failures": start_failures,
                  "objective": start_objective},
        "versions": versions(), "command": command,
    }
    title = (f"zswarm tune {plan.scenario_name}: {p.evaluated} simulated candidates x {len(plan.seeds)} "
             f"seeds, faults {faults_text(faults)}")
    return Searched(config, result, start_params, space.values(space.start), start_objective, qualified_below,
                    title, out, finalists(result.records, args.finalists, qualified_below))


def no_set(s: Searched, plan: Plan) -> None:
    """No candidate qualified: the closest one, the recording and result.json."""
    from zswarm.record.tune_log import save_search

    closest = s.result.closest
    s.out["best"] = None
    s.out["closest"] = None if closest is None else {k: closest[k] for k in ("values", "violation", "failures")}
    save_search(plan.out / "tune.rrd", s.config, s.result.records, s.start_values, s.start_objective,
                s.qualified_below, "### no set found\n" + s.out["stop"])
    write_json(plan.out / "result.json", s.out)


def choose(s: Searched, plan: Plan, space, task, faults, command: str,
           render: Callable[[Any], str]) -> dict[str, Params]:
    """Validate the finalists, compare the best with the start on held-out seeds and write best.toml (the
    start when the best does not beat it), design.json / design.txt (``render``), tune.png and
    comparison.json. Returns the two sets compared."""
    from zswarm.design.guidelines import check
    from zswarm.record.tune_figure import save_figure
    from zswarm.tune.compare import held_out
    from zswarm.tune.finalists import validate

    validation = validate(task, space, s.chosen, plan.validation)
    best = validation[0]
    best_params = space.params(best["x"])
    save_figure(plan.out / "tune.png", s.result.records, s.start_values, s.start_objective,
                s.qualified_below, s.title, chosen=(best["gen"], best["slot"]))
    sets = {"tuned": best_params, "start": s.start_params}
    comparison = {"as_tuned": held_out(task, sets, plan.holdout)}
    tuned_wins = beats(comparison["as_tuned"]["tuned"], comparison["as_tuned"]["start"])
    recommended = best_params if tuned_wins else s.start_params
    write_best_toml(plan.out / "best.toml", recommended, plan, best["validation_objective"], command,
                    kept_start=not tuned_wins)
    if has_guidelines(recommended.law.law):
        report = check(recommended)  # the full report, waived checks included, for the reader
        write_json(plan.out / "design.json", report.to_json())
        (plan.out / "design.txt").write_text(render(report) + "\n")
    else:
        from zswarm.design.guidelines import verdict

        write_json(plan.out / "design.json", verdict(recommended))
        (plan.out / "design.txt").write_text(verdict(recommended)["note"] + "\n")
    if faults.active:
        fault_free = dataclasses.replace(faults, latency=0.0, jitter=0.0, dropout=0.0, distance_loss=0.0)
        comparison["fault_free"] = held_out(dataclasses.replace(task, faults=fault_free), sets, plan.holdout)
    write_json(plan.out / "comparison.json", comparison)
    s.out.update(best={"values": best["values"], "objective": best["search_objective"],
                       "validation_objective": best["validation_objective"], "generation": best["gen"],
                       "slot": best["slot"], "design_failures": design_failures(recommended)},
                 finalists=[{k: v for k, v in row.items() if k != "x"} for row in validation],
                 comparison=comparison, recommended="tuned" if tuned_wins else "start")
    return sets


def design_failures(params: Params) -> list[str]:
    """The checks ``params`` fails (none for a law the guidelines do not cover)."""
    from zswarm.design.guidelines import check

    return list(check(params).failures()) if has_guidelines(params.law.law) else []


def finish(s: Searched, plan: Plan) -> None:
    """The recording (with the outcome as its text panel) and result.json."""
    from zswarm.record.tune_log import save_search

    save_search(plan.out / "tune.rrd", s.config, s.result.records, s.start_values, s.start_objective,
                s.qualified_below, report_md(s.out))
    write_json(plan.out / "result.json", s.out)


def write_best_toml(path: Path, params: Params, plan: Plan, objective: float, command: str,
                    kept_start: bool = False) -> None:
    flat = params.flat()
    law = not has_guidelines(params.law.law)  # its own parameters go in a [law] table
    keep = ([] if law else list(TUNABLE)) + [n for n in plan.overrides if n in FIELDS and n != "law"
                                             and FIELDS[n].group != "potential"]
    swarm = " ".join(f"--set {n}={flat[n]:g}" for n in ("n_agents", "sensing_radius", "v_max", "robot_radius"))
    what = (f"the START set for {plan.scenario_name}: the best set found (validation objective {objective:.4g} s) did "
            "not beat it on the held-out seeds (comparison.json)" if kept_start else
            f"the best set found for {plan.scenario_name} (validation objective {objective:.4g} s)")
    lines = [f"# zswarm tune: {what}",
             f"# command: {command}", "# use it with --params FILE (zswarm run, sim, design, launch.py);",
             f"# its design report (design.txt) is: zswarm design --params FILE {swarm}", "",
             "[params]"]
    lines += [f"{n} = {flat[n]!r}" for n in keep]
    if law:
        lines += ["", "[law]", f"name = {params.law.law!r}", *(f"{k} = {v!r}" for k, v in params.law.settings)]
    tmp = Path(f"{path}.tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, path)


def beats(tuned: dict[str, Any], start: dict[str, Any]) -> bool:
    """Whether the tuned set is better than the start on the held-out seeds (lower objective: mean
    capture time with misses and disqualifications penalised)."""
    return tuned["objective"] is not None and (start["objective"] is None or tuned["objective"] < start["objective"])


def report_md(out: dict[str, Any]) -> str:
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


def failure_counts(records: list[dict[str, Any]]) -> dict[str, int]:
    """How many candidates failed each check (a candidate may fail several; the squeeze runs only for
    one that passes every other check)."""
    return {k: n for k in CHECKS if (n := sum(k in r["failures"] for r in records))}


def faults_text(faults) -> str:
    if not faults.active:
        return "none"
    return f"{faults.latency * 1000:g} ms latency, {faults.jitter * 1000:g} ms jitter, {faults.dropout:g} loss"


def _fmt(v: Any, spec: str = ".3g") -> str:
    return "-" if v is None else format(v, spec)
