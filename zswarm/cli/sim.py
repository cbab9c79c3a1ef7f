"""``zswarm sim``, ``zswarm scenarios`` and ``zswarm bench sim``: the reference simulator's commands."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from zswarm.args import add_law_arg, add_param_args, agent_count, loss_probability, positive_int, seed_arg, sim_seconds
from zswarm.paper.params import parse_assignments
from zswarm.paper.potentials import COMBINATIONS
from zswarm.swarm.scenarios import SCENARIOS, get_scenario


def add_sim_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="static-goal",
                        help=f"a registered scenario ({', '.join(SCENARIOS)}) or a .toml file (default static-goal, "
                             "the paper's Fig 13; zswarm run's default is moving-prey, the demo)")
    parser.add_argument("--seed", type=seed_arg, default=0, help="random seed (spawn positions); default 0")
    add_param_args(parser)
    add_law_arg(parser)
    parser.add_argument("--potential", choices=COMBINATIONS, default=None,
                        help="obstacle-goal combination: additive (eq 12) or multiplicative (eq 14); "
                             "default: the scenario's")
    parser.add_argument("--duration", type=sim_seconds, default=None, help="simulated time, e.g. 30 or 30s")
    parser.add_argument("--agents", type=agent_count, default=None, metavar="N",
                        help="N agents (the same as --set n_agents=N, and zswarm run's --agents)")
    parser.add_argument("--record", type=Path, metavar="FILE.rrd", help="write a Rerun recording")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --record file")
    parser.add_argument("--record-every", type=positive_int, default=1, metavar="K",
                        help="log every K-th step to the recording (default 1)")
    parser.add_argument("--sensing-discs", action="store_true", help="draw each agent's sensing disc")
    parser.add_argument("--sensing-graph", choices=("auto", "on", "off"), default="auto",
                        help="draw who senses whom in the recording's map (auto: for N <= 100)")
    from zswarm.record.live import add_viewer_args

    add_viewer_args(parser, zenoh=False)
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    parser.add_argument("--require-design", action="store_true",
                        help="refuse to start (exit 2) when the set this run would use fails zswarm design")
    from zswarm.net.runspec import add_fault_args, add_safety_arg

    add_safety_arg(parser)
    add_fault_args(parser)


def run_sim(args: argparse.Namespace) -> int:
    from zswarm.net.runspec import faults_from_args, safety_mode
    from zswarm.record.live import viewer_from_args
    from zswarm.sim.simulator import cost_note, simulate
    from zswarm.args import UsageError
    from zswarm.control.step import control_step
    from zswarm.design.guidelines import judged
    from zswarm.files import check_writable

    if args.record is not None and args.record.is_file() and not args.force:
        raise UsageError(f"{args.record} exists; give another path or --force")
    record = args.record and check_writable(args.record, (".rrd",))  # the file and the viewer before the design
    viewer = viewer_from_args(args)
    agents = {"n_agents": args.agents} if args.agents is not None else {}
    scenario = get_scenario(args.scenario, {**parse_assignments(args.assignments), **agents})
    note = cost_note(scenario, args.duration if args.duration is not None else scenario.duration)  # or refused
    scenario.check_placement()  # before the design check, which takes seconds at large N
    control_step([scenario], [args.potential], args.safety or "off", probe=True)  # a bad law or filter: one line
    if note:
        print(note, file=sys.stderr, flush=True)
    explain = " ".join(["zswarm design --scenario", args.scenario, *(f"--set {a}" for a in args.assignments)])
    design, line = judged(scenario.params, scenario.dt, explain, args.require_design,
                          safety_mode(args.safety))
    if line is not None:
        print(line, file=sys.stderr, flush=True)
    faults, safety = faults_from_args(args), safety_mode(args.safety)
    result = simulate(scenario, args.seed, combination=args.potential, duration=args.duration,
                      record=record, record_every=args.record_every,
                      sensing_discs=args.sensing_discs, faults=faults, viewer=viewer,
                      sensing_graph={"auto": None, "on": True, "off": False}[args.sensing_graph], safety=safety)
    result.summary["design"] = design
    if args.json:
        print(json.dumps(result.summary, sort_keys=True))
    else:
        for key, value in result.summary.items():
            print(f"{key:>30}: {value}")
        if args.record is not None:
            print(f"recorded to {args.record} (open with: rerun {args.record})")
    return 0


def run_scenarios(args: argparse.Namespace) -> int:
    rows = [get_scenario(name) for name in SCENARIOS]
    if args.json:
        print(json.dumps([{"name": s.name, "n_agents": s.n_agents, "prey": s.prey.kind,
                           "obstacles": len(s.obstacles), "interaction": s.params.interaction.interaction,
                           "description": s.description} for s in rows]))
        return 0
    for s in rows:
        print(f"{s.name:<22} N={s.n_agents:<4} prey={s.prey.kind:<9} obstacles={len(s.obstacles):<3} "
              f"{s.params.interaction.interaction:<10} {s.description}")
    print("\n--set n_agents=N grows a scenario by the rule of docs/scaling.md")
    return 0


def run_bench_sim(args: argparse.Namespace) -> int:
    from zswarm.provenance import machine
    from zswarm.sim.simulator import Simulator

    if args.batch is not None:
        from zswarm.cli.bench_batch import run_bench_batch

        return run_bench_batch(args)
    runs = []
    for n in args.sizes:
        scenario = get_scenario("large-swarm", {"n_agents": n})
        steps = (args.steps or 1000) if n <= 1000 else max((args.steps or 1000) // 10, 20)
        sim = Simulator(scenario, seed=0)
        start = time.perf_counter()
        for _ in range(steps):
            sim.advance(sim.command())
        seconds = time.perf_counter() - start
        runs.append({"n_agents": n, "steps": steps, "seconds": seconds, "steps_per_second": steps / seconds})
        if not args.json:
            print(f"N={n:>6}  {steps:>5} steps  {seconds:8.3f} s  {steps / seconds:10.1f} steps/s")
    per_step = {r["n_agents"]: r["seconds"] / r["steps"] for r in runs}
    ratio = per_step[10000] / per_step[1000] if {1000, 10000} <= per_step.keys() else None
    out = {"runs": runs, "cost_ratio_10000_1000": ratio, "machine": machine()}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"cost per step N=10000 : N=1000 = {ratio:.2f}" if ratio else "")
        print(f"machine: {out['machine']}")
    return 0


def add_bench_sim_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sizes", type=lambda s: [positive_int(x) for x in s.split(",")],
                        default=[10, 100, 1000, 10000], help="comma-separated N (default 10,100,1000,10000)")
    parser.add_argument("--steps", type=positive_int, default=None,
                        help="steps for N <= 1000 (default 1000; a tenth of it, at least 20, above); "
                             "with --batch, steps of every run (default 200)")
    parser.add_argument("--batch", type=positive_int, default=None, metavar="B",
                        help="instead: B runs of --scenario (seeds 0..B-1, every second one through the "
                             "faulty channel) stepped together by the batched simulator, against the same "
                             "B runs one by one")
    parser.add_argument("--scenario", default="moving-prey", help="with --batch (default moving-prey)")
    parser.add_argument("--latency", default="100ms", help="with --batch: the faulty runs' delay (default 100ms)")
    parser.add_argument("--dropout", type=loss_probability, default=0.3,
                        help="with --batch: the faulty runs' loss probability (default 0.3)")
    parser.add_argument("--json", action="store_true")

