"""What a process believes about other agents' poses: one table for the agent and the world alike.

:meth:`PoseTable.accept` takes a pose in when its key names its own id, it is no impossible jump from
the last accepted one (``max_step`` per elapsed step, the steps capped by the receiver's own clock, so a
forged sequence number buys no distance), and it is the newest (or so far behind that its sender must
have restarted). Lockstep poses are also kept by step. Whom to believe when two senders claim an id is
:class:`Contest`'s rule (tests/test_forged_pose.py). :class:`Rejections` counts what was refused.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from typing import Callable

from zswarm.swarm.timed_contacts import SEQ_RESTART
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


#: How many times one tick's reach (v_max dt) a pose may move from the last accepted before it is a jump.
JUMP_SLACK = 3.0


def max_step(scenario) -> float:
    """The farthest an agent of ``scenario`` may move per tick before its pose is an impossible jump, for
    the agent and the world alike: one tick's reach with :data:`JUMP_SLACK` slack."""
    return JUMP_SLACK * scenario.params.swarm.v_max * scenario.dt


#: Seconds a rival track must have sent consistently before it may take an id over (the staleness limit).
TAKEOVER = 0.5
#: ... and the poses it must have sent in that time (one stale duplicate is no track).
TAKEOVER_POSES = 3

Vouch = Callable[[msg.Pose], bool]  # the id's member token is in the cell of this pose
Announced = Callable[[int], "float | None"]  # when the id's liveliness token came (None: not heard)


def vouched_by(cells: set[tuple[int, ...]] | None, cell: tuple[int, ...]) -> bool:
    """Whether a sender's member tokens (``cells``: where the receiver knows them, None: nowhere) put
    it in ``cell``, the cell of a pose under its id. The real agent declares its token in the cell of
    each pose before it publishes the pose there (:meth:`agents.agent.Agent.publish_pose`)."""
    return cells is not None and cell in cells


@dataclass
class Rival:
    """Poses of one id refused as jumps that agree among themselves: another sender's track."""

    latest: msg.Pose
    received: float
    first: float
    count: int = 1


class Contest:
    """Whom to believe when two senders claim one agent id, for the pose table and the world's arrays.

    Without ``--secure`` anyone can publish a pose under any id. Poses refused as jumps that agree among
    themselves form a rival track; it takes the id over once it has sent :data:`TAKEOVER_POSES` poses
    over :data:`TAKEOVER` seconds and either the held track fell silent that long, or ``vouch`` puts the
    id's member token in the rival's cell and not the held one's, or (neither or both vouched) the held
    track began before the id's liveliness token came (``announced``) and the rival did not. What an
    attacker without ``--secure`` can still do is listed in docs/running.md.
    """

    def __init__(self, max_step: float, period: float, takeover: float = TAKEOVER) -> None:
        self.max_step, self.period, self.takeover = max_step, period, takeover
        self.rivals: dict[int, Rival] = {}
        self.takeovers = 0

    def offer(self, pose: msg.Pose, now: float, held: msg.Pose, held_received: float, held_first: float,
              vouch: Vouch | None = None, announced: Announced | None = None) -> bool:
        """A pose refused as a jump from ``held`` (accepted last at ``held_received``, its track taken in
        first at ``held_first``): True if it takes the id over now (the caller then holds it as the
        latest)."""
        r = self.rivals.get(pose.id)
        if r is not None and pose.seq > r.latest.seq:
            elapsed = (now - min(r.received, r.latest.stamp)) / self.period + 2.0 if pose.step < 0 else None
            if implausible_jump(r.latest, pose, self.max_step, elapsed):
                r = None
        if r is None:
            self.rivals[pose.id] = Rival(pose, now, now)
            return False
        if supersedes(r.latest, pose):
            r.latest, r.received, r.count = pose, now, r.count + 1
        if r.received - r.first < self.takeover or r.count < TAKEOVER_POSES:
            return False
        mine, theirs = (vouch(r.latest), vouch(held)) if vouch is not None else (False, False)
        since = announced(pose.id) if announced is not None else None
        if (now - held_received >= self.takeover or (mine and not theirs)
                or (mine == theirs and since is not None and held_first < since <= r.first + self.takeover)):
            del self.rivals[pose.id]
            self.takeovers += 1
            return True
        return False

    def forget(self, who: int) -> None:
        self.rivals.pop(who, None)


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
        self.contest = Contest(max_step, period)

    def get(self, who: int) -> Entry | None:
        return self.entries.get(who)

    def forget(self, who: int) -> Entry | None:
        self.contest.forget(who)
        return self.entries.pop(who, None)

    def accept(self, key_agent: int | None, pose: msg.Pose, now: float, vouch: Vouch | None = None,
               announced: Announced | None = None) -> str | None:
        """Take ``pose`` (arrived under a key naming ``key_agent``) into the table; returns None when
        accepted, else the rejection reason. ``vouch``, ``announced``: what the receiver knows of the
        id's tokens (:class:`Contest`)."""
        if key_agent != pose.id:
            return "schema"
        old = self.entries.get(pose.id)
        if old is None:
            old = self.entries[pose.id] = Entry(pose, now, first=now)
        else:
            # the receiver's clock since the old pose was sent (or taken in, if its stamp claims a time
            # after that): a pose that waited in a queue does not make the next one an impossible jump
            elapsed = (now - min(old.received, old.latest.stamp)) / self.period + 2.0 if pose.step < 0 else None
            restart = old.latest.seq - pose.seq > SEQ_RESTART
            if not restart and implausible_jump(old.latest, pose, self.max_step, elapsed):
                # far from what it holds, newer or not (a forger ahead in sequence numbers must not make
                # the real sender's poses merely stale): another sender's track, unless it takes over
                if not self.contest.offer(pose, now, old.latest, old.received, old.first, vouch, announced):
                    return "jump" if pose.seq > old.latest.seq else None
                old.latest, old.received, old.first, old.by_step = pose, now, now, {}  # the rival took it over
            elif supersedes(old.latest, pose):
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
