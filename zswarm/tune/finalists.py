"""Choosing the best set without the winner's curse: the search's best few, re-run on fresh seeds.

Among hundreds of candidates judged on K seeds each, the lowest objective is partly luck: a set that
collides once in five runs passes four seeds a third of the time. So the ``count`` best distinct
qualified candidates of the search are run again on validation seeds (never used by the search, nor by
the held-out comparison), all in one batch, and the one with the best validation objective is chosen.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from zswarm.tune.objective import Task, evaluate
from zswarm.tune.space import Space


def finalists(records: list[dict[str, Any]], count: int, qualified_below: float) -> list[dict[str, Any]]:
    """The ``count`` best qualified candidates (lowest objective, first found among equals), distinct."""
    seen: set[tuple[float, ...]] = set()
    out = []
    for r in sorted((r for r in records if r.get("objective", np.inf) < qualified_below),
                    key=lambda r: r["objective"]):
        key = tuple(r["x"])
        if key not in seen:
            seen.add(key)
            out.append(r)
        if len(out) == count:
            break
    return out


def validate(task: Task, space: Space, chosen: list[dict[str, Any]], seeds: tuple[int, ...]
             ) -> list[dict[str, Any]]:
    """Each finalist on ``seeds``: its search objective, validation objective and disqualified runs,
    best first (the search's order among equals)."""
    results = evaluate(task, [space.params(np.array(r["x"])) for r in chosen], seeds)
    rows = []
    for rank, (r, (value, outcomes, reasons)) in enumerate(zip(chosen, results)):
        rows.append({"search_rank": rank, "gen": r["gen"], "slot": r["slot"], "x": r["x"], "values": r["values"],
                     "search_objective": r["objective"], "validation_objective": value,
                     "validation_disqualified": sum(why is not None for why in reasons),
                     "validation_captured": sum(o.capture_time is not None for o in outcomes)})
    return sorted(rows, key=lambda row: (row["validation_objective"], row["search_rank"]))
