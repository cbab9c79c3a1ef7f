"""The world's table of accepted poses on the free clock: :meth:`zswarm.net.poses.PoseTable.accept`'s
rules applied to a tick's records at once, as arrays, a row per agent (at N = 1000 and 40 Hz the world
takes in 40,000 poses a second). ``tests/test_pose_batch.py`` holds the two equal over random sequences
of poses, batched at random. A record refused as a jump goes to the table's
:class:`~zswarm.net.poses.Contest`, a record at a time; poses of one agent within a batch are taken in
arrival order. Lockstep's poses by step are kept by the table alone.
"""

from __future__ import annotations

import numpy as np

from zswarm.swarm.timed_contacts import SEQ_RESTART
from zswarm.net import messages as msg
from zswarm.net.poses import Announced, Contest, Vouch

ACCEPTED, SCHEMA, JUMP = 0, 1, 2
REASON = {SCHEMA: "schema", JUMP: "jump"}


class PoseArrays:
    """Accepted poses, a row per agent heard (``row`` maps an agent id to its row: ids may be sparse, up
    to ``MAX_ID``), as arrays; ``dims`` 2 or 3, ``period`` the senders' seconds per tick."""

    def __init__(self, max_step: float, period: float, dims: int) -> None:
        self.max_step, self.period, self.dims = max_step, period, dims
        self.row: dict[int, int] = {}
        self.contest = Contest(max_step, period)
        self._size(64)

    def _size(self, n: int) -> None:
        """Room for ``n`` rows (growing by doubling), keeping what is there."""
        old = getattr(self, "known", np.zeros(0, dtype=bool))
        if n <= len(old):
            return
        n = max(n, 2 * len(old))

        def grown(a: np.ndarray, fill: float | int) -> np.ndarray:
            out = np.full((n, *a.shape[1:]), fill, dtype=a.dtype)
            out[:len(a)] = a
            return out
        d = self.dims
        self.ids = grown(getattr(self, "ids", np.zeros(0, dtype=np.int64)), -1)
        self.known = grown(old, False)
        self.seq = grown(getattr(self, "seq", np.zeros(0, dtype=np.int64)), 0)
        self.step = grown(getattr(self, "step", np.zeros(0, dtype=np.int64)), -1)
        self.stamp = grown(getattr(self, "stamp", np.zeros(0)), 0.0)
        self.received = grown(getattr(self, "received", np.zeros(0)), 0.0)
        self.first = grown(getattr(self, "first", np.zeros(0)), 0.0)
        self.position = grown(getattr(self, "position", np.zeros((0, d))), 0.0)
        self.velocity = grown(getattr(self, "velocity", np.zeros((0, d))), 0.0)
        self.heading = grown(getattr(self, "heading", np.zeros(0)), np.nan)
        self.safety = grown(getattr(self, "safety", np.zeros(0, dtype=np.int64)), 0)

    def forget(self, who: int) -> None:
        self.contest.forget(who)
        row = self.row.get(who)
        if row is not None:
            self.known[row] = False

    def _rows(self, ids: list[int]) -> np.ndarray:
        """The row of each id, a new one for an id not heard before."""
        row = self.row
        for who in ids:
            if who not in row:
                row[who] = len(row)
                self._size(len(row))
                self.ids[row[who]] = who
        return np.fromiter((row[who] for who in ids), dtype=np.int64, count=len(ids))

    def accept(self, key_ids: np.ndarray, rows: np.ndarray, now: float, vouch: Vouch | None = None,
               announced: Announced | None = None) -> np.ndarray:
        """Take the decoded records ``rows`` (:data:`zswarm.net.messages.POSE_ROWS`, of this table's
        dimension), in arrival order, that arrived under keys naming ``key_ids`` (-1: no id); returns
        per row :data:`ACCEPTED`, :data:`SCHEMA` or :data:`JUMP`. ``vouch``: as
        :meth:`zswarm.net.poses.PoseTable.accept`'s."""
        ids = rows["id"].astype(np.int64)
        reasons = np.where(ids == key_ids, ACCEPTED, SCHEMA)
        at = self._rows(ids[reasons == ACCEPTED].tolist())
        order = np.argsort(ids, kind="stable")  # arrival order within each id
        first = np.r_[True, ids[order][1:] != ids[order][:-1]] if len(ids) else np.zeros(0, dtype=bool)
        start = np.maximum.accumulate(np.where(first, np.arange(len(ids)), 0))
        rank = np.empty(len(ids), dtype=np.int64)
        rank[order] = np.arange(len(ids)) - start  # how many poses of its agent came before it here
        where = np.full(len(ids), -1, dtype=np.int64)
        where[reasons == ACCEPTED] = at
        for r in range(int(rank.max()) + 1 if len(ids) else 0):
            sel = np.flatnonzero((rank == r) & (reasons == ACCEPTED))
            reasons[sel] = self._round(where[sel], rows[sel], now, vouch, announced)
        return reasons

    def _round(self, who: np.ndarray, rows: np.ndarray, now: float, vouch: Vouch | None = None,
               announced: Announced | None = None) -> np.ndarray:
        """Records of distinct agents (``who``: their rows): the jump check against what each row holds,
        then the update."""
        seq, step = rows["seq"], rows["s"]
        pos = np.stack([rows[n] for n in ("x", "y", "z")[:self.dims]], axis=1)
        known = self.known[who]
        old_seq, old_step = self.seq[who], self.step[who]
        steps = np.where((step >= 0) & (old_step >= 0), np.maximum(step - old_step, 1),
                         np.maximum(seq - old_seq, 1)).astype(float)
        elapsed = (now - np.minimum(self.received[who], self.stamp[who])) / self.period + 2.0
        steps = np.where(step < 0, np.minimum(steps, np.maximum(elapsed, 1.0)), steps)
        gap = pos - self.position[who]
        far = np.hypot(gap[:, 0], gap[:, 1]) if self.dims == 2 else np.sqrt(np.einsum("ij,ij->i", gap, gap))
        restart = old_seq - seq > SEQ_RESTART
        distant = known & ~restart & (far > self.max_step * steps + 1e-9)  # newer or not: PoseTable.accept
        jump = distant & (seq > old_seq)
        took = np.zeros(len(who), dtype=bool)
        for k in np.flatnonzero(distant).tolist():  # another sender's track: may it take the id over?
            took[k] = self.contest.offer(pose_of(rows[k], self.dims), now, self.held(int(who[k])),
                                         float(self.received[who[k]]), float(self.first[who[k]]), vouch, announced)
        jump &= ~took
        newer = took | (~distant & (~known | (seq > old_seq) | restart))
        w = who[newer]
        self.first[who[(newer & ~known) | took]] = now  # when the track it now holds was first taken in
        self.known[w] = True
        self.seq[w], self.step[w], self.stamp[w] = seq[newer], step[newer], rows["t"][newer]
        self.received[w] = now
        self.position[w] = pos[newer]
        names = ("vx", "vy", "vz")[:self.dims]
        self.velocity[w] = np.stack([rows[n][newer] for n in names], axis=1)
        self.heading[w] = rows["h"][newer] if "h" in rows.dtype.names else np.nan
        self.safety[w] = rows["f"][newer]
        return np.where(jump, JUMP, ACCEPTED)

    def held(self, row: int) -> msg.Pose:
        """The pose a row holds, as a pose."""
        p, v, h = self.position[row], self.velocity[row], float(self.heading[row])
        return msg.Pose(int(self.ids[row]), int(self.seq[row]), float(self.stamp[row]), int(self.step[row]),
                        float(p[0]), float(p[1]), float(v[0]), float(v[1]), None if np.isnan(h) else h,
                        float(p[2]) if self.dims == 3 else None, float(v[2]) if self.dims == 3 else None,
                        int(self.safety[row]))

    def latest(self, among: set[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The ids whose latest pose it holds (of those in ``among``, if given), ascending, and their rows."""
        rows = np.flatnonzero(self.known)
        ids = self.ids[rows]
        if among is not None:
            keep = np.isin(ids, np.fromiter(among, dtype=np.int64, count=len(among)))
            rows, ids = rows[keep], ids[keep]
        order = np.argsort(ids)
        return ids[order], rows[order]


def pose_of(record: np.void, dims: int) -> msg.Pose:
    """A decoded record (a row of :data:`zswarm.net.messages.POSE_ROWS`) as a pose."""
    names = record.dtype.names
    return msg.Pose(int(record["id"]), int(record["seq"]), float(record["t"]), int(record["s"]), float(record["x"]),
                    float(record["y"]), float(record["vx"]), float(record["vy"]),
                    float(record["h"]) if "h" in names else None, float(record["z"]) if dims == 3 else None,
                    float(record["vz"]) if dims == 3 else None, int(record["f"]), int(record["n"]))
