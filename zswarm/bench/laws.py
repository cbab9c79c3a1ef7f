"""``zswarm bench laws``: the laws side by side on the same scenario, seeds and faults, in the
reference simulator, with and without the safety filter.

Each row is one law under one latency (with the dropout given) and one filter mode, over seeds
0..K-1: collisions (onsets, summed), the closest pair, how many runs caught the prey or reached the
goal and their median time, the order parameter (|sum v_i| / sum |v_i|, averaged over the run), the
groups of the sensing graph at the end (the most over the seeds), stalls (agents the filter held still
for a second or more, summed) and the filter's interventions (agent-steps it changed, summed).
"""

from __future__ import annotations


from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Case:
    scenario: str
    law: str
    latency: float  # s
    dropout: float
    safety: str
    seed: int
    agents: int | None
    extra: tuple[tuple[str, Any], ...] = ()
    duration: float | None = None


def run_case(case: Case) -> dict[str, Any]:
    """One run of the reference simulator: the figures a row sums up."""
    from zswarm.swarm.faults import FaultModel
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.simulator import simulate

    overrides = {**dict(case.extra), "law": case.law, **({"n_agents": case.agents} if case.agents else {})}
    scenario = get_scenario(case.scenario, overrides)
    faults = FaultModel(latency=case.latency, dropout=case.dropout, seed=case.seed)
    result = simulate(scenario, case.seed, faults=faults, safety=case.safety, duration=case.duration)
    s, order = result.summary, np.asarray(result.metrics.series["order"])
    return {"law": case.law, "latency": case.latency, "safety": case.safety, "seed": case.seed,
            "collisions": s["collisions"], "closest_pair": s["min_pair_distance"], "capture_time": s["capture_time"],
            "order": float(order.mean()) if len(order) else None, "groups": s["final_components"],
            "stalls": s.get("safety_stalled_agents", 0), "interventions": s.get("safety_interventions", 0)}


def row(runs: list[dict[str, Any]], dropout: float) -> dict[str, Any]:
    """The runs of one law, latency and filter mode, summed up."""
    caught = [r["capture_time"] for r in runs if r["capture_time"] is not None]
    orders = [r["order"] for r in runs if r["order"] is not None]
    first = runs[0]
    return {"law": first["law"], "latency": first["latency"], "dropout": dropout, "safety": first["safety"],
            "runs": len(runs), "collisions": sum(r["collisions"] for r in runs),
            "closest_pair": min(r["closest_pair"] for r in runs), "reached": len(caught),
            "capture_median": float(np.median(caught)) if caught else None,
            "order": float(np.mean(orders)) if orders else None, "groups": max(r["groups"] for r in runs),
            "stalls": sum(r["stalls"] for r in runs), "interventions": sum(r["interventions"] for r in runs)}


def table(rows: list[dict[str, Any]]) -> list[str]:
    """The rows as a Markdown table (docs/laws.md)."""
    out = ["| law | latency | safety | collisions | closest pair | reached | capture (median s) | order | groups "
           "| stalls | interventions |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cap = "-" if r["capture_median"] is None else f"{r['capture_median']:.1f}"
        order = "-" if r["order"] is None else f"{r['order']:.2f}"
        out.append(f"| {r['law']} | {r['latency'] * 1000:g} ms | {r['safety']} | {r['collisions']} | "
                   f"{r['closest_pair']:.3f} | {r['reached']}/{r['runs']} | {cap} | {order} | {r['groups']} | "
                   f"{r['stalls']} | {r['interventions']} |")
    return out
