"""A distributed run beside its centralized reference: the same scenario, seed and duration simulated
with the same equations (:mod:`zswarm.sim`), stored in the run's summary as ``reference`` and
``vs_reference`` (distributed minus reference). A run that ends S after the capture
(``--end-after-capture S``) is compared with a reference that ends by the same rule: S after its own
capture, or at the duration asked where it catches nothing sooner. The world never runs the simulator
itself: the tools that start it (``zswarm run``, sweeps, tests) add this after it has written its
summary."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from zswarm.files import write_json
from zswarm.net.runspec import RunSpec

COMPARED = ("capture_time", "collisions", "final_components", "min_pair_distance", "final_centroid_goal_distance",
            "min_obstacle_clearance")


def reference_comparison(result: dict[str, Any], spec: RunSpec) -> dict[str, Any]:
    """``reference`` and ``vs_reference`` for a distributed run's ``result`` (its summary)."""
    from zswarm.sim.simulator import simulate

    from zswarm.errors import Failure

    scenario = spec.scenario

    def simulated(duration: float) -> dict[str, Any]:
        return simulate(scenario, spec.seed, combination=spec.combination, safety=spec.safety,
                        duration=max(duration, scenario.dt)).summary

    try:
        after = result.get("end_after_capture")
        if after is None:
            ref = simulated(float(result.get("duration") or 0.0))
        else:  # the reference ends by the run's rule: ``after`` seconds after its own capture, or when asked
            asked = spec.steps * scenario.dt
            ref = simulated(asked)
            caught = ref["capture_time"]
            if caught is not None and caught + after < asked:
                ref = simulated(caught + after)
    except Failure as exc:  # the law failed in the simulation too: said, and the run's own summary kept
        return {"reference": {"error": str(exc)}, "vs_reference": None}
    reference = {k: ref[k] for k in COMPARED}
    return {"reference": reference,
            "vs_reference": {k: (None if result.get(k) is None or ref[k] is None else result[k] - ref[k])
                             for k in COMPARED}}


def add_reference(summary_path: Path, spec: RunSpec, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """Add the reference comparison (and ``extra``, what the launcher knows: the routers and which
    agent used which) to the summary file, rewritten whole; returns the summary."""
    result = json.loads(Path(summary_path).read_text())
    result.update(reference_comparison(result, spec))
    result.update(extra or {})
    write_json(Path(summary_path), result)
    return result
