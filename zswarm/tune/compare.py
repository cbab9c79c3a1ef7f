"""The chosen set against the starting set on seeds the search never saw, in the batched simulator, judged
by the tune's own rule (:func:`zswarm.tune.objective.disqualified`)."""

from __future__ import annotations

from typing import Any

from zswarm.paper.params import Params


def held_out(task, sets: dict[str, Params], seeds: tuple[int, ...]) -> dict[str, dict[str, Any]]:
    """Each set on the held-out seeds: outcomes and their aggregate."""
    from zswarm.tune.objective import evaluate, run_score

    labels = list(sets)
    results = evaluate(task, [sets[k] for k in labels], seeds)
    out = {}
    for label, (value, outcomes, reasons) in zip(labels, results):
        out[label] = aggregate([o.to_dict() for o in outcomes], seeds, reasons,
                               [run_score(o, task) for o in outcomes], value)
    return out


def aggregate(runs: list[dict[str, Any]], seeds, reasons, scores, objective) -> dict[str, Any]:
    caught = [r["capture_time"] for r in runs if r["capture_time"] is not None]
    clearances = [r["min_obstacle_clearance"] for r in runs if r["min_obstacle_clearance"] is not None]
    return {"runs": len(runs), "captured": len(caught),
            "mean_capture_time": sum(caught) / len(caught) if caught else None,
            "mean_score": sum(scores) / len(scores) if scores else None, "objective": objective,
            "collisions": sum(r["collisions"] for r in runs),
            "obstacle_collisions": sum(r["obstacle_collisions"] for r in runs),
            "min_obstacle_clearance": min(clearances) if clearances else None,
            "min_pair_distance": min(r["min_pair_distance"] for r in runs),
            "disqualified": sum(r is not None for r in reasons),
            "per_seed": [{**r, "seed": s, "disqualified": why} for r, s, why in zip(runs, seeds, reasons)]}
