"""Staged crashes and outages as data: a schedule of events, each due at a time of the run's clock.

``--kill K@T`` kills K agents (chosen with the run's seed) at T, ``--restart-after S`` starts them
again S seconds later, ``--pause WHAT@T:S`` freezes a process (SIGSTOP) from T for S seconds and lets it
go on (SIGCONT), ``--world-outage T:S`` is ``--pause world@T:S``, ``--world-crash T[:S]`` kills the
world at T (and with S starts a replacement S seconds later). docs/experiments.md says what each does.
"""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass
from typing import Literal, Sequence

from zswarm.net.runspec import WORLD_SILENT_S

#: How long a staged world fault may keep the world away (frozen, or dead before its replacement starts):
#: its replacement needs some seconds more to start, and the agents leave after WORLD_SILENT_S.
WORLD_AWAY_MAX_S = WORLD_SILENT_S - 10.0

Action = Literal["kill_world", "resume_world", "kill_agents", "restart_agents", "pause", "unpause"]
#: The actions that start a fault (the others end one: resume_world, restart_agents, unpause).
FAULT_STARTS = ("kill_world", "kill_agents", "pause")


@dataclass(frozen=True)
class Event:
    at: float  # seconds on the run's clock
    action: Action
    count: int = 0  # kill_agents: how many
    what: str = ""  # pause, unpause: the process, by the name the launcher gives it


@dataclass(frozen=True)
class Pause:
    """``--pause WHAT@T:S``: the process ``what`` (``world``, ``router``, ``router-K``, ``agent-ID``)
    frozen at T for S seconds."""

    what: str
    at: float
    length: float

    def __str__(self) -> str:
        return f"{self.what}@{self.at:g}:{self.length:g}"


def schedule(kill: tuple[int, float] | None = None, restart_after: float | None = None,
             world_outage: tuple[float, float] | None = None,
             world_crash: tuple[float, float | None] | None = None, pauses: Sequence[Pause] = ()) -> list[Event]:
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
    for p in [*([Pause("world", *world_outage)] if world_outage is not None else []), *pauses]:
        events += [Event(p.at, "pause", what=p.what), Event(p.at + p.length, "unpause", what=p.what)]
    return sorted(events, key=lambda e: e.at)


def check(kill: tuple[int, float] | None, restart_after: float | None, world_outage: tuple[float, float] | None,
          world_crash: tuple[float, float | None] | None, migrate_every: float | None, agents: int, roles,
          run_s: float, wall_s: float, cluster: bool = False, pauses: Sequence[Pause] = (),
          names: Sequence[str] = ()) -> None:
    """Refuse, in one line, a fault the run cannot stage: more agents killed than this machine runs, a
    time after the run's end (``wall_s`` wall seconds: ``run_s`` of the run's clock), a restart of
    nothing (over a ``cluster``, ``--restart-after`` also restarts a lost node's agents), a world fault
    where no world runs, a pause of a process this machine does not run (``names``: those it does).
    Raises :class:`UsageError`."""
    from zswarm.errors import UsageError

    end = f"the run lasts {wall_s:g} s, --duration {run_s:g} at --time-scale {run_s / wall_s:g}"
    if kill is not None:
        if "agents" not in roles or kill[0] > agents:
            raise UsageError(f"--kill {kill[0]}@{kill[1]:g}: this machine runs {agents if 'agents' in roles else 0} "
                             f"agents (give K <= {agents})")
        if kill[1] >= wall_s:
            raise UsageError(f"--kill {kill[0]}@{kill[1]:g}: {kill[1]:g} s is after the run's end: {end}")
    if restart_after is not None:
        if kill is None and not cluster:
            raise UsageError("--restart-after restarts the agents --kill killed: give --kill K@T too")
        if kill is not None and kill[1] + restart_after >= wall_s:
            raise UsageError(f"--restart-after {restart_after:g}: the restart falls after the run's end: {end}")
    for flag, fault in (("--world-outage", world_outage), ("--world-crash", world_crash)):
        if fault is not None:
            if "world" not in roles:
                raise UsageError(f"{flag} stages a world fault: give this machine the world role")
            if fault[0] >= wall_s:
                raise UsageError(f"{flag} {fault[0]:g}: {fault[0]:g} s is after the run's end: {end}")
            if fault[1] is not None and fault[1] > WORLD_AWAY_MAX_S:
                raise UsageError(f"{flag} {fault[0]:g}:{fault[1]:g}: the agents leave a world silent for "
                                 f"{WORLD_SILENT_S:g} s, so it may be away {WORLD_AWAY_MAX_S:g} s at most "
                                 f"(give S <= {WORLD_AWAY_MAX_S:g})")
    for p in pauses:
        if p.what not in names:
            have = ", ".join(short_names(names)) or "none"
            raise UsageError(f"--pause {p}: this machine runs no {p.what} (its processes: {have})")
        if p.at >= wall_s:
            raise UsageError(f"--pause {p}: {p.at:g} s is after the run's end: {end}")
        if not p.what.startswith("agent-") and p.length > WORLD_AWAY_MAX_S:
            raise UsageError(f"--pause {p}: the agents leave a world they have not heard for {WORLD_SILENT_S:g} s, "
                             f"so the world or a router may be paused {WORLD_AWAY_MAX_S:g} s at most "
                             f"(give S <= {WORLD_AWAY_MAX_S:g})")
    if migrate_every is not None and migrate_every >= run_s:
        raise UsageError(f"--migrate-every {migrate_every:g}: no move falls within the run: {end} (give S < {run_s:g})")


def short_names(names: Sequence[str]) -> list[str]:
    """Process names for a message: agent-0 ... agent-9 as one range."""
    agents = sorted(int(n.split("-")[1]) for n in names if re.fullmatch(r"agent-\d+", n))
    rest = [n for n in names if not re.fullmatch(r"agent-\d+", n)]
    if agents:
        rest.append(f"agent-{agents[0]}" if len(agents) == 1 else f"agent-{agents[0]} ... agent-{agents[-1]}")
    return rest


def parse_pause(text: str) -> Pause:
    """``WHAT@T:S``: WHAT is ``world``, ``router`` (the first), ``router-K`` or ``agent-ID``."""
    what, _, when = text.partition("@")
    if not re.fullmatch(r"world|router(-\d+)?|agent-\d+", what) or not when:
        raise argparse.ArgumentTypeError(f"expected WHAT@T:S with WHAT world, router, router-K or agent-ID, "
                                         f"e.g. router@5:2 or agent-3@10:0.5 (got {text!r})")
    return Pause(what, *parse_outage(when))


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
