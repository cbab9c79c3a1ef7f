"""How the world takes poses in, and hands them to an observed step as arrays.

Every pose it accepts also goes into the free clock's judge (:mod:`zswarm.swarm.timed_contacts`).
Two ways in, one set of rules (:mod:`zswarm.net.poses`):

- one at a time (lockstep, and a free clock below :data:`BATCH_FROM` agents): each decoded pose into
  the per-pose table, which keeps lockstep's poses by step;
- a tick's at once (a free clock from :data:`BATCH_FROM` agents, ``--intake``): the records of a
  tick decoded in one call and accepted as arrays (:mod:`zswarm.net.pose_batch`). A record the
  batch would refuse goes the one-at-a-time way, which says why.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from zswarm.swarm.timed_contacts import TimedContacts
from zswarm.net import messages as msg
from zswarm.net.pose_batch import ACCEPTED, REASON, PoseArrays
from zswarm.net.poses import PoseTable, Rejections, max_step, vouched_by
from zswarm.net.runspec import RunSpec

#: From this many agents a free-running world takes a tick's poses in at once (``--intake auto``):
#: ``zswarm bench world``, this 2-core machine, one at a time against at once: N = 10 (``moving-prey-3d``,
#: 20 Hz) 8.5-9.0 % of a core against 10.5-11.2 %; N = 100 24.3 % against 24.1 %; N = 300 48.8 % against
#: 43.7 %; N = 1000 70.1-70.9 % against 53.5-56.6 % (docs/cluster.md).
BATCH_FROM = 100


class Snapshot(NamedTuple):
    """The live agents' poses as arrays, in id order: ids (N,), positions and velocities (N, D), headings
    (N,; NaN where a body has none; None when none has), safety flags (N,) and send stamps (N,)."""

    ids: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    heading: np.ndarray | None
    safety: np.ndarray
    stamps: np.ndarray


def snapshot_of(poses: dict[int, msg.Pose], dims: int) -> Snapshot:
    """Poses by id as a :class:`Snapshot`, in one pass (at N = 1000 the world does this 20-40 times a
    second: indexing the table once per field by numpy ids cost milliseconds)."""
    order = sorted(poses)
    rows = [poses[i] for i in order]
    table = np.array([(p.x, p.y, p.vx, p.vy, p.stamp, p.safety) for p in rows], dtype=float).reshape(-1, 6)
    if dims == 3:
        zs = np.array([(p.z, p.vz) for p in rows], dtype=float).reshape(-1, 2)
        pos, vel = np.column_stack([table[:, :2], zs[:, 0]]), np.column_stack([table[:, 2:4], zs[:, 1]])
    else:
        pos, vel = np.ascontiguousarray(table[:, :2]), np.ascontiguousarray(table[:, 2:4])
    heading = (np.array([np.nan if p.heading is None else p.heading for p in rows])
               if any(p.heading is not None for p in rows) else None)
    return Snapshot(np.array(order, dtype=np.int64), pos, vel, heading, table[:, 5].astype(np.int64),
                    table[:, 4].copy())


class PoseIntake:
    """The world's accepted poses (``batched``: a free clock's, as arrays); refusals are counted in
    ``rejected``, accepted poses go to ``timed`` (the free clock's judge, if any)."""

    def __init__(self, spec: RunSpec, rejected: Rejections, timed: TimedContacts | None, batched: bool) -> None:
        scenario = spec.scenario
        self.keys, self.dims, self.rejected, self.timed = spec.keys, scenario.dimensions, rejected, timed
        step = max_step(scenario)
        self.batched = batched and spec.clock == "free"
        # one of the two holds the poses: the arrays (batched) or the per-pose table (lockstep's steps too)
        self.table = None if self.batched else PoseTable(step, spec.period)
        self.arrays = PoseArrays(step, spec.period, self.dims) if self.batched else None
        self.record_sizes = msg.POSE_SIZES_BY_DIMS[self.dims]  # this run's records
        self.members: dict[int, set[tuple[int, ...]]] = {}  # id -> the cells holding its member token
        self.announced: dict[int, float] = {}  # id -> when its liveliness token came (World._on_liveliness)

    def member(self, key: str, deleted: bool) -> None:
        """A member token came or went: which cell each agent says it is in (whom to believe when two
        senders claim one id, :class:`zswarm.net.poses.Contest`)."""
        parsed = self.keys.member_of(key)
        if parsed is None:
            return
        cell, who = parsed
        if deleted:
            held = self.members.get(who)
            if held is not None:
                held.discard(cell)
                if not held:
                    del self.members[who]
        else:
            self.members.setdefault(who, set()).add(cell)

    def vouched(self, pose: msg.Pose) -> bool:
        """The sender's member token is in the cell of ``pose`` (:func:`zswarm.net.poses.vouched_by`)."""
        return vouched_by(self.members.get(pose.id), self.keys.cell(*pose.position))

    def one(self, key: str, pose: msg.Pose, payload: bytes, received: float) -> bool:
        """A decoded pose of this run's dimension (``payload``: its record); True if accepted."""
        who = self.keys.agent_of(key)
        if self.batched:
            return self._rows(np.array([-1 if who is None else who]),
                              np.frombuffer(payload, dtype=msg.POSE_ROWS[len(payload)]), received) == 1
        reason = self.table.accept(who, pose, received, self.vouched, self.announced.get)
        if reason is not None:
            self.rejected.add(reason)
            return False
        if self.timed is not None:
            self.timed.add(pose.id, pose.seq, pose.stamp, pose.position, received)
        return True

    def batch(self, keys: list[str], payloads: list[bytes], received: float,
              one_by_one: Callable[[str, bytes], None]) -> int:
        """A tick's pose samples at once: runs of records of this run's sizes, in arrival order, decoded
        and accepted as arrays; each record they would refuse, and anything else, to ``one_by_one``.
        Returns how many it took in itself."""
        start, taken = 0, 0
        for end in range(1, len(payloads) + 1):
            if end < len(payloads) and len(payloads[end]) == len(payloads[start]):
                continue
            if len(payloads[start]) in self.record_sizes:
                rows, ok = msg.decode_pose_records(payloads[start:end])
                for k in np.flatnonzero(~ok).tolist():
                    one_by_one(keys[start + k], payloads[start + k])
                good = [key for key, fine in zip(keys[start:end], ok.tolist()) if fine]
                ids = np.array([-1 if (who := self.keys.agent_of(key)) is None else who for key in good],
                               dtype=np.int64)
                self._rows(ids, rows[ok], received)
                taken += len(good)
            else:
                for key, payload in zip(keys[start:end], payloads[start:end]):
                    one_by_one(key, payload)
            start = end
        return taken

    def _rows(self, key_ids: np.ndarray, rows: np.ndarray, received: float) -> int:
        """Records into the arrays and the judge's record, the refused counted by reason; how many taken."""
        reasons = self.arrays.accept(key_ids, rows, received, self.vouched, self.announced.get)
        taken = reasons == ACCEPTED
        for code in reasons[~taken].tolist():
            self.rejected.add(REASON[code])
        if self.timed is not None and taken.any():
            took = rows[taken]
            points = zip(*(took[n].tolist() for n in ("x", "y", "z")[:self.dims]))
            for who, seq, stamp, point in zip(took["id"].tolist(), took["seq"].tolist(), took["t"].tolist(), points):
                self.timed.add(who, seq, stamp, point, received)
        return int(taken.sum())

    def forget(self, who: int) -> None:
        (self.arrays if self.batched else self.table).forget(who)

    def latest(self, alive: set[int]) -> Snapshot:
        """Free clock: the latest pose of every live agent it holds one of."""
        if not self.batched:
            return snapshot_of(self.table.latest(alive), self.dims)
        t = self.arrays
        ids, rows = t.latest(alive)
        heading = t.heading[rows]
        return Snapshot(ids, t.position[rows], t.velocity[rows], heading if (~np.isnan(heading)).any() else None,
                        t.safety[rows], t.stamp[rows])

    def at_step(self, step: int, alive: set[int]) -> Snapshot:
        """Lockstep: the step-``step`` pose of every live agent it holds one of."""
        return snapshot_of(self.table.at_step(step, alive), self.dims)

    def missing(self, step: int, alive: set[int]) -> set[int]:
        """Lockstep: the live agents whose step-``step`` pose has not come."""
        return alive - set(self.table.at_step(step))
