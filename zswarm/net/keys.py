"""Every key expression of a run, built in one place; the key space is drawn in docs/running.md."""

from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from zswarm.errors import UsageError
from zswarm.paper.neighbours import cell_meets

RUN_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


def check_run_id(run: str) -> str:
    if not RUN_ID.match(run):
        raise UsageError(f"run id {run!r} must be 1-64 letters, digits, '_', '.' or '-'")
    return run



@dataclass(frozen=True)
class Keys:
    """Every key expression of one run; ``dims``: 2, or 3 for a run in space (cells are then voxels)."""

    run: str
    cell_size: float
    dims: int = 2

    @property
    def root(self) -> str:
        return f"zswarm/{self.run}"

    def cell(self, *coords: float) -> tuple[int, ...]:
        """The cell (voxel in 3-D) a point lies in."""
        size = self.cell_size
        if len(coords) == 2:  # every agent, every tick
            return (math.floor(coords[0] / size), math.floor(coords[1] / size))
        return tuple(math.floor(c / size) for c in coords)

    def pose(self, cell: tuple[int, ...], agent: int) -> str:
        return f"{self.root}/pose/{'/'.join(map(str, cell))}/{agent}"

    def any_cell_pose(self, agent: int) -> str:
        """Agent ``agent``'s pose in whichever cell it is (a pattern)."""
        return f"{self.root}/pose/{'*/' * self.dims}{agent}"

    def cell_poses(self, cell: tuple[int, ...]) -> str:
        return f"{self.root}/pose/{'/'.join(map(str, cell))}/*"

    @property
    def all_poses(self) -> str:
        return f"{self.root}/pose/**"

    def member(self, cell: tuple[int, ...], agent: int) -> str:
        """Agent ``agent``'s token in the cell it is in."""
        return f"{self.root}/in/{'/'.join(map(str, cell))}/{agent}"

    def cell_members(self, cell: tuple[int, ...]) -> str:
        return f"{self.root}/in/{'/'.join(map(str, cell))}/*"

    def any_cell_member(self, agent: int) -> str:
        """Agent ``agent``'s token in whichever cell it is (a pattern)."""
        return f"{self.root}/in/{'*/' * self.dims}{agent}"

    @property
    def all_members(self) -> str:
        return f"{self.root}/in/**"

    def member_of(self, key: str) -> tuple[tuple[int, ...], int] | None:
        """(cell, agent) of a member token's key (None if it is not one of this run's dimension)."""
        parts = key.split("/")
        if len(parts) != 4 + self.dims or parts[2] != "in":
            return None
        try:
            return tuple(int(c) for c in parts[3:-1]), int(parts[-1])
        except ValueError:
            return None

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

    def obstacle_query(self, point: Sequence[float], r: float) -> str:
        """Ask for the obstacles within r of ``point`` (x, y, and z in 3-D)."""
        coords = ";".join(f"{name}={c!r}" for name, c in zip("xyz", point))
        return f"{self.obstacles}?{coords};r={r!r}"

    def stats(self, agent: int) -> str:
        return f"{self.root}/stats/{agent}"

    @property
    def all_stats(self) -> str:
        return f"{self.root}/stats/*"

    @property
    def control(self) -> str:
        return f"{self.root}/control"

    @property
    def world_started(self) -> str:
        return f"{self.root}/world/started"

    def report_taken(self, agent: int) -> str:
        """Where the world says it holds ``agent``'s final report (the agent's cue to leave)."""
        return f"{self.root}/world/taken/{agent}"

    @property
    def all_reports_taken(self) -> str:
        return f"{self.root}/world/taken/*"

    def handoff(self, agent: int) -> str:
        """Where the process running ``agent`` answers with its state, to one that takes it over."""
        return f"{self.root}/handoff/{agent}"

    @property
    def positions(self) -> str:
        """The world's queryable of where every live agent was last seen (the driver's placement)."""
        return f"{self.root}/world/positions"

    @staticmethod
    def agent_of(key: str) -> int | None:
        """The agent id at the end of a pose, alive or stats key (None if it is not a number)."""
        tail = key.rsplit("/", 1)[-1]
        return int(tail) if tail.isdigit() else None


def cells_in_disc(keys: Keys, point: Sequence[float], r: float) -> set[tuple[int, ...]]:
    """Every cell whose square (cube in 3-D) meets the disc (ball) of radius r about ``point``."""
    return cells_in_disc_margin(keys, point, r)[0]


ROUNDING = 1e-9  # kept off the margin: a move within it must not flip a cell that rounding puts on the edge


def cells_in_disc_margin(keys: Keys, point: Sequence[float], r: float) -> tuple[set[tuple[int, ...]], float]:
    """Every cell whose square (cube) meets the disc (ball) of radius r about ``point``
    (:func:`cells_in_disc`), and how far the point may move, in any direction, before that set changes.

    A cell is in the set when its signed distance from the point (negative inside it: minus the
    distance to its nearest face) is at most r. A signed distance changes no faster than the point
    moves, so the set stays the same while the point is closer to where it was than every cell's
    |distance - r|. Cells farther than r + one cell size are not looked at, so the margin is at most
    one cell size.
    """
    s, r2 = keys.cell_size, r * r
    axes = []  # per axis, each cell index of the disc's box and a ring of one cell around it, with its
    for c in point:  # squared distance to the point along that axis, depth inside, and whether in the box
        c, lo, hi = float(c), math.floor((float(c) - r) / s), math.floor((float(c) + r) / s)
        axes.append([(i, (min(max(c, i * s), i * s + s) - c) ** 2, min(c - i * s, i * s + s - c), lo <= i <= hi)
                     for i in range(lo - 1, hi + 2)])
    cells: set[tuple[int, ...]] = set()
    margin = s
    if len(axes) == 2:  # the same, written out for the plane: a moving agent asks every tick or two
        for i, dx, ex, bx in axes[0]:
            for j, dy, ey, by in axes[1]:
                d2 = dx + dy
                m = abs((math.sqrt(d2) if d2 > 0.0 else -min(ex, ey)) - r)
                if m < margin:
                    margin = m
                if bx and by and d2 <= r2:
                    cells.add((i, j))
        return cells, max(margin - ROUNDING, 0.0)
    for combo in itertools.product(*axes):  # in plain floats: an agent asks every tick or two
        d2 = 0.0
        for _, dk, _, _ in combo:  # axis by axis, in this order
            d2 += dk
        signed = math.sqrt(d2) if d2 > 0.0 else -min(a[2] for a in combo)
        margin = min(margin, abs(signed - r))
        if d2 <= r2 and all(a[3] for a in combo):
            cells.add(tuple(a[0] for a in combo))
    return cells, max(margin - ROUNDING, 0.0)


def in_reach(positions: np.ndarray, r: float, cell_size: float) -> np.ndarray:
    """``[i, j]``: agent j at ``positions`` (N, D) publishes into a cell that agent i's disc (ball) of
    radius r meets (:func:`cells_in_disc`), so a lossless transport hands i every pose of j."""
    p = np.asarray(positions, dtype=float)
    p = p.reshape(-1, p.shape[-1] if p.ndim > 1 else 2)
    meets = cell_meets(p[:, None, :], p[None, :, :], r, cell_size)  # [i, j]: j's cell meets i's disc
    np.fill_diagonal(meets, False)
    return meets


def in_reach_counts(positions: np.ndarray, r: float, cell_size: float) -> np.ndarray:
    """For each agent, how many others are :func:`in_reach`: the poses a lossless transport hands it per
    publishing round. Counted per cell, not per pair: for each cell offset that can meet a disc, the
    agents whose disc meets their offset cell add that cell's head count (less themselves, in their
    own cell). The same counts as ``in_reach(...).sum(axis=1)``, in O(N) memory (at N = 1000 the pair
    matrix took the world 70 ms, once a second)."""
    p = np.asarray(positions, dtype=float)
    p = p.reshape(-1, p.shape[-1] if p.ndim > 1 else 2)
    if len(p) == 0:
        return np.zeros(0, dtype=np.intp)
    cell = np.floor(p / cell_size).astype(np.int64)
    reach = int(r // cell_size) + 1  # a cell this many steps away can still meet a disc; one more cannot
    base = cell.min(axis=0) - reach
    width = cell.max(axis=0) + reach - base + 1
    stride = np.concatenate([[1], np.cumprod(width[:-1])]).astype(np.int64)
    codes, heads = np.unique((cell - base) @ stride, return_counts=True)
    counts = np.full(len(p), -1, dtype=np.intp)  # not itself
    for offset in itertools.product(range(-reach, reach + 1), repeat=p.shape[1]):
        other = cell + np.asarray(offset, dtype=np.int64)
        lo = other * cell_size
        meets = ((np.clip(p, lo, lo + cell_size) - p) ** 2).sum(axis=1) <= r * r
        code = (other[meets] - base) @ stride
        k = np.minimum(np.searchsorted(codes, code), len(codes) - 1)
        counts[meets] += np.where(codes[k] == code, heads[k], 0)
    return counts


def parse_parameters(text: str) -> dict[str, str]:
    """``x=1.0;y=2.0;r=1.5`` -> {'x': '1.0', ...}."""
    out = {}
    for part in str(text).split(";"):
        name, sep, value = part.partition("=")
        if sep:
            out[name.strip()] = value.strip()
    return out


