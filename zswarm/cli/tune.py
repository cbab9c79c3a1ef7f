"""``zswarm tune``: the parameters the design guidelines allow that catch the prey fastest on a network.

CMA-ES searches the potential parameters in log space (:mod:`zswarm.tune.search`); every candidate
that fails ``zswarm design`` is rejected before it is simulated; the others run on K seeds under the
given faults in the batched simulator. This module checks the settings and reports;
:mod:`zswarm.tune.pipeline` runs the search and says what it writes in ``--out DIR``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from zswarm.args import add_law_arg, add_param_args, non_negative, positive_float, positive_int, seed_arg, sim_seconds
from zswarm.errors import UsageError
from zswarm.files import write_json
from zswarm.paper.params import parse_assignments
from zswarm.paper.potentials import COMBINATIONS
from zswarm.swarm.scenarios import SCENARIOS, get_scenario
from zswarm.tune.feasibility import CHECKS
from zswarm.tune.pipeline import HOLDOUT_OFFSET, VALIDATION_OFFSET, Plan
from zswarm.tune.space import TUNABLE

DESCRIPTION = (
    "Search the potential parameters (CMA-ES, in log space) for the set that catches the prey fastest "
    "under the given network faults, with the paper's design guidelines as hard constraints. "
    "Objective: the mean over --seeds K runs of the capture time, a run that never catches the prey "
    "counting as its duration plus --miss-penalty. A set whose runs have any collision (agents closer "
    "than 2 d^r), obstacle contact, or clearance below d_m^ro is disqualified; a set that fails zswarm "
    "design (Props 1-5, formation, contact, swarm squeeze; see --waive) is never simulated. "
    "Resumes from --out DIR after an interruption; deterministic for a given --seed. "
    "Exit 0 with a set that beats the start, 1 when no set passed or none beat the start on the held-out seeds "
    "(best.toml then keeps the start), 2 on a usage error.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from zswarm.net.runspec import add_fault_args

    parser.add_argument("--scenario", default="moving-prey-blocked",
                        help=f"a registered scenario ({', '.join(SCENARIOS)}) or a .toml file "
                             "(default moving-prey-blocked)")
    add_param_args(parser)
    add_law_arg(parser)
    parser.add_argument("--tune", default=None, metavar="NAMES",
                        help=f"comma-separated parameters to search (apf: potential ones, default all, "
                             f"{','.join(TUNABLE)}; another law: those it declares ranges for, default all, "
                             "zswarm laws); the others keep the scenario's (or --set) value")
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
    parser.add_argument("--duration", type=sim_seconds, default=None, help="simulated seconds per run "
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


def _plan(args: argparse.Namespace):
    """The checked settings: the plan, the search space, the task each candidate is judged on, the faults."""
    from zswarm.design.guidelines import has_guidelines
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
    names = [n.strip() for n in args.tune.split(",") if n.strip()] if args.tune else None
    space = Space.build(names, scenario.params)
    faults = faults_from_args(args)
    plan = Plan.of(args.scenario, overrides, list(space.names), args.seed, args.seeds, args.validate, args.holdout, args.out)
    safety = "off" if has_guidelines(scenario.params.law.law) else "barrier"  # none: the filter is the guarantee
    return plan, space, Task(scenario, plan.seeds, faults, args.potential, args.miss_penalty, safety), faults


def run(args: argparse.Namespace) -> int:
    from zswarm.cli.tune_confirm import confirm
    from zswarm.cli.tune_print import Bar, print_failure, print_result
    from zswarm.design.text import render
    from zswarm.tune.pipeline import choose, finish, no_set, search_phase

    plan, space, task, faults = _plan(args)
    command = "zswarm tune " + " ".join(sys.argv[2:] if sys.argv[1:2] == ["tune"] else sys.argv[1:])
    bar = Bar(quiet=args.json, seeds=len(task.seeds), miss_s=task.duration + task.miss_penalty)
    try:
        s = search_phase(plan, space, task, faults, args, bar, command)
    finally:
        bar.done()
    if not s.chosen:
        no_set(s, plan)
        print_failure(s.out, args)
        return 1
    sets = choose(s, plan, space, task, faults, command, render)
    if args.confirm:
        try:
            s.out["confirm"] = confirm(plan, args, sets, faults, quiet=args.json)
        except RuntimeError as exc:  # a distributed run failed: say which, keep what was written
            write_json(plan.out / "result.json", s.out)
            print(f"zswarm tune: {exc}", file=sys.stderr)
            return 1
        write_json(plan.out / "confirm.json", s.out["confirm"])
    finish(s, plan)
    if args.json:
        print(json.dumps(s.out, default=str))
    else:
        print_result(s.out, plan, faults)
    if s.out["recommended"] != "tuned":
        t, st = s.out["comparison"]["as_tuned"]["tuned"], s.out["comparison"]["as_tuned"]["start"]
        print(f"zswarm tune: the chosen set does not beat the start on the held-out seeds (objective "
              f"{t['objective']:.2f} s, caught {t['captured']}/{t['runs']}, against {st['objective']:.2f} s, "
              f"{st['captured']}/{st['runs']}): {plan.out}/best.toml keeps the start; a larger --budget or more "
              f"--seeds may find better", file=sys.stderr)
        return 1
    return 0
