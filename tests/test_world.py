"""The world's own parts with real objects (a Zenoh session, a recording): its batched intake and its
recorder's prey trail."""

import numpy as np

from zswarm.net import messages as msg


def test_a_batched_world_takes_good_records_and_refuses_bad_ones_by_reason():
    """World.take_poses (a tick's poses at once): good records join the arrays and the judge's record;
    a record of another version, one of the other dimension, one under another agent's key and an impossible
    jump are refused, each counted by the reason the per-pose path gives."""
    import asyncio

    from world.recorder import WorldRecorder
    from world.world import World
    from zswarm.net.config import open_session, zenoh_config
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="batched", scenario_name="moving-prey", overrides=(("n_agents", 4),))
    keys = spec.keys
    asyncio.set_event_loop(asyncio.new_event_loop())  # the world makes its events on one
    with open_session(zenoh_config("peer", scout=False), "t") as session:
        world = World(spec, session, WorldRecorder(None, None, None, 4, spec.scenario.dt), [], batched=True)

        def pose(who, seq, x, key=None, **extra):
            p = msg.Pose(who, seq, 10.0, -1, x, 0.0, 0.0, 0.0, **extra)
            return keys.pose(keys.cell(x, 0.0), who if key is None else key), msg.encode(p)
        good = [pose(0, 1, 0.0), pose(1, 1, 0.5), pose(2, 1, 1.0, heading=0.25)]
        bad = [pose(3, 1, 0.0, key=2),                                      # under agent 2's key
               (keys.pose((0, 0), 3), b"\xc1" + b"\0" * 63),                  # a record of version 0
               pose(3, 2, 0.0, z=1.0, vz=0.0)]                              # 3-D in a 2-D run
        world.take_poses(*map(list, zip(*good, *bad)), 10.0)
        world.take_poses(*map(list, zip(pose(0, 2, 5.0), pose(1, 2, 0.51))), 10.05)  # agent 0 jumps
        ids, rows = world.intake.arrays.latest()
        assert ids.tolist() == [0, 1, 2]
        assert world.intake.arrays.position[rows, 0].tolist() == [0.0, 0.51, 1.0]
        assert np.isnan(world.intake.arrays.heading[rows[0]]) and world.intake.arrays.heading[rows[2]] == 0.25
        assert world.rejected.counts == {"schema": 1, "version": 1, "dimensions": 1, "jump": 1}
        assert world.received == 8
        assert sorted(world.timed.tracks) == [0, 1, 2] and len(world.timed.tracks[1].stamps) == 2


def test_a_prey_that_stays_draws_no_trail_and_one_that_moves_draws_its_path(tmp_path):
    """The recorder's prey trail holds the prey's distinct positions: a static goal (large-swarm's) is
    not redrawn as hundreds of copies of one point every step."""
    from world.recorder import WorldRecorder

    rec = WorldRecorder(tmp_path / "r.rrd", None, None, 2, 0.05)
    rec.open("trail", {}, np.zeros((0, 2)), np.zeros(0))
    ids, pos = np.arange(2), np.zeros((2, 2))
    for k in range(5):
        rec.log_step(k, 0.05 * k, ids, pos, pos, np.array([3.0, 1.0]), {})
    assert len(rec.trail) == 1
    for k in range(5, 10):
        rec.log_step(k, 0.05 * k, ids, pos, pos, np.array([3.0 + 0.1 * k, 1.0]), {})
    assert len(rec.trail) == 6
    rec.close({})
    assert (tmp_path / "r.rrd").stat().st_size > 0
