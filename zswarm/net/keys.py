"""Every key expression of a run, built in one place.

Key space of a run (``RUN`` is the run id, cells are ``floor(x/size)``, ``floor(y/size)``):

    zswarm/RUN/pose/CX/CY/ID   agent ID's pose, published into the cell it is in; each agent also
                               answers a queryable there with its latest pose
    zswarm/RUN/alive/ID        liveliness token of agent ID
    zswarm/RUN/prey            the prey's position (published by the world)
    zswarm/RUN/tick            lockstep ticks (published by the world)
    zswarm/RUN/obstacles       the world's queryable: ``?x=..;y=..;r=..`` answers obstacles within r
    zswarm/RUN/stats/ID        agent ID's transport counters (for the world's summary)
    zswarm/RUN/control         run control (end of run)
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from zswarm.errors import UsageError

RUN_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


def check_run_id(run: str) -> str:
    if not RUN_ID.match(run):
        raise UsageError(f"run id {run!r} must be 1-64 letters, digits, '_', '.' or '-'")
    return run



@dataclass(frozen=True)
class Keys:
    """Every key expression of one run."""

    run: str
    cell_size: float

    @property
    def root(self) -> str:
        return f"zswarm/{self.run}"

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self.cell_size), math.floor(y / self.cell_size)

    def pose(self, cell: tuple[int, int], agent: int) -> str:
        return f"{self.root}/pose/{cell[0]}/{cell[1]}/{agent}"

    def any_cell_pose(self, agent: int) -> str:
        """Agent ``agent``'s pose in whichever cell it is (a pattern)."""
        return f"{self.root}/pose/*/*/{agent}"

    def cell_poses(self, cell: tuple[int, int]) -> str:
        return f"{self.root}/pose/{cell[0]}/{cell[1]}/*"

    @property
    def all_poses(self) -> str:
        return f"{self.root}/pose/**"

    def alive(self, agent: int) -> str:
        return f"{self.root}/alive/{agent}"

    @property
    def all_alive(self) -> str:
        return f"{self.root}/alive/*"

    @property
    def prey(self) -> str:
        return f"{self.root}/prey"

    @property
    def tick(self) -> str:
        return f"{self.root}/tick"

    @property
    def obstacles(self) -> str:
        return f"{self.root}/obstacles"

    def obstacle_query(self, x: float, y: float, r: float) -> str:
        return f"{self.obstacles}?x={x!r};y={y!r};r={r!r}"

    def stats(self, agent: int) -> str:
        return f"{self.root}/stats/{agent}"

    @property
    def all_stats(self) -> str:
        return f"{self.root}/stats/*"

    @property
    def control(self) -> str:
        return f"{self.root}/control"

    @staticmethod
    def agent_of(key: str) -> int | None:
        """The agent id at the end of a pose, alive or stats key (None if it is not a number)."""
        tail = key.rsplit("/", 1)[-1]
        return int(tail) if tail.isdigit() else None


def cells_in_disc(keys: Keys, x: float, y: float, r: float) -> set[tuple[int, int]]:
    """Every cell whose square meets the disc of radius r about (x, y)."""
    return cells_in_disc_margin(keys, x, y, r)[0]


ROUNDING = 1e-9  # kept off the margin: a move within it must not flip a cell that rounding puts on the edge


def cells_in_disc_margin(keys: Keys, x: float, y: float, r: float) -> tuple[set[tuple[int, int]], float]:
    """Every cell whose square meets the disc of radius r about (x, y) (:func:`cells_in_disc`), and
    how far (x, y) may move, in any direction, before that set changes.

    A cell is in the set when its signed distance from (x, y) (negative inside it: minus the distance
    to its nearest edge) is at most r. A signed distance changes no faster than the point moves, so
    the set stays the same while the point is closer to where it was than every cell's
    |distance - r|. Cells farther than r + one cell size are not looked at, so the margin is at most
    one cell size.
    """
    s = keys.cell_size
    lo_x, hi_x = math.floor((x - r) / s), math.floor((x + r) / s)  # the cells the disc's box spans
    lo_y, hi_y = math.floor((y - r) / s), math.floor((y + r) / s)
    cells, margin = set(), s
    for cx in range(lo_x - 1, hi_x + 2):
        for cy in range(lo_y - 1, hi_y + 2):
            x0, y0 = cx * s, cy * s
            nx, ny = min(max(x, x0), x0 + s), min(max(y, y0), y0 + s)
            d2 = (nx - x) ** 2 + (ny - y) ** 2
            if d2 <= r * r and lo_x <= cx <= hi_x and lo_y <= cy <= hi_y:
                cells.add((cx, cy))
            signed = math.sqrt(d2) if d2 > 0.0 else -min(x - x0, x0 + s - x, y - y0, y0 + s - y)
            margin = min(margin, abs(signed - r))
    return cells, max(margin - ROUNDING, 0.0)


def in_reach_counts(positions: np.ndarray, r: float, cell_size: float) -> np.ndarray:
    """For each agent at ``positions`` (N, 2), how many others publish into a cell that its disc of
    radius r meets (:func:`cells_in_disc`): the poses a lossless transport hands it per publishing round."""
    p = np.asarray(positions, dtype=float).reshape(-1, 2)
    lo = np.floor(p / cell_size) * cell_size  # each agent's cell
    nearest = np.clip(p[:, None, :], lo[None, :, :], lo[None, :, :] + cell_size)  # [i, j]: of j's cell to i
    meets = ((nearest - p[:, None, :]) ** 2).sum(axis=2) <= r * r
    np.fill_diagonal(meets, False)
    return meets.sum(axis=1)


def parse_parameters(text: str) -> dict[str, str]:
    """``x=1.0;y=2.0;r=1.5`` -> {'x': '1.0', ...}."""
    out = {}
    for part in str(text).split(";"):
        name, sep, value = part.partition("=")
        if sep:
            out[name.strip()] = value.strip()
    return out


