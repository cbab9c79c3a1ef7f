"""Which spatial cells (voxels in 3-D) one agent listens to: those its sensing disc (ball), grown by
2 v_max dt, overlaps; chosen again only once it has moved far enough to change them."""

from __future__ import annotations

import math

from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys, cells_in_disc_margin


class CellView:
    def __init__(self, keys: Keys, bridge: Bridge, body, subscription_radius: float) -> None:
        self.keys, self.bridge, self.body, self.subscription_radius = keys, bridge, body, subscription_radius
        self.cells: dict[tuple[int, ...], object] = {}  # cell -> its subscription
        self.since: dict[tuple[int, ...], int] = {}  # step at which each cell was subscribed
        self.chosen_at: tuple[tuple[float, ...], float] | None = None  # where they were chosen, and the margin

    def move(self) -> list[tuple[int, ...]]:
        """Subscribe to the cells the sensing disc overlaps, leave the others; returns the new ones."""
        point = self.body.position
        at = self.chosen_at
        if at is not None and math.dist(point, at[0]) < at[1]:
            return []  # not yet moved far enough to change which cells its disc meets
        wanted, margin = cells_in_disc_margin(self.keys, point, self.subscription_radius)
        self.chosen_at = (point, margin)
        for cell in [c for c in self.cells if c not in wanted]:
            self.bridge.unsubscribe(self.cells.pop(cell))
            self.since.pop(cell, None)
        new = [c for c in wanted if c not in self.cells]
        for cell in new:
            # its own pose is published into one of them: not handed back to it
            self.cells[cell] = self.bridge.subscribe(self.keys.cell_poses(cell), "pose", remote=True)
            self.since[cell] = self.body.step
        return new
