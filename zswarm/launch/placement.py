"""Which node runs which agent: by space (agents that start near each other share a node, so most of
their neighbour traffic stays on one router), or round-robin.

:func:`place` splits the spawn positions k-d style: the widest axis is cut where the nodes on each side
get their share of agents, recursively, so each node receives a compact block of the start. Shares are
in proportion to the nodes' CPUs. The figure the choice is judged by is a run's ``cross_router_share``
(each agent counts the poses it takes in from another router). :func:`replace` makes the split anew
as the swarm moves, with the fewest moves (``zswarm run --migrate-every``).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

PLACEMENTS = ("space", "round-robin")


def shares(n: int, capacities: Sequence[float]) -> list[int]:
    """``n`` agents over nodes in proportion to ``capacities`` (largest remainders; sums to ``n``). A
    node of capacity 0 (a head started with ``--num-cpus 0``) gets no agent, only its router."""
    caps = np.asarray(capacities, float)
    if len(caps) == 0 or np.any(caps < 0) or caps.sum() <= 0:
        raise ValueError("the nodes need CPUs: every capacity >= 0 and one at least > 0")
    exact = n * caps / caps.sum()
    out = np.floor(exact).astype(int)
    for k in np.argsort(-(exact - out), kind="stable")[: n - out.sum()]:  # never a node of capacity 0
        out[k] += 1
    return out.tolist()


def place(spawns: np.ndarray, capacities: Sequence[float], how: str = "space") -> list[int]:
    """The node of each agent (index into ``capacities``), for spawn positions ``spawns`` (N x D)."""
    n = len(spawns)
    counts = shares(n, capacities)
    if how == "round-robin":
        out, k = [], 0
        left = list(counts)
        for _ in range(n):  # deal ids in turn, skipping nodes that are full
            while left[k % len(left)] == 0:
                k += 1
            out.append(k % len(left))
            left[k % len(left)] -= 1
            k += 1
        return out
    if how != "space":
        raise ValueError(f"placement is one of {', '.join(PLACEMENTS)} (got {how!r})")
    node = np.zeros(n, dtype=int)
    _split(np.asarray(spawns, float), np.arange(n), list(range(len(counts))), counts, node)
    return node.tolist()


def replace(points: np.ndarray, current: Sequence[int], capacities: Sequence[float]) -> list[int]:
    """Where the agents now at ``points`` should run, given where they run (``current``): the space
    split made anew (:func:`place`), its blocks handed to nodes so that as few agents as possible
    move. Greedily, the block and node that share the most agents first; a block only goes to a node
    of its own share (equal capacities: any node), so each node keeps its share."""
    current = np.asarray(current, dtype=int)
    k = len(capacities)
    block = np.asarray(place(points, capacities, "space"), dtype=int)
    counts = shares(len(block), capacities)
    overlap = np.zeros((k, k), dtype=int)  # [block, node]
    np.add.at(overlap, (block, current), 1)
    pairs = sorted(((int(overlap[b, m]), -b, -m) for b in range(k) for m in range(k) if counts[b] == counts[m]),
                   reverse=True)
    node_of_block: dict[int, int] = {}
    taken: set[int] = set()
    for _, b, m in pairs:
        if -b not in node_of_block and -m not in taken:
            node_of_block[-b] = -m
            taken.add(-m)
    return [node_of_block[b] for b in block.tolist()]


def _split(points: np.ndarray, ids: np.ndarray, nodes: list[int], counts: list[int], out: np.ndarray) -> None:
    if len(nodes) == 1:
        out[ids] = nodes[0]
        return
    half = len(nodes) // 2
    left_n = sum(counts[nodes[k]] for k in range(half))
    sub = points[ids]
    axis = int(np.argmax(np.ptp(sub, axis=0))) if len(ids) else 0
    order = ids[np.lexsort((ids, sub[:, axis]))] if len(ids) else ids  # ties broken by id: deterministic
    _split(points, order[:left_n], nodes[:half], counts, out)
    _split(points, order[left_n:], nodes[half:], counts, out)
