"""Staged crashes and outages as data: a schedule of events, each due at a time of the run's clock.

``--kill K@T`` kills K agents (chosen with the run's seed) at T, ``--restart-after S`` starts them
again S seconds later, ``--world-outage T:S`` freezes the world from T for S seconds, ``--world-crash
T[:S]`` kills the world at T (and with S starts a replacement S seconds later).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import Literal

Action = Literal["kill_world", "resume_world", "kill_agents", "restart_agents", "freeze_world", "thaw_world"]


@dataclass(frozen=True)
class Event:
    at: float  # seconds on the run's clock
    action: Action
    count: int = 0  # kill_agents: how many


def schedule(kill: tuple[int, float] | None = None, restart_after: float | None = None,
             world_outage: tuple[float, float] | None = None,
             world_crash: tuple[float, float | None] | None = None) -> list[Event]:
    """Every staged event, in the order they fall due (ties keep this order: world first)."""
    events: list[Event] = []
    if world_crash is not None:
        at, after = world_crash
        events.append(Event(at, "kill_world"))
        if after is not None:
            events.append(Event(at + after, "resume_world"))
    if kill is not None:
        events.append(Event(kill[1], "kill_agents", kill[0]))
        if restart_after is not None:
            events.append(Event(kill[1] + restart_after, "restart_agents"))
    if world_outage is not None:
        start, length = world_outage
        events += [Event(start, "freeze_world"), Event(start + length, "thaw_world")]
    return sorted(events, key=lambda e: e.at)


def parse_kill(text: str) -> tuple[int, float]:
    try:
        k, t = text.split("@")
        out = int(k), float(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K@T, e.g. 3@10 (got {text!r})") from None
    if out[0] < 1 or not out[1] >= 0:
        raise argparse.ArgumentTypeError(f"expected K >= 1 and T >= 0 (got {text!r})")
    return out


def parse_outage(text: str) -> tuple[float, float]:
    try:
        t, d = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T:S, e.g. 10:5 (got {text!r})") from None
    if not t >= 0 or not d > 0:
        raise argparse.ArgumentTypeError(f"expected T >= 0 and S > 0 (got {text!r})")
    return t, d


def parse_crash(text: str) -> tuple[float, float | None]:
    """``T`` (kill the world at T for good) or ``T:S`` (and start a new one S seconds later)."""
    if ":" in text:
        return parse_outage(text)
    try:
        t = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T or T:S, e.g. 10 or 10:3 (got {text!r})") from None
    if not t >= 0:
        raise argparse.ArgumentTypeError(f"expected T >= 0 (got {text!r})")
    return t, None
