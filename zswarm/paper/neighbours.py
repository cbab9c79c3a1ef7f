"""Who senses whom: a uniform cell grid, so finding pairs costs O(N k), not O(N^2).

Points (in 2-D or 3-D: the dimension is the last axis) are bucketed into square cells (cubes) of side
``cell``; a query looks only at the 3 x 3 (3 x 3 x 3) block of cells around each query point, which
holds every target within ``cell`` of it. Everything is vectorized (sorting, ``searchsorted`` and
``repeat``); there is no Python loop over agents.
"""

from __future__ import annotations

import itertools

import numpy as np

#: Cell indices are offset by this per dimension and packed into one int64 key (2-D: 2^31 cells a side;
#: 3-D: 2^21).
_OFFSET = {2: np.int64(1 << 30), 3: np.int64(1 << 20)}


def step_reach(v_max, dt):
    """2 v_max dt: how much closer two agents can come in one step (each moves v_max dt)."""
    return 2.0 * v_max * dt


def subscription_radius(sensing_radius, v_max, dt):
    """R + 2 v_max dt: the disc about an agent whose cells it listens to, so that whoever can enter its
    sensing disc by the next step is heard already. The one home of that disc: the agents' cells, the
    simulated channel's, the benchmarks' and the world's count of poses in reach (numbers or arrays)."""
    return sensing_radius + step_reach(v_max, dt)


def cell_meets(point: np.ndarray, other: np.ndarray, r, cell_size) -> np.ndarray:
    """Whether the cell (a square, in 3-D a cube, of side ``cell_size`` on the grid through the origin)
    that holds ``other`` meets the disc (ball) of radius ``r`` about ``point``, broadcast over leading
    axes: the one home of which cells an agent listens to, as a test on positions
    (:func:`zswarm.net.keys.cells_in_disc` lists the same cells by key)."""
    lo = np.floor(np.asarray(other, dtype=float) / cell_size) * cell_size
    gap = np.clip(point, lo, lo + cell_size) - point
    return np.einsum("...k,...k->...", gap, gap) <= np.square(r)


def _keys(cells: np.ndarray) -> np.ndarray:
    off = _OFFSET[cells.shape[1]]
    key = cells[:, 0] + off
    for d in range(1, cells.shape[1]):
        key = key * (2 * off) + (cells[:, d] + off)
    return key


def _points(points: np.ndarray, dims: int | None = None) -> np.ndarray:
    """Points as an (N, D) float array (D from the array, or ``dims`` for an empty one)."""
    a = np.asarray(points, dtype=float)
    d = dims or (a.shape[-1] if a.ndim >= 2 and a.shape[-1] in (2, 3) else 2)
    return a.reshape(-1, d)


class CellIndex:
    """Targets bucketed by cell; ``candidates`` returns every (query, target) pair in adjacent cells."""

    def __init__(self, targets: np.ndarray, cell: float) -> None:
        if not cell > 0:
            raise ValueError(f"cell size must be > 0 (got {cell})")
        self.targets = _points(targets)
        self.dims = self.targets.shape[1]
        self.cell = float(cell)
        keys = _keys(np.floor(self.targets / self.cell).astype(np.int64))
        self.order = np.argsort(keys, kind="stable")
        self.sorted_keys = keys[self.order]

    def candidates(self, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(query index, target index) for every target in the 3 x 3 cells around each query point.

        The last coordinate is the key's least significant part, so the three cells a row (column) of
        the block holds along it have consecutive keys: one slice of the sorted targets each, found
        with two searches (3 rows in 2-D, 9 in 3-D, not 9 or 27 cells)."""
        query = _points(query, self.dims)
        base = np.floor(query / self.cell).astype(np.int64)
        q_parts, t_parts = [], []
        for shift in itertools.product((-1, 0, 1), repeat=self.dims - 1):
            keys = _keys(base + np.array((*shift, 0), dtype=np.int64))
            lo = np.searchsorted(self.sorted_keys, keys - 1, side="left")
            hi = np.searchsorted(self.sorted_keys, keys + 1, side="right")
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


#: Up to this many points, :func:`pairs_within` compares every pair at once, an (N, N) matrix, in the
#: batched simulator's order (so a run alone equals its run in a batch exactly). Against the cell index:
#: N = 10: 7 us against 69; N = 50: 45 against 89; N = 100: 160 against 116; N = 200: 620 against 170
#: (``large-swarm``'s spawn, radius 1): from about N = 80 the cells are cheaper, by little below 128.
DENSE_MAX = 128


def pairs_within(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Ordered pairs (i, j), i != j, with |p_i - p_j| <= radius; each unordered pair appears twice.
    Up to :data:`DENSE_MAX` points in row-major order (by i, then j); beyond, in the cell index's order."""
    points = _points(points)
    if len(points) <= DENSE_MAX:
        d = points[:, None, :] - points[None, :, :]
        near = np.einsum("ijk,ijk->ij", d, d) <= radius * radius
        np.fill_diagonal(near, False)
        i, j = np.nonzero(near)
        return i.astype(np.intp), j.astype(np.intp)
    return cell_pairs(points, radius)


def cell_pairs(points: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pairs_within` through the cell index, whatever N (the path beyond :data:`DENSE_MAX`)."""
    points = _points(points)
    i, j = CellIndex(points, radius).candidates(points)
    # squared distances a coordinate at a time, from contiguous columns: the same sums as an einsum
    # over the rows (so the same pairs, in the same order), in half the time (N = 1000: 0.9 ms, not 1.9)
    first, *rest = points.T.copy()
    d2 = first[i]
    d2 -= first[j]
    d2 *= d2
    for column in rest:
        dc = column[i]
        dc -= column[j]
        dc *= dc
        d2 += dc
    keep = d2 <= radius * radius
    keep &= i != j
    return i[keep], j[keep]


class ObstacleIndex:
    """Static circular (spherical) obstacles, indexed once; ``sensed`` finds those whose boundary is within
    reach."""

    def __init__(self, centers: np.ndarray, radii: np.ndarray, sensing_radius: float) -> None:
        self.centers = _points(centers)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.sensing_radius = float(sensing_radius)
        reach = self.sensing_radius + (float(self.radii.max()) if len(self.radii) else 0.0)
        self.index = CellIndex(self.centers, reach)

    def sensed(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(agent index, obstacle index) with |P - C| - rho <= sensing_radius."""
        if len(self.centers) == 0:
            empty = np.zeros(0, dtype=np.intp)
            return empty, empty
        points = _points(points, self.centers.shape[1])
        if len(points) * len(self.centers) <= DENSE_MAX * DENSE_MAX:  # every pair at once, as pairs_within
            i, m = np.indices((len(points), len(self.centers))).reshape(2, -1)
        else:
            i, m = self.index.candidates(points)
        d = points[i] - self.centers[m]
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        keep = dist - self.radii[m] <= self.sensing_radius
        return i[keep], m[keep]


def obstacle_clearance(points: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """|P - C| - rho (the |psi^o| that Props 1-2 bound), broadcast over points and obstacles."""
    d = points - centers
    return np.sqrt(np.einsum("...k,...k->...", d, d)) - radii
