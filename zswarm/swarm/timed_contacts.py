"""Collisions judged at one instant, from poses sent at different times (the free clock's judge): two
agents collide only where they were closer than 2 d^r at the same instant on the senders' clock, each
held at its newest pose stamped at or before it; lost poses are ``gaps``, contacts they leave unsure
``uncertain``, poses after their instant was judged ``late`` (docs/safety.md, "Counting collisions at
one instant")."""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from zswarm.paper.neighbours import pairs_within

#: A sequence number this far behind the newest from its sender is a restarted sender (it counts from 1
#: again), not an old pose: the rule of every reader of poses, here and in :mod:`zswarm.net.poses`.
SEQ_RESTART = 1000
ONSETS_KEPT = 20


@dataclass
class Track:
    """One agent's poses from the last judged instant on: stamps ascending, positions beside them."""

    stamps: list[float] = field(default_factory=list)
    points: list[tuple[float, ...]] = field(default_factory=list)
    seqs: list[int] = field(default_factory=list)
    last_seq: int = 0
    heard: float = -math.inf  # when its last pose arrived (the receiver's clock)
    ended: bool = False  # it left: its poses hold up to its last stamp and not after

    def at(self, t: float) -> tuple[float, ...] | None:
        """Its position at ``t`` (the latest pose stamped at or before it), None before its first pose
        or after it left."""
        k = bisect_right(self.stamps, t) - 1
        if k < 0 or (self.ended and t > self.stamps[-1]):
            return None
        return self.points[k]

    def exact(self, t: float) -> bool:
        """Its position at ``t`` is known exactly: ``t`` is one of its stamps, or the pose in force is
        followed by the next sequence number (no pose of it was lost in between), or by none yet (a
        silent agent holds its place, as the judge assumes of it)."""
        k = bisect_right(self.stamps, t) - 1
        return k >= 0 and (self.stamps[k] == t or k + 1 == len(self.seqs) or self.seqs[k + 1] == self.seqs[k] + 1)


@dataclass(frozen=True)
class Onset:
    """Two agents entering contact at one instant (a stamp on the senders' clock)."""

    stamp: float
    i: int
    j: int
    distance: float


def _within(stamps: list[float], start: float | None, end: float) -> list[float]:
    """The stamps in (start, end] (all up to ``end`` when start is None), by bisection."""
    lo = 0 if start is None else bisect_right(stamps, start)
    return stamps[lo:bisect_right(stamps, end)]


class TimedContacts:
    """The judge of the module doc; :meth:`add` every accepted pose, :meth:`judge` once per world tick."""

    def __init__(self, collision_distance: float, silence: float = 5.0) -> None:
        self.distance, self.silence = float(collision_distance), float(silence)
        self.tracks: dict[int, Track] = {}
        self.first: float | None = None  # the first instant judged
        self.judged: float | None = None  # the last instant judged (t_c)
        self.contact: set[tuple[int, int]] = set()  # pairs in contact at t_c
        self.collisions = 0
        self.uncertain = 0  # contacts at instants where a lost pose leaves a position unknown
        self.onsets: list[Onset] = []  # the first ONSETS_KEPT onsets
        self.closest = math.inf  # the smallest distance at one instant among the pairs walked
        self.gaps = self.late = 0

    # --- what arrives -----------------------------------------------------------------------------------

    def add(self, who: int, seq: int, stamp: float, position: tuple[float, ...], received: float) -> None:
        """One accepted pose of agent ``who``, stamped by its sender, taken in at ``received``."""
        track = self.tracks.get(who)
        if track is None or track.ended or track.last_seq - seq > SEQ_RESTART:
            track = self.tracks[who] = Track(last_seq=seq - 1)  # new, back, or restarted: a new track
        track.heard = max(track.heard, received)
        if self.judged is not None and stamp <= self.judged:
            self.late += 1
            return
        if seq > track.last_seq:
            self.gaps += seq - track.last_seq - 1
            track.last_seq = seq
        else:
            self.gaps = max(self.gaps - 1, 0)  # a pose counted missing came after all
        k = bisect_right(track.stamps, stamp)
        track.stamps.insert(k, stamp)
        track.points.insert(k, position)
        track.seqs.insert(k, seq)

    def leave(self, who: int) -> None:
        """Agent ``who`` left (or crashed): its last pose holds up to its stamp, then it is gone."""
        track = self.tracks.get(who)
        if track is not None:
            track.ended = True

    # --- judging ------------------------------------------------------------------------------------------

    def ready(self, now: float) -> float | None:
        """The instant every agent's poses up to are in (t_c of the module doc), at ``now`` on the
        receiver's clock; None with no pose."""
        tracks = [t for t in self.tracks.values() if t.stamps]
        if not tracks:
            return None
        waiting = [t.stamps[-1] for t in tracks if not t.ended and now - t.heard <= self.silence]
        return min(waiting) if waiting else max(t.stamps[-1] for t in tracks)

    def judge(self, now: float) -> list[Onset]:
        """Judge every instant up to :meth:`ready`; returns the onsets found."""
        t_c = self.ready(now)
        if t_c is None or (self.judged is not None and t_c <= self.judged):
            return []
        start = self.judged
        if self.first is None:
            self.first = min(t.stamps[0] for t in self.tracks.values() if t.stamps)
        found: list[Onset] = []
        ids, anchors, reach = [], [], []
        for who, track in self.tracks.items():
            span = self._span(track, start, t_c)
            if span is None:
                continue
            anchor = track.points[span[1]]  # plain floats: a span holds a pose or two at a world tick
            ids.append(who)
            anchors.append(anchor)
            reach.append(max(math.dist(p, anchor) for p in track.points[span[0]:span[1] + 1]))
        if len(ids) >= 2:
            found = self._walk(ids, np.asarray(anchors, dtype=float), np.asarray(reach), start, t_c)
        self._prune(t_c)
        self.judged = t_c
        return found

    def _span(self, track: Track, start: float | None, t_c: float) -> tuple[int, int] | None:
        """Indices of the poses that hold somewhere in [start, t_c] (all up to t_c at the first
        judgement); None if none does."""
        last = bisect_right(track.stamps, t_c) - 1
        if last < 0 or (track.ended and start is not None and track.stamps[-1] < start):
            return None
        first = 0 if start is None else max(bisect_right(track.stamps, start) - 1, 0)
        return first, last

    def _walk(self, ids: list[int], anchors: np.ndarray, reach: np.ndarray, start: float | None,
              t_c: float) -> list[Onset]:
        """Walk the pairs that can come within 2 d^r (with a margin, for the closest distance) through
        the instants of the interval (start, t_c]."""
        bound = 2.0 * self.distance
        a, b = pairs_within(anchors, bound + 2.0 * float(reach.max()))
        d = np.linalg.norm(anchors[a] - anchors[b], axis=1)
        keep = (a < b) & (d <= bound + reach[a] + reach[b])
        was, now = self.contact, set()
        found: list[Onset] = []
        for x, y in zip(a[keep].tolist(), b[keep].tolist()):
            i, j = ids[x], ids[y]
            pair = (i, j) if i < j else (j, i)
            ti, tj = self.tracks[i], self.tracks[j]
            instants = sorted(set(_within(ti.stamps, start, t_c) + _within(tj.stamps, start, t_c)))
            touching = pair in was
            for s in instants:
                p, q = ti.at(s), tj.at(s)
                if p is None or q is None:
                    touching = False
                    continue
                dist = math.dist(p, q)
                self.closest = min(self.closest, dist)
                if dist < self.distance and not touching:
                    if not (ti.exact(s) and tj.exact(s)):
                        self.uncertain += 1
                    else:
                        self.collisions += 1
                        onset = Onset(s, pair[0], pair[1], dist)
                        found.append(onset)
                        if len(self.onsets) < ONSETS_KEPT:
                            self.onsets.append(onset)
                touching = dist < self.distance
            if touching:
                now.add(pair)
        self.contact = now
        return found

    def _prune(self, t_c: float) -> None:
        """Keep, of each track, the pose that holds at t_c and the later ones; drop tracks that ended."""
        for who in list(self.tracks):
            track = self.tracks[who]
            if track.ended and (not track.stamps or track.stamps[-1] <= t_c):
                del self.tracks[who]
                continue
            k = max(bisect_right(track.stamps, t_c) - 1, 0)
            del track.stamps[:k], track.points[:k], track.seqs[:k]

    def result(self) -> dict[str, Any]:
        """The summary keys (``*_at_one_time``), judged up to the last instant every pose was in."""
        walked = math.isfinite(self.closest)
        return {"collisions_at_one_time": self.collisions,
                # None when no pair ever came within twice the collision distance: then it is at least that
                "closest_at_one_time": self.closest if walked else None,
                "closest_at_one_time_at_least": None if walked else 2.0 * self.distance,
                "judged_at_one_time_s": (self.judged - self.first) if self.first is not None else None,
                "uncertain_contacts_at_one_time": self.uncertain,
                "pose_gaps": self.gaps, "poses_too_late_to_judge": self.late,
                "collision_onsets_at_one_time": [{"stamp": o.stamp, "agents": [o.i, o.j], "distance": o.distance}
                                                 for o in self.onsets]}


def judge_tracks(tracks: list[tuple[int, np.ndarray]], collision_distance: float,
                 window: float = 0.05) -> dict[str, Any]:
    """The same judge over the agents' own tracks (``agents --tracks``): every pose each agent sent, as
    rows (stamp, x, y[, z]), one array per process (a restarted agent has two). Nothing is missing or
    late, so this is the exact count: the poses are taken in the order they were sent, ``window``
    seconds at a time, each window judged once it is all in; a process's track ends with its last pose."""
    rows: list[tuple[float, int, bool, tuple[float, ...]]] = []
    for who, track in tracks:
        last = len(track) - 1
        rows += [(r[0], who, k == last, tuple(r[1:])) for k, r in enumerate(np.asarray(track, float).tolist())]
    rows.sort(key=lambda r: r[0])
    judge = TimedContacts(collision_distance, silence=0.0)  # all is in: nobody is waited for
    seqs: dict[int, int] = {}
    end = rows[0][0] + window if rows else 0.0
    for stamp, who, last, point in rows:
        if stamp > end:
            judge.judge(now=math.inf)
            end = stamp + window
        seqs[who] = seqs.get(who, 0) + 1
        judge.add(who, seqs[who], stamp, point, received=stamp)
        if last:
            judge.leave(who)
    judge.judge(now=math.inf)
    out = judge.result()
    return {"collisions": out["collisions_at_one_time"], "closest": out["closest_at_one_time"],
            "judged_s": out["judged_at_one_time_s"], "processes": len(tracks), "poses": len(rows),
            "onsets": out["collision_onsets_at_one_time"]}
