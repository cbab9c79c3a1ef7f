"""Who senses whom: a uniform cell grid, so finding pairs costs O(N k), not O(N^2).

Points are bucketed into square cells of side ``cell``; a query looks only at the 3 x 3 block of cells
around each query point, which holds every target within ``cell`` of it. Everything is vectorized
(sorting, ``searchsorted`` and ``repeat``); there is no Python loop over agents.
"""

from __future__ import annotations

import numpy as np

_OFFSET = np.int64(1 << 30)


def _keys(cells: np.ndarray) -> np.ndarray:
    return (cells[:, 0] + _OFFSET) * (2 * _OFFSET) + (cells[:, 1] + _OFFSET)


class CellIndex:
    """Targets bucketed by cell; ``candidates`` returns every (query, target) pair in adjacent cells."""

    def __init__(self, targets: np.ndarray, cell: float) -> None:
        if not cell > 0:
            raise ValueError(f"cell size must be > 0 (got {cell})")
        self.targets = np.asarray(targets, dtype=float).reshape(-1, 2)
        self.cell = float(cell)
        keys = _keys(np.floor(self.targets / self.cell).astype(np.int64))
        self.order = np.argsort(keys, kind="stable")
        self.sorted_keys = keys[self.order]

    def candidates(self, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(query index, target index) for every target in the 3 x 3 cells around each query point."""
        query = np.asarray(query, dtype=float).reshape(-1, 2)
        base = np.floor(query / self.cell).astype(np.int64)
        q_parts, t_parts = [], []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                keys = _keys(base + np.array([dx, dy], dtype=np.int64))
                lo = np.searchsorted(self.sorted_keys, keys, side="left")
                hi = np.searchsorted(self.sorted_keys, keys, side="right")
                counts = hi - lo
                total = int(counts.sum())
                if total == 0:
                    continue
                q = np.repeat(np.arange(len(query)), counts)
                first = np.repeat(lo - (np.cumsum(counts) - counts), counts)
                t_parts.append(self.order[first + np.arange(total)])
                q_parts.append(q)
        if not q_parts:
            empty = np.zeros(0, dtype=np.intp)
            return empty, empty
        return np.concatenate(q_parts), np.concatenate(t_parts)


def pairs_within(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Ordered pairs (i, j), i != j, with |p_i - p_j| <= radius; each unordered pair appears twice."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    i, j = CellIndex(points, radius).candidates(points)
    d = points[i] - points[j]
    keep = (i != j) & (np.einsum("ij,ij->i", d, d) <= radius * radius)
    return i[keep], j[keep]


class ObstacleIndex:
    """Static circular obstacles, indexed once; ``sensed`` finds those whose boundary is within reach."""

    def __init__(self, centers: np.ndarray, radii: np.ndarray, sensing_radius: float) -> None:
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 2)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.sensing_radius = float(sensing_radius)
        reach = self.sensing_radius + (float(self.radii.max()) if len(self.radii) else 0.0)
        self.index = CellIndex(self.centers, reach)

    def sensed(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(agent index, obstacle index) with |P - C| - rho <= sensing_radius."""
        if len(self.centers) == 0:
            empty = np.zeros(0, dtype=np.intp)
            return empty, empty
        i, m = self.index.candidates(points)
        d = points[i] - self.centers[m]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        keep = dist - self.radii[m] <= self.sensing_radius
        return i[keep], m[keep]
