"""What a process believes about other agents' poses: one table for the agent and the world alike.

Every pose that arrives passes the same acceptance rules (:meth:`PoseTable.accept`):

- the key's agent id must be the pose's own (else ``schema``);
- a pose farther from the last accepted one than ``max_step`` per elapsed step could carry an agent
  is an impossible jump (``jump``); elapsed steps are capped by the receiver's own clock since the last
  accepted pose was sent (taken in, if its stamp claims later), so a forged sequence number cannot buy
  a forged pose an arbitrarily long way, and poses that arrive in a burst after a queue are not refused;
- the newest pose wins (or one so far behind that its sender must have restarted);
- lockstep poses (step >= 0) are also kept by step, for the last ``keep_steps`` steps.

:class:`Rejections` counts what was refused, by reason, and says so once per reason.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Callable

from zswarm.model.timed_contacts import SEQ_RESTART
from zswarm.net import messages as msg


def implausible_jump(old: msg.Pose, new: msg.Pose, max_step: float, elapsed_steps: float | None = None) -> bool:
    """``new`` lies farther from ``old`` than ``max_step`` per elapsed step could carry an agent.

    Steps are counted by lockstep step numbers when both have them, else by sequence numbers (one
    pose per control tick), at least one; ``elapsed_steps`` (the receiver's own clock) caps the
    count, so a forged sequence number cannot buy a forged pose an arbitrarily long way.
    """
    if new.step >= 0 and old.step >= 0:
        steps = max(new.step - old.step, 1)
    else:
        steps = max(new.seq - old.seq, 1)
    if elapsed_steps is not None:
        steps = min(steps, max(elapsed_steps, 1.0))
    if new.z is None or old.z is None:
        return math.hypot(new.x - old.x, new.y - old.y) > max_step * steps + 1e-9
    return math.hypot(new.x - old.x, new.y - old.y, new.z - old.z) > max_step * steps + 1e-9


def supersedes(old: msg.Pose, new: msg.Pose) -> bool:
    """``new`` replaces ``old``: a newer sequence number, or one so far behind that the sender must
    have restarted (a restarted agent counts from 1 again, and may be anywhere: no jump check then;
    so a forged huge number cannot lock the real sender out)."""
    return new.seq > old.seq or old.seq - new.seq > SEQ_RESTART


@dataclass
class Entry:
    """The latest accepted pose of one agent, when it arrived (local wall time), its step poses, and
    when the first arrived."""

    latest: msg.Pose
    received: float
    by_step: dict[int, msg.Pose] = field(default_factory=dict)
    first: float = 0.0  # when its first pose arrived


@dataclass
class Rejections:
    """Messages refused, by reason; the first of each reason is reported (``report``), the rest counted."""

    who: str
    report: Callable[[str], None] | None = None
    counts: dict[str, int] = field(default_factory=dict)

    def add(self, reason: str, detail: str | None = None) -> None:
        """Count one rejection; the first of a reason is reported, unless ``detail`` is None (quiet)."""
        if reason not in self.counts and detail is not None:
            text = f"rejected a message ({detail}); further '{reason}' rejections are only counted"
            print(f"{self.who}: {text}", file=sys.stderr, flush=True)
            if self.report is not None:
                self.report(text)
        self.counts[reason] = self.counts.get(reason, 0) + 1

    @property
    def total(self) -> int:
        return sum(self.counts.values())


class PoseTable:
    """Accepted poses by agent id (see the module doc). ``period``: the sender's seconds per control
    tick, which turns the receiver's clock into elapsed steps for free-clock poses."""

    def __init__(self, max_step: float, period: float, keep_steps: int = 3) -> None:
        self.max_step, self.period, self.keep_steps = max_step, period, keep_steps
        self.entries: dict[int, Entry] = {}

    def get(self, who: int) -> Entry | None:
        return self.entries.get(who)

    def forget(self, who: int) -> Entry | None:
        return self.entries.pop(who, None)

    def accept(self, key_agent: int | None, pose: msg.Pose, now: float) -> str | None:
        """Take ``pose`` (arrived under a key naming ``key_agent``) into the table; returns None when
        accepted, else the rejection reason."""
        if key_agent != pose.id:
            return "schema"
        old = self.entries.get(pose.id)
        if old is None:
            old = self.entries[pose.id] = Entry(pose, now, first=now)
        else:
            # the receiver's clock since the old pose was sent (or taken in, if its stamp claims a time
            # after that): a pose that waited in a queue does not make the next one an impossible jump
            elapsed = (now - min(old.received, old.latest.stamp)) / self.period + 2.0 if pose.step < 0 else None
            if pose.seq > old.latest.seq and implausible_jump(old.latest, pose, self.max_step, elapsed):
                return "jump"
            if supersedes(old.latest, pose):
                old.latest, old.received = pose, now
        if pose.step >= 0:
            old.by_step[pose.step] = pose
            for s in [s for s in old.by_step if s < pose.step - self.keep_steps]:
                del old.by_step[s]
        return None

    def at_step(self, step: int, among: set[int] | None = None) -> dict[int, msg.Pose]:
        """Every pose of lockstep step ``step`` (of the agents in ``among``, if given)."""
        return {who: e.by_step[step] for who, e in self.entries.items()
                if step in e.by_step and (among is None or who in among)}

    def latest(self, among: set[int] | None = None) -> dict[int, msg.Pose]:
        """The latest pose of every agent (in ``among``, if given)."""
        return {who: e.latest for who, e in self.entries.items() if among is None or who in among}
