"""Do the design checks predict what the swarm does? The study behind ``zswarm bench guidelines``.

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

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from zswarm.paper.params import FIELDS, ParamError, Params

INTERACTIONS = ("paper", "mean", "gate", "nearest", "cutoff", "mean+gate", "mean+gate+cutoff", "mean+nearest")
POTENTIAL = [name for name, spec in FIELDS.items() if spec.group == "potential"]



def sample_set(rng: np.random.Generator, base: Params, spread: float) -> Params:
    """One random set around ``base``; drawn again until it is a valid parameter set that its interaction
    can use (the gate needs a pair spacing)."""
    from zswarm.paper.neighbour_law import neighbour_law

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
    from zswarm.design.guidelines import check
    from zswarm.swarm.scenarios import get_scenario
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


def cases(scenarios: list[str], agents: list[int], sets: int, spread: float, seed: int) -> list[Case]:
    """For each scenario and N: its own set, the same with the paper's interaction, ``sets`` random ones."""
    from zswarm.swarm.scenarios import get_scenario

    rng = np.random.default_rng(seed)
    out = []
    for name in scenarios:
        for n in agents:
            base = get_scenario(name, {"n_agents": n}).params
            chosen = [base, base.with_values({"interaction": "paper"})]
            chosen += [sample_set(rng, base, spread) for _ in range(sets)]
            out += [Case(name, n, k, s) for k, s in enumerate(chosen)]
    return out


def run_study(todo: list[Case], seeds: int, workers: int, progress: Callable[[str], None]) -> list[dict[str, Any]]:
    """Every case judged and run in a pool of ``workers`` processes, the largest N first (so the slowest
    sets do not come last); the rows in (scenario, N, index) order."""
    from multiprocessing import get_context

    start = time.time()
    tasks = sorted(((c, seeds) for c in todo), key=lambda t: -t[0].n)
    rows = []
    with get_context("fork").Pool(workers) as pool:
        for k, row in enumerate(pool.imap_unordered(judge_and_run, tasks, chunksize=1), 1):
            rows.append(row)
            if k % max(1, len(tasks) // 20) == 0:
                progress(f"{k}/{len(tasks)} sets ({time.time() - start:.0f} s)")
    rows.sort(key=lambda r: (r["scenario"], r["n"], r["index"]))
    return rows


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
