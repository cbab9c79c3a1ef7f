"""``zswarm sweep`` (``python launch.py sweep``): run a grid of latency x dropout x repeats, distributed and simulated.

Each cell keeps its own directory (``DIR/cells/<cell>/``): the distributed run's ``run.rrd`` and
``run.json`` and the reference simulator's ``sim.json`` under the same faults and seed. A cell whose
summary exists is finished and is never run again, so an interrupted sweep resumes where it stopped.
At the end the sweep writes ``results.csv``, ``results.md`` (mean and spread over repeats),
``sweep.png`` (capture time and clearance against latency x dropout) and ``sweep.rrd`` (the metric
curves of every cell).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from zswarm.args import Parser, UsageError, seed_arg
from zswarm.files import write_json
from zswarm.model.faults import FaultModel, parse_duration_list
from zswarm.net.runspec import RunSpec

OUTCOMES = ("capture_time", "collisions", "min_obstacle_clearance", "max_components", "final_components",
            "observed_dropout", "observed_latency_ms")


@dataclass(frozen=True)
class Cell:
    latency: float
    dropout: float
    repeat: int

    @property
    def name(self) -> str:
        return f"lat{round(self.latency * 1000)}ms_drop{self.dropout:g}_rep{self.repeat}"


def build_parser(prog: str = "zswarm sweep") -> Parser:
    p = Parser(prog=prog, description="Sweep latency x dropout, distributed and simulated.")
    p.add_argument("--scenario", default="static-goal", help="a registered scenario or a .toml file "
                   "(default static-goal)")
    p.add_argument("--latency", default="0,50,100,200ms",
                   help="one-way latencies, a comma-separated list (default 0,50,100,200ms)")
    p.add_argument("--dropout", default="0,0.2,0.5",
                   help="loss probabilities, a comma-separated list (default 0,0.2,0.5)")
    p.add_argument("--jitter", default="0", help="jitter of every cell, e.g. 10ms (default 0)")
    p.add_argument("--burst", type=float, default=0.0,
                   help="mean loss-burst length of every cell (default 0: independent)")
    p.add_argument("--repeats", type=int, default=3, help="runs per cell, seeds seed..seed+repeats-1 (default 3)")
    p.add_argument("--seed", type=seed_arg, default=0, help="repeat r uses seed + r (default 0)")
    p.add_argument("--agents", type=int, default=None, help="N (default: the scenario's)")
    p.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    p.add_argument("--out", type=Path, required=True, help="output directory (reused to resume)")
    p.add_argument("--sim-only", action="store_true", help="only the reference simulator (fast)")
    return p


def parse_lists(args: argparse.Namespace) -> tuple[list[float], list[float]]:
    try:
        lat = parse_duration_list(args.latency)
        drop = [float(x) for x in args.dropout.split(",") if x.strip()]
        for d in drop:
            FaultModel(dropout=d)
        FaultModel(burst=args.burst)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if not lat or not drop or args.repeats < 1:
        raise UsageError("give at least one latency, one dropout and --repeats >= 1")
    return lat, drop


def cell_spec(cell: Cell, args: argparse.Namespace, jitter: float) -> RunSpec:
    """The run of one cell: the sweep's scenario under the cell's faults, seed + repeat."""
    seed = args.seed + cell.repeat
    return RunSpec(run=f"sweep-{cell.name}".replace(".", "_"), scenario_name=args.scenario,
                   overrides=(("n_agents", args.agents),) if args.agents is not None else (), seed=seed,
                   duration=args.duration, faults=FaultModel(latency=cell.latency, jitter=jitter, dropout=cell.dropout,
                                                             burst=args.burst, seed=seed))


def run_cell_distributed(cell: Cell, args: argparse.Namespace, folder: Path, jitter: float) -> None:
    spec = cell_spec(cell, args, jitter)
    cmd = [sys.executable, "-m", "zswarm", "run", *spec.to_argv(), "--record", str(folder / "run.rrd"),
           "--summary", str(folder / "run.part.json"), "--quiet"]
    res = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"cell {cell.name}: zswarm run exited {res.returncode}: {res.stderr.strip()[-300:]}")
    os.replace(folder / "run.part.json", folder / "run.json")  # the cell is finished only now


def simulate_cell(cell: Cell, args: argparse.Namespace, jitter: float, **kw):
    from zswarm.sim.simulator import simulate

    spec = cell_spec(cell, args, jitter)
    return simulate(spec.scenario, spec.seed, duration=spec.duration, faults=spec.faults, **kw)


def _stats(values: list[Any]) -> tuple[float | None, float | None]:
    nums = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    if not nums:
        return None, None
    return float(np.mean(nums)), float(np.std(nums))


def aggregate(cells: list[Cell], out: Path, sources: Sequence[str]) -> list[dict[str, Any]]:
    rows = []
    keys = sorted({(c.latency, c.dropout) for c in cells})
    for source in sources:
        fname = "run.json" if source == "distributed" else "sim.json"
        for lat, drop in keys:
            summaries = [json.loads((out / "cells" / c.name / fname).read_text()) for c in cells
                         if (c.latency, c.dropout) == (lat, drop) and (out / "cells" / c.name / fname).exists()]
            if not summaries:
                continue
            row: dict[str, Any] = {"source": source, "latency_ms": lat * 1000, "dropout": drop,
                                   "runs": len(summaries),
                                   "capture_rate": np.mean([s["capture_time"] is not None for s in summaries])}
            for k in OUTCOMES:
                vals = [s.get(k) for s in summaries]
                if k == "min_obstacle_clearance":
                    finite = [v for v in vals if v is not None]
                    row[k] = min(finite) if finite else None
                elif k == "max_components":
                    row[k] = max(v for v in vals if v is not None)
                else:
                    row[f"{k}_mean"], row[f"{k}_std"] = _stats(vals)
            rows.append(row)
    return rows


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def write_tables(rows: list[dict[str, Any]], out: Path) -> None:
    if not rows:
        return
    fields = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(rows)
    lines = ["| source | latency ms | dropout | runs | captured | capture time s | collisions | min clearance "
             "| max components | observed loss | observed delay ms |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ct = "-" if r["capture_time_mean"] is None else f"{r['capture_time_mean']:.1f} ± {r['capture_time_std']:.1f}"
        lines.append(f"| {r['source']} | {r['latency_ms']:g} | {r['dropout']:g} | {r['runs']} | "
                     f"{r['capture_rate'] * 100:.0f} % | {ct} | {_fmt(r['collisions_mean'])} | "
                     f"{_fmt(r['min_obstacle_clearance'])} | {r['max_components']} | "
                     f"{_fmt(r['observed_dropout_mean'])} | {_fmt(r['observed_latency_ms_mean'])} |")
    (out / "results.md").write_text("\n".join(lines) + "\n")


def write_curves(cells: list[Cell], args: argparse.Namespace, out: Path, jitter: float) -> None:
    """sweep.rrd: per cell, the centroid-prey distance and the closest pair over time."""
    import rerun as rr
    import rerun.blueprint as rrb

    from zswarm.record.recording import close_recording, open_recording
    from zswarm.record.replay import load_run

    bp = rrb.Blueprint(rrb.Vertical(rrb.TimeSeriesView(origin="centroid_goal_distance"),
                                    rrb.TimeSeriesView(origin="min_pair_distance")), collapse_panels=True)
    rec = open_recording(out / "sweep.rrd", "zswarm-sweep", bp)
    rec.log("config", rr.TextDocument(json.dumps(vars(args), default=str, indent=2)), static=True)
    for cell in cells:
        sim = simulate_cell(cell, args, jitter).metrics
        t = np.asarray(sim.times)
        for metric in ("centroid_goal_distance", "min_pair_distance"):
            rec.send_columns(f"{metric}/sim/{cell.name}", indexes=[rr.TimeColumn("sim_time", duration=t)],
                             columns=rr.Scalars.columns(scalars=np.asarray(sim.series[metric])))
        run_path = out / "cells" / cell.name / "run.rrd"
        if (out / "cells" / cell.name / "run.json").exists():
            frames = [f for f in load_run(run_path).frames if f.prey is not None and len(f.ids)]
            t = np.array([f.t for f in frames])
            cd = np.array([np.linalg.norm(f.positions.mean(axis=0) - f.prey) for f in frames])
            rec.send_columns(f"centroid_goal_distance/distributed/{cell.name}",
                             indexes=[rr.TimeColumn("sim_time", duration=t)], columns=rr.Scalars.columns(scalars=cd))
    close_recording(rec)


def main(argv: Sequence[str] | None, prog: str = "zswarm sweep") -> int:
    args = build_parser(prog).parse_args(argv)
    lat, drop = parse_lists(args)
    from zswarm.model.faults import parse_duration

    try:
        jitter = parse_duration(args.jitter)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    from zswarm.model.scenarios import get_scenario

    get_scenario(args.scenario, {"n_agents": args.agents} if args.agents is not None else {})
    if args.duration is not None and not args.duration > 0:
        raise UsageError(f"--duration must be > 0 (got {args.duration})")
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out} is a file; give a directory (a new one, or a sweep's to resume it)")
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create --out {args.out}: {exc.strerror}") from None
    cells = [Cell(la, d, r) for la in lat for d in drop for r in range(args.repeats)]
    todo = [c for c in cells if not (args.out / "cells" / c.name / "sim.json").exists()
            or (not args.sim_only and not (args.out / "cells" / c.name / "run.json").exists())]
    print(f"sweep: {len(cells)} cells, {len(cells) - len(todo)} already finished", flush=True)
    start = time.monotonic()
    try:
        for k, cell in enumerate(todo, 1):
            folder = args.out / "cells" / cell.name
            folder.mkdir(parents=True, exist_ok=True)
            if not (folder / "sim.json").exists():
                write_json(folder / "sim.json", simulate_cell(cell, args, jitter).summary)
            if not args.sim_only and not (folder / "run.json").exists():
                run_cell_distributed(cell, args, folder, jitter)
            elapsed = time.monotonic() - start
            eta = elapsed / k * (len(todo) - k)
            bar = "#" * int(30 * k / len(todo))
            print(f"[{bar:<30}] {k}/{len(todo)} {cell.name}  elapsed {elapsed:.0f} s  ETA {eta:.0f} s", flush=True)
    except KeyboardInterrupt:
        print("sweep: interrupted; run the same command again to resume", file=sys.stderr, flush=True)
        return 130
    except RuntimeError as exc:
        print(f"sweep: {exc}", file=sys.stderr, flush=True)
        return 1
    sources = ("simulated",) if args.sim_only else ("distributed", "simulated")
    rows = aggregate(cells, args.out, sources)
    write_tables(rows, args.out)
    write_curves(cells, args, args.out, jitter)
    from zswarm.cli.sweep_figure import save_figure

    d_m_ro = cell_spec(cells[0], args, jitter).scenario.params.margins.d_m_ro if cells else None
    save_figure(rows, args.out / "sweep.png", args.scenario, d_m_ro)
    print(f"sweep: wrote {args.out / 'results.md'}, {args.out / 'results.csv'}, {args.out / 'sweep.png'} and "
          f"{args.out / 'sweep.rrd'}")
    return 0
