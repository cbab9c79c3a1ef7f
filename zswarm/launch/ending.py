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
    if not plan.quiet and plan.record.exists():
        say(f"recording {plan.record} (open with: {viewer_command()} {plan.record}); summary {plan.summary}", err=False)


def viewer_command() -> str:
    """How to start the Rerun viewer from here: ``rerun`` where it is on PATH, else the one installed
    beside this Python (a virtual environment's bin/ that was not activated), relative to here when it
    is below."""
    import shutil
    import sys
    from pathlib import Path

    if shutil.which("rerun") is not None:
        return "rerun"
    beside = Path(sys.executable).parent / "rerun"
    try:
        return str(beside.relative_to(Path.cwd()))
    except ValueError:
        return str(beside)
