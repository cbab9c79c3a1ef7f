"""The world's own parts with real objects (a Zenoh session, a recording): its batched intake (against
the one-at-a-time one) and its recorder's prey trail."""

import numpy as np
import pytest

from zswarm.net import messages as msg


def test_a_batched_world_takes_good_records_and_refuses_bad_ones_by_reason():
    """World.take_poses (a tick's poses at once): good records join the arrays and the judge's record;
    a record of another version, one of the other dimension, one under another agent's key and an impossible
    jump are refused, each counted by the reason the per-pose path gives."""
    from world.recorder import WorldRecorder
    from world.world import World
    from zswarm.net.config import open_session, zenoh_config
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="batched", scenario_name="moving-prey", overrides=(("n_agents", 4),))
    keys = spec.keys
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


def _worlds(scenario):
    """A batched and a one-at-a-time world of the same run, on one peer session (nothing connects)."""
    from world.recorder import WorldRecorder
    from world.world import World
    from zswarm.net.config import open_session, zenoh_config
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="both", scenario_name=scenario, overrides=(("n_agents", 6),))
    session = open_session(zenoh_config("peer", scout=False), "t")
    recorder = lambda: WorldRecorder(None, None, None, 6, spec.scenario.dt)  # noqa: E731
    return spec, session, World(spec, session, recorder(), [], batched=True), World(spec, session, recorder(), [])


@pytest.mark.parametrize("scenario", ["moving-prey", "moving-prey-3d"])
def test_the_two_intakes_end_a_tick_with_the_same_swarm(scenario):
    """The same samples into a batched world (a tick at once) and a one-at-a-time world: the same
    counts by reason and the same snapshot the observed step reads, in 2-D and 3-D."""
    spec, session, batched, single = _worlds(scenario)
    keys, dims = spec.keys, spec.scenario.dimensions
    rng = np.random.default_rng(5)
    try:
        for tick in range(1, 30):
            samples = []
            for who in rng.permutation(6).tolist() + rng.integers(0, 6, 2).tolist():  # some twice a tick
                seq = tick + int(rng.integers(0, 2))
                x, y = 0.3 * who + 0.01 * tick + (3.0 if rng.random() < 0.05 else 0.0), float(rng.normal(0, 0.1))
                extra = dict(z=float(rng.normal(0, 0.1)), vz=0.1) if dims == 3 else dict(
                    heading=float(rng.uniform(-3, 3)) if who == 5 else None)
                if rng.random() < 0.05:  # now and then a pose of the other dimension
                    extra = dict(z=0.0, vz=0.0) if dims == 2 else {}
                p = msg.Pose(who, seq, 100.0 + 0.05 * tick, -1, x, y, 0.2, -0.1, safety=int(rng.integers(0, 4)), **extra)
                key_of = who if rng.random() > 0.05 else (who + 1) % 6
                samples.append((keys.pose(keys.cell(x, y), key_of), msg.encode(p)))
            samples.append((keys.pose((0, 0), 1), b"\xc1" + bytes(63)))
            now = 100.0 + 0.05 * tick + 0.01
            batched.take_poses([k for k, _ in samples], [p for _, p in samples], now)
            for key, payload in samples:
                single.handle(("pose", key, payload, False, now))
            a, b = batched.intake.latest(set(range(6))), single.intake.latest(set(range(6)))
            assert a.ids.tolist() == b.ids.tolist()
            for x, y in zip(a[1:], b[1:]):
                assert (x is None and y is None) or np.array_equal(x, y, equal_nan=True)
        assert batched.rejected.counts == single.rejected.counts and batched.received == single.received
        assert {"jump", "schema", "dimensions", "version"} <= set(single.rejected.counts)
        assert {w: t.stamps for w, t in batched.timed.tracks.items()} == {w: t.stamps for w, t in single.timed.tracks.items()}
    finally:
        session.close()


def test_the_world_sends_the_prey_as_data_and_only_ticks_ahead_of_it():
    """The prey goes to every agent every tick as ordinary data, batched with the poses (sent express,
    it left the router as one write per agent a tick, and the poses' latency p99 rose by half at
    N = 50: docs/benchmarks.md). A tick goes ahead of data and waits for room; a repeated final tick
    goes at once and may be dropped. Real Zenoh: the QoS each sample arrives with."""
    import time
    from types import SimpleNamespace

    import zenoh

    from world.world import World
    from zswarm.net import messages as msg

    heard: dict[str, tuple] = {}
    with zenoh.open(zenoh.Config()) as session:
        session.declare_subscriber("w/**", lambda s: heard.setdefault(
            str(s.key_expr), (s.express, s.priority, s.congestion_control)))
        world = SimpleNamespace(session=session, sent=0)
        World.publish(world, "w/prey", msg.Prey(1, time.time(), 1, 0.0, 0.0))
        World.publish(world, "w/tick", msg.Tick(1, time.time(), 0.0, 0.0))
        World.publish(world, "w/again", msg.Tick(2, time.time(), 0.0, 0.0, final=True), again=True)
        deadline = time.monotonic() + 10.0
        while len(heard) < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert heard["w/prey"] == (False, zenoh.Priority.DATA, zenoh.CongestionControl.DROP)
    assert heard["w/tick"] == (True, zenoh.Priority.INTERACTIVE_HIGH, zenoh.CongestionControl.BLOCK)
    assert heard["w/again"] == (True, zenoh.Priority.DATA, zenoh.CongestionControl.DROP)
    assert world.sent == 3


def test_tokens_that_go_just_before_the_worlds_own_link_go_with_it():
    """A router that stops closes its clients' links in turn: the world can hear an agent's token go a
    moment before it loses its own link. That agent is cut off with the rest, not crashed (a real
    router session, closed under a real client world)."""
    import time

    from world.recorder import WorldRecorder
    from world.world import World
    from zswarm.host.procs import free_port
    from zswarm.net.config import connected, open_session, zenoh_config
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="cutoff", scenario_name="moving-prey", overrides=(("n_agents", 3),))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = open_session(zenoh_config("router", listen=[endpoint]), "router")
    with open_session(zenoh_config("client", connect=[endpoint]), "world", retry_for=10.0) as session:
        world = World(spec, session, WorldRecorder(None, None, None, 3, spec.scenario.dt), [])
        for who in range(3):
            world._on_liveliness(who, deleted=False)
        assert connected(session)
        world._on_liveliness(0, deleted=True)  # the router closed agent 0's link first
        router.close()
        deadline = time.monotonic() + 10.0
        while connected(session) and time.monotonic() < deadline:
            time.sleep(0.01)
        world._on_liveliness(1, deleted=True)
        world._on_liveliness(2, deleted=True)
        world.settle_departures(force=True)
    assert {d["id"]: d["how"] for d in world.census.departures} == {0: "world cut off", 1: "world cut off",
                                                                     2: "world cut off"}
    assert world.census.cut_off == {0, 1, 2}
