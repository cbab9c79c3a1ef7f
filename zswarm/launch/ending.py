"""How a launched run ends: every run leaves a recording and a summary.

A world that wrote its summary gets the reference simulation of the same run beside it
(:mod:`zswarm.launch.reference`); one that died without has its recording repaired and the summary
recomputed from it (:func:`zswarm.record.salvage.salvage_summary`).
"""

from __future__ import annotations

from typing import Any, Callable

from zswarm.errors import UsageError
from zswarm.launch.plan import Plan


def finish_recording(plan: Plan, world_code: int, started_at: float, routing: dict[str, Any],
                     say: Callable[..., None]) -> None:
    """After the world exited with ``world_code``; ``routing``: the routers and each agent's, for the summary."""
    fresh = plan.summary.exists() and plan.summary.stat().st_mtime >= started_at
    if fresh and world_code == 0:
        from zswarm.launch.reference import add_reference

        add_reference(plan.summary, plan.spec, routing)
    elif world_code != 2 and plan.record.exists():
        from zswarm.record.salvage import salvage_summary

        try:
            salvage_summary(plan.record, plan.summary)
            say(f"the world ended with code {world_code}; its recording was made whole and "
                f"the summary recomputed from it (\"salvaged\": true)")
        except UsageError as exc:
            say(f"the world ended with code {world_code} and its recording cannot be salvaged: {exc}")
    if plan.tracks is not None and plan.summary.exists():
        add_tracks(plan, say)
    if not plan.quiet and plan.record.exists():
        say(f"recording {plan.record} (open with: {installed_command()} {plan.record}); summary {plan.summary}", err=False)


def add_tracks(plan: Plan, say: Callable[..., None]) -> None:
    """``--tracks``: the collisions judged at one instant from what every agent sent
    (:func:`zswarm.swarm.timed_contacts.judge_tracks`), into the summary as ``tracks``, and said."""
    import json

    import numpy as np

    from zswarm.files import write_json
    from zswarm.swarm.timed_contacts import judge_tracks

    files = sorted(plan.tracks.glob("agent-*.npy"))
    tracks = [(int(f.name.split("-")[1]), np.load(f)) for f in files]
    judged = judge_tracks(tracks, 2.0 * plan.spec.scenario.params.swarm.robot_radius)
    summary = json.loads(plan.summary.read_text())
    write_json(plan.summary, {**summary, "tracks": {"folder": str(plan.tracks), **judged}})
    closest = "-" if judged["closest"] is None else f"{judged['closest']:.3f}"
    say(f"tracks: {judged['collisions']} collisions at one instant in the {judged['poses']} poses "
        f"{judged['processes']} agent processes sent (closest {closest}; the world's snapshots counted "
        f"{summary.get('collisions')})", err=False)


def installed_command(name: str = "rerun") -> str:
    """How to start the installed command ``name`` (``rerun``, ``zswarm``) from here: ``name`` where it is
    on PATH, else the one installed beside this Python (a virtual environment's bin/ that was not
    activated), relative to here when it is below."""
    import shutil
    import sys
    from pathlib import Path

    if shutil.which(name) is not None:
        return name
    beside = Path(sys.executable).parent / name
    try:
        return str(beside.relative_to(Path.cwd()))
    except ValueError:
        return str(beside)
