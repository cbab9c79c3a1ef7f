"""``zswarm bench guidelines``: do the design checks predict what the swarm does?

For each scenario and N: the scenario's own (scaled) set, the same with the paper's interaction, and
K random sets around it (each potential value times a factor drawn log-uniformly in [1/S, S], a
random interaction, gate and k). Each set is judged by ``zswarm design`` (the checks for that N, R,
interaction and time step) and simulated on a few seeds. A set *collides* if any of its runs has a
collision. The number that matters is **false-safe**: sets the checker passes that collide (target 0).
How conservative the checker is: sets it fails that never collide.

Runs go through :func:`zswarm.sim.outcome.run_outcome` (the reference simulator with a lean tally,
stopped at a run's first collision: whether a set collides is what is asked) in a pool of processes,
one per core. The batched simulator would step the runs of one N together, but its dense pairs cost
B N^2 a step, and at N >= 100 the reference simulator's cell grid on every core is faster.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.args import UsageError, positive_float, positive_int, seed_arg
from zswarm.model.params import FIELDS, ParamError, Params

DESCRIPTION = __doc__.split("\n\n")[1]
INTERACTIONS = ("paper", "mean", "gate", "nearest", "cutoff", "mean+gate", "mean+gate+cutoff", "mean+nearest")
POTENTIAL = [name for name, spec in FIELDS.items() if spec.group == "potential"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    ints = lambda t: [positive_int(x) for x in t.split(",")]  # noqa: E731
    p.add_argument("--scenarios", type=lambda t: t.split(","), default=["moving-prey", "large-swarm"],
                   help="comma-separated scenarios (default moving-prey,large-swarm)")
    p.add_argument("--agents", type=ints, default=[10, 30, 100, 300], help="N values (default 10,30,100,300)")
    p.add_argument("--sets", type=positive_int, default=24, help="random sets per scenario and N (default 24)")
    p.add_argument("--seeds", type=positive_int, default=2, help="runs per set (default 2)")
    p.add_argument("--spread", type=positive_float, default=3.0,
                   help="each potential value is scaled by a factor in [1/S, S] (default 3)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seed of the sampling (default 0)")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1, help="processes (default: cores)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="write study.json (every set and run) and guidelines.png there")
    p.add_argument("--json", action="store_true", help="print the table as JSON")


def sample_set(rng: np.random.Generator, base: Params, spread: float) -> Params:
    """One random set around ``base``; drawn again until it is a valid parameter set that its interaction
    can use (the gate needs a pair spacing)."""
    from zswarm.model.neighbour_law import neighbour_law

    while True:
        change: dict[str, Any] = {n: float(base.flat()[n]) * math.exp(rng.uniform(-1, 1) * math.log(spread))
                                  for n in POTENTIAL if float(base.flat()[n]) > 0}
        change["interaction"] = str(rng.choice(INTERACTIONS))
        change["gate"] = float(rng.uniform(0.5, 1.0))
        change["k_nearest"] = int(rng.integers(3, 13))
        try:
            params = base.with_values(change)
            neighbour_law(params)
            return params
        except ParamError:
            continue


@dataclass(frozen=True)
class Case:
    scenario: str
    n: int
    index: int  # 0: the scenario's own set; 1: it with the paper's interaction; then random
    params: Params


def judge_and_run(task: tuple[Case, int]) -> dict[str, Any]:
    """One set: its design verdict, and its runs on seeds 0..seeds-1 (in a worker process)."""
    from zswarm.model.design import check
    from zswarm.model.scenarios import get_scenario
    from zswarm.sim.outcome import run_outcome

    case, seeds = task
    scenario = get_scenario(case.scenario, {"n_agents": case.n}).with_params(case.params)
    report = check(case.params, dt=scenario.dt)
    runs = [run_outcome(scenario, seed, stop_at_collision=True).to_dict() for seed in range(seeds)]
    return {"scenario": case.scenario, "n": case.n, "index": case.index, "params": case.params.flat(),
            "design_ok": report.ok, "failures": report.failures(),
            "collided": any(r["collisions"] > 0 for r in runs),
            "one_group": all(r["final_components"] == 1 for r in runs),
            "reached": all(r["capture_time"] is not None for r in runs),
            "min_pair_distance": min(r["min_pair_distance"] for r in runs), "runs": runs}


def cases(args: argparse.Namespace) -> list[Case]:
    from zswarm.model.scenarios import get_scenario

    rng = np.random.default_rng(args.seed)
    out = []
    for name in args.scenarios:
        for n in args.agents:
            base = get_scenario(name, {"n_agents": n}).params
            sets = [base, base.with_values({"interaction": "paper"})]
            sets += [sample_set(rng, base, args.spread) for _ in range(args.sets)]
            out += [Case(name, n, k, s) for k, s in enumerate(sets)]
    return out


def table(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Verdict against outcome, per scenario and N and over all."""
    out = []
    keys = sorted({(r["scenario"], r["n"]) for r in rows}) + [("all", 0)]
    for scenario, n in keys:
        sel = [r for r in rows if scenario == "all" or (r["scenario"], r["n"]) == (scenario, n)]
        passed = [r for r in sel if r["design_ok"]]
        failed = [r for r in sel if not r["design_ok"]]
        out.append({
            "scenario": scenario, "n": n, "sets": len(sel), "passed": len(passed),
            "false_safe": sum(r["collided"] for r in passed),
            "passed_clean": sum(not r["collided"] for r in passed),
            "failed_collided": sum(r["collided"] for r in failed),
            "conservative": sum(not r["collided"] for r in failed),
            "passed_one_group": sum(r["one_group"] for r in passed),
            "passed_reached": sum(r["reached"] for r in passed),
        })
    return out


def run(args: argparse.Namespace) -> int:
    from multiprocessing import get_context

    from zswarm.model.scenarios import SCENARIOS
    from zswarm.provenance import machine, versions

    for name in args.scenarios:
        if name not in SCENARIOS:
            raise UsageError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}")
    if args.out is not None:
        from zswarm.files import check_writable

        args.out.mkdir(parents=True, exist_ok=True)
        check_writable(args.out / "study.json")
    start = time.time()
    todo = cases(args)
    # the largest N first, so the slowest sets do not come last
    tasks = sorted(((c, args.seeds) for c in todo), key=lambda t: -t[0].n)
    print(f"guidelines: {len(todo)} sets x {args.seeds} seeds on {args.workers} processes", file=sys.stderr,
          flush=True)
    rows = []
    with get_context("fork").Pool(args.workers) as pool:
        for k, row in enumerate(pool.imap_unordered(judge_and_run, tasks, chunksize=1), 1):
            rows.append(row)
            if k % max(1, len(tasks) // 20) == 0:
                print(f"guidelines: {k}/{len(tasks)} sets ({time.time() - start:.0f} s)", file=sys.stderr, flush=True)
    rows.sort(key=lambda r: (r["scenario"], r["n"], r["index"]))
    result = {"table": table(rows), "settings": {k: (str(v) if isinstance(v, Path) else v)
                                                 for k, v in vars(args).items() if k != "run"},
              "machine": machine(), "versions": versions(), "seconds": time.time() - start}
    if args.out is not None:
        (args.out / "study.json").write_text(json.dumps({**result, "sets": rows}, indent=1))
        from zswarm.cli.guidelines_figure import save_figure

        robot = rows[0]["params"]["robot_radius"] if rows else 0.05
        save_figure(result["table"], rows, args.out / "guidelines.png", 2.0 * float(robot))
    if args.json:
        print(json.dumps(result))
    else:
        print(render(result["table"]))
        print(f"machine: {result['machine']}; {result['seconds']:.0f} s")
    return 0


def render(rows: list[dict[str, Any]]) -> str:
    head = (f"{'scenario':<13} {'N':>4} {'sets':>5} {'pass':>5} {'FALSE-SAFE':>10} {'pass ok':>8} "
            f"{'fail coll':>9} {'conservative':>12} {'pass 1 group':>12} {'pass reached':>12}")
    lines = [head]
    for r in rows:
        lines.append(f"{r['scenario']:<13} {r['n'] or '':>4} {r['sets']:>5} {r['passed']:>5} {r['false_safe']:>10} "
                     f"{r['passed_clean']:>8} {r['failed_collided']:>9} {r['conservative']:>12} "
                     f"{r['passed_one_group']:>12} {r['passed_reached']:>12}")
    return "\n".join(lines)
