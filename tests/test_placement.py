"""Which node runs which agent (zswarm.launch.placement) and what it saves (zswarm bench placement):
pure functions and the command, no Ray needed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarm_procs import cross_router_share

from zswarm.launch.placement import place, replace, shares
from zswarm.net.keys import in_reach


def test_shares_follow_the_capacities_and_a_node_without_cpus_gets_no_agent():
    assert shares(10, [1, 1]) == [5, 5] and shares(7, [2, 1]) == [5, 2] and sum(shares(5, [1, 1, 1])) == 5
    assert shares(10, [0, 1, 1]) == [0, 5, 5]
    for n, caps in ((1, [0, 1, 1]), (13, [3, 0, 2, 5]), (1000, [16, 16, 8, 0.5])):
        got = shares(n, caps)
        assert sum(got) == n and all(g == 0 for g, c in zip(got, caps) if c == 0)
        assert all(abs(g - n * c / sum(caps)) < 1 for g, c in zip(got, caps))  # largest remainders
    with pytest.raises(ValueError):
        shares(3, [0, 0])


@pytest.mark.parametrize("how", ["space", "round-robin"])
def test_every_agent_gets_a_node_and_each_node_its_share(how):
    rng = np.random.default_rng(3)
    points = rng.uniform(-10, 10, size=(101, 2))
    node = place(points, [2, 1, 1, 0], how)
    assert len(node) == 101 and np.bincount(node, minlength=4).tolist() == shares(101, [2, 1, 1, 0])


def test_space_placement_keeps_neighbours_together_and_round_robin_does_not():
    """On a 20 x 20 grid over 4 nodes, the poses a cell rule delivers cross nodes far less often when
    the grid is split by space; and the share is what it says on a small hand-made case."""
    g = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0)), axis=-1).reshape(-1, 2)
    meets = in_reach(g, 1.55, 1.5)
    share = {}
    for how in ("space", "round-robin"):
        node = np.asarray(place(g, [1, 1, 1, 1], how))
        share[how] = (meets & (node[:, None] != node[None, :])).sum() / meets.sum()
        heard = {i: {int(j): 1 for j in np.flatnonzero(meets[i])} for i in range(len(g))}
        assert cross_router_share(heard, dict(enumerate(node.tolist()))) == pytest.approx(share[how])
    assert share["space"] < 0.25 * share["round-robin"], share
    assert cross_router_share({0: {1: 3, 2: 1}, 1: {0: 4}}, {0: 0, 1: 1, 2: 0}) == pytest.approx(7 / 8)
    assert cross_router_share({}, {0: 0}) is None


def test_a_new_split_moves_as_few_agents_as_it_can_and_keeps_each_share():
    """replace: a swarm that has not moved stays where it is, whatever the nodes were called; one that
    moved keeps each node's share and moves fewer agents than handing the new blocks out as numbered."""
    rng = np.random.default_rng(5)
    points = rng.uniform(-10, 10, size=(90, 2))
    first = np.asarray(place(points, [1, 1, 1], "space"))
    renamed = (first + 1) % 3  # the same blocks, on other nodes
    assert replace(points, renamed, [1, 1, 1]) == renamed.tolist()
    turned = points @ np.array([[0.0, -1.0], [1.0, 0.0]])  # a quarter turn about the origin
    new = np.asarray(replace(turned, first, [1, 1, 1]))
    as_numbered = np.asarray(place(turned, [1, 1, 1], "space"))
    assert np.bincount(new, minlength=3).tolist() == shares(90, [1, 1, 1])
    assert (new != first).sum() <= (as_numbered != first).sum()
    assert sorted(np.unique(as_numbered)) == sorted(np.unique(new))
    # unequal capacities: a block only goes to a node of its own share
    caps = [2, 1, 1]
    base = np.asarray(place(points, caps, "space"))
    got = np.asarray(replace(turned, base, caps))
    assert np.bincount(got, minlength=3).tolist() == shares(90, caps)


def test_bench_placement_reports_both_shares(cli):
    res = cli("-m", "zswarm", "bench", "placement", "--agents", "30", "--nodes", "3", "--duration", "3",
              "--samples", "5", "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    assert 0 < out["space"] < out["round_robin"] < 1 and out["ratio"] == pytest.approx(out["space"] / out["round_robin"])
    assert 0 < out["space_replaced"] < out["round_robin"]
    assert out["migrate_every"] == 10.0 and out["moves"] == 0  # a 3 s run is never moved
    moved = json.loads(cli("-m", "zswarm", "bench", "placement", "--agents", "60", "--nodes", "3", "--duration", "20",
                           "--samples", "20", "--migrate-every", "2", "--json").stdout)
    assert moved["moves"] > 0 and moved["space_migrated"] < moved["space"]
    assert moved["ratio_migrated"] == pytest.approx(moved["space_migrated"] / moved["round_robin"])
    bad = cli("-m", "zswarm", "bench", "placement", "--agents", "3", "--nodes", "5")
    assert bad.returncode == 2 and "--nodes between 1 and N" in bad.stderr


def test_migration_moves_only_the_agents_it_may_and_looks_again_every_period():
    from zswarm.launch.migration import Migration

    m = Migration(5.0)
    assert not m.due(4.9) and m.due(5.0)
    rng = np.random.default_rng(2)
    ids = np.arange(30)
    positions = np.column_stack([np.where(ids < 15, -5.0, 5.0) + rng.uniform(-1, 1, 30), rng.uniform(-1, 1, 30)])
    where = {int(i): int(i) % 2 for i in ids}  # dealt in turn: half of each side on the wrong router
    moves = m.plan(7.3, ids, positions, where, [1.0, 1.0], busy={0, 15})  # still moving: left where they are
    moved = {a for a, _, _, _ in moves}
    assert not moved & {0, 15} and all(where[a] == frm != to for a, frm, to, _ in moves)
    after = {**where, **{a: to for a, _, to, _ in moves}}
    left = {after[i] for i in range(1, 15)}
    assert len(left) == 1 and {after[i] for i in range(16, 30)} == {1 - left.pop()}  # one side a router
    assert len(moves) == 14  # half of each side was on the other router
    assert m.next_at == 10.0 and not m.due(9.9)
    s = m.summary(30)
    assert s["moves"] == len(moves) and s["epochs"] == 1 and sum(s["moved"].values()) == len(moves)
