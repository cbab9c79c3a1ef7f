"""Agents moved between routers (the nodes of a cluster) as the swarm moves: ``zswarm run
--migrate-every S``.

Placement by space is made once, from the spawn positions; as a swarm gathers and turns about its
goal, the blocks each node received shear into one another and more and more neighbour traffic
crosses between routers (docs/cluster.md). Every S seconds of the run's clock the launcher asks the
world where each agent was last seen (its ``keys.positions`` queryable: the launcher places, it never
steers), splits the swarm anew by space and hands the new blocks to the nodes that already hold most
of each (:func:`zswarm.launch.placement.replace`). Each agent whose node changes is started on its
new node with ``--takeover``; that process takes the running one's state and the running one leaves
(:mod:`agents.handoff`, make-before-break). An agent still moving is left where it is until the next
time.
"""

from __future__ import annotations

from collections import Counter
from typing import Any, Sequence

import numpy as np

from zswarm.launch.placement import replace


class Migration:
    def __init__(self, every: float) -> None:
        self.every = every
        self.next_at = every  # the run's clock (simulated seconds) at which to look next
        self.epochs = 0
        self.moved: Counter[int] = Counter()  # agent -> its moves so far
        self.skipped = 0  # agents left where they were: their last move not over, or their process gone
        self.unanswered = 0  # looks the world did not answer in time (the next look tries again)

    def due(self, t: float) -> bool:
        return t >= self.next_at

    def plan(self, t: float, ids: np.ndarray, positions: np.ndarray, where: dict[int, int],
             capacities: Sequence[float], busy: set[int]) -> list[tuple[int, int, int, np.ndarray]]:
        """The moves to make now, as (agent, from, to, where it was seen), of the agents seen at
        ``positions`` (``ids``) that run where ``where`` says and are not ``busy`` moving."""
        while self.next_at <= t:
            self.next_at += self.every
        self.epochs += 1
        moving = np.array([int(i) in busy for i in ids], dtype=bool)
        keep = np.array([int(i) in where for i in ids], dtype=bool) & ~moving
        self.skipped += int(moving.sum())
        ids, positions = np.asarray(ids)[keep], np.asarray(positions)[keep]
        if len(ids) < len(capacities):
            return []
        current = [where[int(i)] for i in ids]
        new = replace(positions, current, capacities)
        out = [(int(i), a, b, p) for i, a, b, p in zip(ids, current, new, positions) if a != b]
        self.moved.update(i for i, _, _, _ in out)
        return out

    def summary(self, n_agents: int) -> dict[str, Any]:
        moves = sum(self.moved.values())
        return {"every": self.every, "epochs": self.epochs, "moves": moves,
                "moves_per_agent": moves / max(n_agents, 1), "left_moving": self.skipped,
                "looks_unanswered": self.unanswered,
                "moved": {str(i): n for i, n in sorted(self.moved.items())}}
