"""A sweep's cells: each the scenario under one latency x dropout x repeat, run distributed and simulated.

Each cell keeps its own directory (``DIR/cells/<cell>/``): the distributed run's ``run.rrd`` and
``run.json`` (:func:`zswarm.launch.run_once.run_once`) and the reference simulator's ``sim.json``
under the same faults and seed (every cell's simulation stepped at once: :func:`simulate_cells`). :func:`aggregate` folds the finished cells into rows (mean and spread
over repeats), :func:`write_tables` and :func:`write_curves` write ``results.csv``, ``results.md`` and
``sweep.rrd``. ``zswarm sweep`` (:mod:`zswarm.cli.sweep`) drives them.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from zswarm.launch.run_once import run_once
from zswarm.swarm.faults import FaultModel
from zswarm.net.runspec import RunSpec

OUTCOMES = ("capture_time", "collisions", "min_obstacle_clearance", "max_components", "final_components",
            "observed_dropout", "observed_latency_ms")


@dataclass(frozen=True)
class Cell:
    latency: float
    dropout: float
    repeat: int
    safety: str = "barrier"

    @property
    def name(self) -> str:
        return f"lat{round(self.latency * 1000)}ms_drop{self.dropout:g}_rep{self.repeat}_{self.safety}"


def cell_spec(cell: Cell, args: argparse.Namespace, jitter: float) -> RunSpec:
    """The run of one cell: the sweep's scenario under the cell's faults, seed + repeat."""
    seed = args.seed + cell.repeat
    return RunSpec(run=f"sweep-{cell.name}".replace(".", "_"), scenario_name=args.scenario,
                   overrides=tuple(getattr(args, "overrides", {}).items()) or
                   ((("n_agents", args.agents),) if args.agents is not None else ()), seed=seed,
                   duration=args.duration, faults=FaultModel(latency=cell.latency, jitter=jitter, dropout=cell.dropout,
                                                             burst=args.burst, seed=seed), safety=cell.safety)


def run_cell_distributed(cell: Cell, args: argparse.Namespace, folder: Path, jitter: float) -> None:
    pauses = [a for p in getattr(args, "pause", ()) for a in ("--pause", str(p))]
    run_once(cell_spec(cell, args, jitter), folder / "run.rrd", folder / "run.json", f"cell {cell.name}", pauses)


def simulate_cell(cell: Cell, args: argparse.Namespace, jitter: float, **kw):
    from zswarm.sim.simulator import simulate

    spec = cell_spec(cell, args, jitter)
    return simulate(spec.scenario, spec.seed, duration=spec.duration, faults=spec.faults, safety=spec.safety, **kw)


def simulate_cells(cells: list[Cell], args: argparse.Namespace, jitter: float) -> list[dict[str, Any]]:
    """Every cell's reference simulation, stepped together by the batched simulator (one array program,
    :mod:`zswarm.sim.batch`; each run as it is alone, up to the order of sums), as summaries; a swarm too
    large for it, one cell at a time."""
    from zswarm.laws.registry import bind
    from zswarm.sim.batch import MAX_AGENTS, Member, simulate_batch

    specs = [cell_spec(c, args, jitter) for c in cells]
    if not specs:
        return []
    scenario = specs[0].scenario
    if scenario.n_agents > MAX_AGENTS:
        return [simulate_cell(c, args, jitter).summary for c in cells]
    steps = int(round((specs[0].duration or scenario.duration) / scenario.dt))
    members = [Member(s.scenario, s.seed, s.faults if s.faults.active else None, safety=s.safety) for s in specs]
    outcomes = simulate_batch(members, steps, components=True).outcomes
    law = bind(scenario, probe=False).describe()  # what the swarm ran (a mixed swarm's groups: in each outcome)
    return [{"scenario": s.scenario.name, "seed": s.seed, "duration": steps * scenario.dt, "safety": s.safety,
             "law": law, "simulator": "batched", **o.to_dict()} for s, o in zip(specs, outcomes)]


def _stats(values: list[Any]) -> tuple[float | None, float | None]:
    nums = [float(v) for v in values if isinstance(v, (int, float)) and math.isfinite(v)]
    if not nums:
        return None, None
    return float(np.mean(nums)), float(np.std(nums))


def aggregate(cells: list[Cell], out: Path, sources: Sequence[str]) -> list[dict[str, Any]]:
    rows = []
    keys = sorted({(c.latency, c.dropout, c.safety) for c in cells})
    for source in sources:
        fname = "run.json" if source == "distributed" else "sim.json"
        for lat, drop, safety in keys:
            summaries = [json.loads((out / "cells" / c.name / fname).read_text()) for c in cells
                         if (c.latency, c.dropout, c.safety) == (lat, drop, safety)
                         and (out / "cells" / c.name / fname).exists()]
            if not summaries:
                continue
            row: dict[str, Any] = {"source": source, "latency_ms": lat * 1000, "dropout": drop, "safety": safety,
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
            if summaries[0].get("groups"):  # a mixed swarm: each group's own tally, over the same runs
                row["groups"] = [_group_row(k, g, summaries) for k, g in enumerate(summaries[0]["groups"]) if g]
            rows.append(row)
    return rows


def _group_row(k: int, group: dict[str, Any], summaries: list[dict[str, Any]]) -> dict[str, Any]:
    """Group ``k`` of a mixed swarm over ``summaries``: who it is, its mean collisions, its closest pair."""
    tallies = [s["groups"][k] for s in summaries if len(s.get("groups") or []) > k and s["groups"][k]]
    closest = [t["min_pair_distance"] for t in tallies if t.get("min_pair_distance") is not None]
    return {"agents": group["agents"], "law": group["law"], "body": group["body"],
            "collisions_mean": _stats([t["collisions"] for t in tallies])[0], "min_pair_distance": min(closest, default=None)}


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def write_tables(rows: list[dict[str, Any]], out: Path) -> None:
    if not rows:
        return
    fields = list(dict.fromkeys(k for r in rows for k in r if k != "groups"))
    with open(out / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    lines = ["| source | latency ms | dropout | safety | runs | captured | capture time s | collisions | min clearance "
             "| max components | observed loss | observed delay ms |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ct = "-" if r["capture_time_mean"] is None else f"{r['capture_time_mean']:.1f} ± {r['capture_time_std']:.1f}"
        lines.append(f"| {r['source']} | {r['latency_ms']:g} | {r['dropout']:g} | {r['safety']} | {r['runs']} | "
                     f"{r['capture_rate'] * 100:.0f} % | {ct} | {_fmt(r['collisions_mean'])} | "
                     f"{_clearance(r['min_obstacle_clearance'])} | {r['max_components']} | "
                     f"{_fmt(r['observed_dropout_mean'])} | {_fmt(r['observed_latency_ms_mean'])} |")
    lines += ["", "min clearance: the closest any agent came to an obstacle's edge (m); \"none sensed\": no agent came "
              "within its sensing radius of one."]
    if any(r.get("groups") for r in rows):
        lines += ["", "Each group of the mixed swarm (a pair of two groups counts for both):", "",
                  "| source | latency ms | dropout | safety | agents | law | body | collisions | closest pair |",
                  "|---|---|---|---|---|---|---|---|---|"]
        lines += [f"| {r['source']} | {r['latency_ms']:g} | {r['dropout']:g} | {r['safety']} | {g['agents']} | {g['law']} "
                  f"| {g['body']} | {_fmt(g['collisions_mean'])} | {_fmt(g['min_pair_distance'])} |"
                  for r in rows for g in r.get("groups") or []]
    (out / "results.md").write_text("\n".join(lines) + "\n")


def _clearance(v: float | None) -> str:
    """An obstacle clearance, or what its absence means: no agent ever sensed an obstacle."""
    return "none sensed" if v is None else _fmt(v)


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
