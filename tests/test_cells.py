"""Which spatial cells an agent listens to: the cells its subscription disc meets, re-chosen only when
it has moved far enough for that set to change."""

from __future__ import annotations

import math
import time

import numpy as np
import zenoh
from hypothesis import example, given, settings
from hypothesis import strategies as st

from agents.outreach import Outreach
from agents.sensing import Body, Sensing
from zswarm.net.bridge import Bridge
from zswarm.net.config import zenoh_config
from zswarm.net.keys import Keys, cells_in_disc, cells_in_disc_margin, in_reach_counts
from zswarm.net.runspec import RunSpec

coord = st.floats(-50, 50, allow_nan=False)
KEYS = Keys("cells", cell_size=1.0)


@settings(max_examples=300, deadline=None)
@given(coord, coord, st.floats(0.05, 3.0), st.floats(0, 2 * math.pi), st.floats(0, 0.999))
@example(0.0, 0.0, 1.9999999999999996, 0.0, 0.75)  # a disc a rounding error inside a cell's edge
def test_the_cells_stay_the_same_within_the_margin(x, y, r, angle, fraction):
    cells, margin = cells_in_disc_margin(KEYS, (x, y), r)
    assert cells == cells_in_disc(KEYS, (x, y), r)
    assert 0.0 <= margin <= KEYS.cell_size
    step = fraction * margin
    assert cells_in_disc(KEYS, (x + step * math.cos(angle), y + step * math.sin(angle)), r) == cells


@settings(max_examples=200, deadline=None)
@given(coord, coord, st.floats(0.05, 3.0))
def test_the_margin_is_tight(x, y, r):
    """Some move of a little more than the margin changes the set (unless the margin is a whole cell)."""
    cells, margin = cells_in_disc_margin(KEYS, (x, y), r)
    if margin >= KEYS.cell_size or margin < 1e-9:
        return
    step = 1.1 * margin
    assert any(cells_in_disc(KEYS, (x + step * math.cos(a), y + step * math.sin(a)), r) != cells
               for a in np.linspace(0.0, 2 * math.pi, 256, endpoint=False))


def test_an_agent_listens_to_exactly_the_cells_its_disc_meets_along_a_walk():
    spec = RunSpec(run="cells", scenario_name="bench-field", overrides=(("n_agents", 4),))
    rng = np.random.default_rng(7)
    with zenoh.open(zenoh_config("peer")) as session:
        sensing = Sensing(spec, 0, Body(0.3, -0.2), probe_latency=True)
        bridge = Bridge(session, None, sensing.handle, batch=True, channels=True)
        body, s = sensing.body, Outreach(sensing, bridge)
        chosen = 0
        for _ in range(400):
            body.x, body.y = body.x + rng.normal(0, 0.04), body.y + rng.normal(0, 0.04)
            at = s.cell_view.chosen_at
            s.follow_cells()
            chosen += s.cell_view.chosen_at is not at
            assert set(s.cells) == cells_in_disc(spec.keys, body.position, sensing.subscription_radius)
            assert {sub for _, sub in bridge.channels} == set(s.cells.values())
        assert chosen < 300  # most ticks keep the cells without working them out again
        bridge.close()


def test_a_moving_agent_asks_a_cell_for_its_poses_only_where_it_could_not_have_heard_them_coming():
    """At its start, after a jump and on a takeover an agent asks each new cell for the poses in it; a
    cell its grown disc reaches while it moves holds nobody it could have missed (their next poses come
    first), and asking would cost each agent there an answer (agents.outreach.Outreach.follow_cells).
    Who sits in a new cell (its member tokens) is asked every time. Real Zenoh: the queries that reach a
    queryable on every cell."""
    spec = RunSpec(run="asks", scenario_name="bench-field", overrides=(("n_agents", 4),))
    asked = {"poses": 0}
    with zenoh.open(zenoh_config("peer")) as session:
        session.declare_queryable("zswarm/asks/pose/**", lambda q: asked.__setitem__("poses", asked["poses"] + 1))
        sensing = Sensing(spec, 0, Body(0.3, -0.2), probe_latency=True)
        bridge = Bridge(session, None, sensing.handle, batch=True, channels=True)
        body, s = sensing.body, Outreach(sensing, bridge)
        step = 0.9 * sensing.v_max * sensing.dt  # less than a tick's worth of motion at v_max

        def walk(ticks: int) -> int:
            before, entered = asked["poses"], 0
            for _ in range(ticks):
                body.x += step
                held = set(s.cells)
                s.follow_cells()
                entered += len(set(s.cells) - held)
            time.sleep(0.3)  # the asks' way through the session
            assert entered > 0  # it crossed cells
            return asked["poses"] - before

        def follow(ask: bool = False) -> int:
            """Follow once; how many cells were new, and how many asks came of it."""
            before, held = asked["poses"], set(s.cells)
            s.follow_cells(ask)
            time.sleep(0.3)  # the asks' way through the session
            return len(set(s.cells) - held), asked["poses"] - before

        new, asks = follow()  # its start
        assert new > 0 and asks == new
        assert walk(60) == 0  # moving: no asks
        body.x += 5.0  # a jump (an odometry reset): every new cell asked
        new, asks = follow()
        assert new > 0 and asks == new
        new = 0
        while not new:  # a takeover's state, close by: asked all the same
            body.x += step
            new, asks = follow(ask=True)
        assert asks == new
        bridge.close()


def test_in_reach_counts_the_others_in_the_cells_each_disc_meets():
    rng = np.random.default_rng(3)
    for n, side, r, dims in ((2, 2.0, 1.1, 2), (30, 6.0, 1.1, 2), (80, 12.0, 0.7, 2), (40, 5.0, 1.1, 3)):
        pos = rng.uniform(-side / 2, side / 2, (n, dims))
        expected = [sum(1 for j in range(n) if j != i and KEYS.cell(*pos[j]) in cells_in_disc(KEYS, pos[i], r))
                    for i in range(n)]
        assert in_reach_counts(pos, r, KEYS.cell_size).tolist() == expected


def test_in_reach_counts_per_cell_equal_the_pair_matrix_on_and_off_the_cell_edges():
    from zswarm.net.keys import in_reach

    rng = np.random.default_rng(5)
    for n, side, r, size, dims in ((500, 20.0, 1.55, 1.5, 2), (300, 8.0, 1.1, 1.0, 3), (200, 6.0, 0.4, 1.0, 2),
                                   (150, 9.0, 3.2, 1.5, 2)):
        pos = rng.uniform(-side / 2, side / 2, (n, dims))
        pos[: n // 3] = np.round(pos[: n // 3] / size * 2) * size / 2  # a third on cell edges and corners
        assert in_reach_counts(pos, r, size).tolist() == in_reach(pos, r, size).sum(axis=1).tolist()
    assert in_reach_counts(np.zeros((0, 2)), 1.0, 1.0).tolist() == []


@settings(max_examples=150, deadline=None)
@given(coord, coord, coord, st.floats(0.05, 2.5), st.floats(0, 2 * math.pi), st.floats(0, math.pi),
       st.floats(0, 0.999))
def test_voxels_stay_the_same_within_the_margin(x, y, z, r, azimuth, polar, fraction):
    """In 3-D the cells are voxels and the disc a ball: the same margin rule holds along any direction."""
    keys = Keys("cells", cell_size=1.0, dims=3)
    cells, margin = cells_in_disc_margin(keys, (x, y, z), r)
    assert all(len(c) == 3 for c in cells) and 0.0 <= margin <= 1.0
    step = fraction * margin
    d = (math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth), math.cos(polar))
    assert cells_in_disc(keys, (x + step * d[0], y + step * d[1], z + step * d[2]), r) == cells
