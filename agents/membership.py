"""Whom an agent counts as a member of the swarm: the liveliness tokens (alive, and since when) and
the member tokens in the cells it listens to (where each neighbour is), the half of what it hears that
says who is there rather than where.

Only agents that hold a liveliness token are used as neighbours by the law; a member token in a cell
the agent listens to keeps a silent neighbour guarded by the safety filter (its silence is loss, not
departure), and vouches for its poses there (:func:`zswarm.net.poses.vouched_by`).
"""

from __future__ import annotations

import math
import time

from zswarm.net import messages as msg
from zswarm.net.keys import Keys
from zswarm.net.poses import vouched_by


class Membership:
    def __init__(self, keys: Keys, agent_id: int) -> None:
        self.keys, self.id = keys, agent_id
        self.alive: set[int] = set()  # ids with a liveliness token
        self.announced: dict[int, float] = {}  # id -> when its liveliness token came (whom to believe first)
        self.members: dict[int, set[tuple[int, ...]]] = {}  # id -> the cells it listens to that hold its token
        self.member_news: set[tuple[int, tuple[int, ...]]] = set()  # (id, cell) that changed live since subscribed
        self.member_live_at: dict[tuple[int, tuple[int, ...]], float] = {}  # (id, cell) -> its last live change
        # ids the safety filter guards on their member token alone, or for want of a sign that they left
        # the cell their newest pose is in: whether each holds a token in those cells is asked about
        # again (agents.outreach.Outreach.check_members)
        self.doubted: dict[int, set[tuple[int, ...]]] = {}
        # (id, cell): its member token was seen to leave that cell (a live removal, or an ask that found
        # nobody holds it), the one sign a quiet neighbour is let go on (agents.guard)
        self.gone_from: set[tuple[int, tuple[int, ...]]] = set()
        self.listening: set[tuple[int, ...]] = set()  # the cells it listens to (agents.cell_view)
        # the member keys of cells it listens to whose "who is here" ask got no reply: asked again
        # (agents.outreach); a frozen or stalled router let a neighbour already there go unknown, and,
        # once that neighbour fell silent, unguarded
        self.unanswered: set[str] = set()
        # the cells it listens to whose "who is here" answer it has taken in: until every one has, a silent
        # neighbour whose member token it has not heard may sit in one of them, and is not let go
        self.known: set[tuple[int, ...]] = set()

    def token(self, who: int, deleted: bool, received: float) -> None:
        """Agent ``who``'s liveliness token came (or went) at ``received``."""
        if not deleted:
            self.alive.add(who)
            self.announced.setdefault(who, received)
        else:
            self.alive.discard(who)
            self.announced.pop(who, None)

    def member(self, key: str, deleted: bool, live: bool = True) -> None:
        """A member token came into (or left) one of the cells it listens to (``live``), or was there
        when it asked (an answer that can come after a live change of the same token: it counts only
        if none came)."""
        parsed = self.keys.member_of(key)
        if parsed is None or parsed[1] == self.id:
            return
        cell, who = parsed
        if cell not in self.listening:
            return  # an answer about a cell it has left since it asked
        if live:
            self.member_news.add((who, cell))
            self.member_live_at[(who, cell)] = time.time()
        elif (who, cell) in self.member_news:
            return
        if not deleted:
            self.members.setdefault(who, set()).add(cell)
            self.gone_from.discard((who, cell))
        else:
            self._not_in(who, {cell})
            self.gone_from.add((who, cell))

    def unanswered_ask(self, key: str) -> None:
        """Nobody answered its ask of who sits in the cell of members key ``key``: it is asked again while
        the agent listens to that cell."""
        cell = self._cell_of(key)
        if cell in self.listening:
            self.unanswered.add(key)

    def answered(self, key: str) -> None:
        """Its ask of who sits in the cell of members key ``key`` is answered, every token in it taken in."""
        cell = self._cell_of(key)
        if cell in self.listening:
            self.known.add(cell)

    @property
    def settled(self) -> bool:
        """Whether it knows who sits in every cell it listens to (each one's answer taken in)."""
        return self.listening <= self.known

    def _cell_of(self, key: str) -> tuple[int, ...] | None:
        parsed = self.keys.member_of(key.removesuffix("*") + "0")  # the cell's members: ".../in/CELL/*"
        return None if parsed is None else parsed[0]

    def member_gone(self, key: str, asked: float) -> None:
        """The member token ``key`` was asked about at ``asked`` and nobody holds it: it is no longer in
        that cell, unless a live change of it came since (a token's removal can miss an agent that took the
        token in from the answer to its ask on entering the cell: docs/safety.md)."""
        parsed = self.keys.member_of(key)
        if parsed is None:
            return
        cell, who = parsed
        if self.member_live_at.get((who, cell), -math.inf) < asked and cell in self.listening:
            self._not_in(who, {cell})
            self.gone_from.add((who, cell))

    def listen_to(self, new: list[tuple[int, ...]], left: list[tuple[int, ...]]) -> None:
        """It listens to the cells ``new`` now, and no longer to ``left``: what their tokens said no
        longer holds."""
        self.listening.update(new)
        if not left:
            return
        gone = set(left)
        self.listening -= gone
        self.known -= gone
        self.member_news = {(who, cell) for who, cell in self.member_news if cell not in gone}
        self.member_live_at = {k: t for k, t in self.member_live_at.items() if k[1] not in gone}
        self.gone_from = {(who, cell) for who, cell in self.gone_from if cell not in gone}
        for who in list(self.members):
            self._not_in(who, gone)

    def _not_in(self, who: int, cells: set[tuple[int, ...]]) -> None:
        """Agent ``who``'s token is in none of ``cells`` (it is forgotten when it is in no cell it listens to)."""
        held = self.members.get(who)
        if held is not None:
            held -= cells
            if not held:
                del self.members[who]

    def vouched(self, pose: msg.Pose) -> bool:
        """The sender's member token is in the cell of ``pose`` (:func:`zswarm.net.poses.vouched_by`)."""
        return vouched_by(self.members.get(pose.id), self.keys.cell(*pose.position))
