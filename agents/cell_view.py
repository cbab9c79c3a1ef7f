"""Which spatial cells (voxels in 3-D) one agent listens to: those its sensing disc (ball), grown by
2 v_max dt, overlaps; chosen again only once it has moved far enough to change them. For each, the
poses published into it and the member tokens of the agents in it (who is there, whether or not
their poses get through)."""

from __future__ import annotations

import math

from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys, cells_in_disc_margin


class CellView:
    def __init__(self, keys: Keys, bridge: Bridge, body, subscription_radius: float) -> None:
        self.keys, self.bridge, self.body, self.subscription_radius = keys, bridge, body, subscription_radius
        self.cells: dict[tuple[int, ...], object] = {}  # cell -> its subscription
        self.members: dict[tuple[int, ...], object] = {}  # cell -> its member tokens' subscription
        self.since: dict[tuple[int, ...], int] = {}  # step at which each cell was subscribed
        self.chosen_at: tuple[tuple[float, ...], float] | None = None  # where they were chosen, and the margin

    def move(self) -> tuple[list[tuple[int, ...]], list[tuple[int, ...]]]:
        """Subscribe to the cells the sensing disc overlaps, leave the others; returns the new ones and
        the ones left."""
        point = self.body.position
        at = self.chosen_at
        if at is not None and math.dist(point, at[0]) < at[1]:
            return [], []  # not yet moved far enough to change which cells its disc meets
        wanted, margin = cells_in_disc_margin(self.keys, point, self.subscription_radius)
        self.chosen_at = (point, margin)
        left = [c for c in self.cells if c not in wanted]
        for cell in left:
            self.bridge.unsubscribe(self.cells.pop(cell))
            self.bridge.unsubscribe(self.members.pop(cell))
            self.since.pop(cell, None)
        new = [c for c in wanted if c not in self.cells]
        for cell in new:
            # its own pose is published into one of them: not handed back to it
            self.cells[cell] = self.bridge.subscribe(self.keys.cell_poses(cell), "pose", remote=True)
            # without history: a history answer can come after the live removal of the same token (a
            # neighbour that left would seem to stay); who sits there already is asked for apart
            # (agents.outreach), and that answer counts only where nothing live came since
            self.members[cell] = self.bridge.subscribe_liveliness(self.keys.cell_members(cell), "in", history=False)
            self.since[cell] = self.body.step
        return new, left
