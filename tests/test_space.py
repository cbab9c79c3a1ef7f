"""Three dimensions (dimensions = 3): the model, both simulators and the recording in R^3; 2-D untouched."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from conftest import run_cli
from zswarm.errors import UsageError
from zswarm.design.guidelines import check
from zswarm.design.swarm_checks import packing_bound
from zswarm.swarm.faults import FaultModel
from zswarm.paper.neighbours import pairs_within
from zswarm.paper.params import DEFAULT_PARAMS
from zswarm.paper.field import field
from zswarm.swarm.prey import PreyMotion, step
from zswarm.swarm.scenarios import get_scenario
from zswarm.record.replay import load_run
from zswarm.sim.batch import Member, simulate_batch
from zswarm.sim.simulator import simulate


@pytest.mark.parametrize("name", ["moving-prey-3d", "window-3d"])
def test_the_3d_scenarios_reach_their_prey_with_no_collision_and_pass_the_guidelines(name):
    scenario = get_scenario(name)
    assert scenario.dimensions == 3 and check(scenario.params, dt=scenario.dt).ok
    run = simulate(scenario, 0, keep_trajectory=True)
    s = run.summary
    assert s["capture_time"] is not None and s["collisions"] == 0 and s["obstacle_collisions"] == 0
    assert s["final_components"] == 1 and s["min_obstacle_clearance"] > scenario.params.margins.d_m_ro
    if name == "window-3d":
        _passes_the_window(run.trajectory)


def _passes_the_window(x: np.ndarray) -> None:
    """window-3d: every agent crossed the wall (x = 0), and through its window, not round it."""
    assert x.shape[-1] == 3 and (x[0, :, 0] < -2.0).all() and (x[-1, :, 0] > 1.0).all()  # all crossed x = 0
    crossing = [x[np.argmax(x[:, i, 0] > 0.0), i] for i in range(x.shape[1])]
    assert all(abs(p[1]) < 0.8 and abs(p[2]) < 0.8 for p in crossing)  # through the window, not round the wall


def test_pairs_in_3d_are_every_pair_within_the_radius():
    rng = np.random.default_rng(3)
    points = rng.uniform(-2.0, 2.0, (300, 3))
    i, j = pairs_within(points, 0.6)
    d = np.linalg.norm(points[:, None] - points[None], axis=-1)
    want = {(a, b) for a, b in zip(*np.nonzero(d <= 0.6)) if a != b}
    assert set(zip(i.tolist(), j.tolist())) == want and len(want) > 300


def test_the_3d_force_is_minus_the_gradient_of_the_potential():
    p = DEFAULT_PARAMS.potential
    rng = np.random.default_rng(5)
    x = rng.uniform(-1.0, 1.0, (4, 3))
    obstacle = np.array([0.3, -0.2, 0.4])

    def energy(pos: np.ndarray) -> float:
        i, j = np.nonzero(~np.eye(4, dtype=bool))
        u, _ = field(pos - np.array([1.0, 0.5, -0.5]), np.arange(4), pos - obstacle, i, pos[i] - pos[j], p)
        return float(u[0])

    i, j = np.nonzero(~np.eye(4, dtype=bool))
    _, f = field(x - np.array([1.0, 0.5, -0.5]), np.arange(4), x - obstacle, i, x[i] - x[j], p)
    h = 1e-6
    grad = [(energy(x + h * e) - energy(x - h * e)) / (2 * h) for e in
            (np.eye(12)[k].reshape(4, 3) * np.eye(4)[0][:, None] for k in range(3))]
    np.testing.assert_allclose(f[0], -np.array(grad), rtol=1e-5, atol=1e-7)


def test_the_packing_bound_holds_for_a_dense_3d_lattice():
    """Face-centred cubic, the densest packing: the points d_min apart within R of one of them."""
    d_min, radius = 0.25, 1.0
    a = d_min * math.sqrt(2.0)  # FCC cube side for nearest neighbours d_min apart
    k = int(radius / a) + 2
    base = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    pts = np.array([(np.array(c) + b) * a for c in itertools.product(range(-k, k + 1), repeat=3) for b in base])
    within = int((np.linalg.norm(pts, axis=1) <= radius).sum()) - 1
    assert within <= packing_bound(radius, d_min, 3) and within > packing_bound(radius, d_min, 2)


def test_a_flying_prey_keeps_its_orbit_and_its_speed():
    motion = PreyMotion(kind="circle", speed=0.15, center=(0.5, 0.0, 0.2), radius=0.5, bob=0.25)
    prey = np.array([0.0, 0.0, 0.2])
    for _ in range(400):
        nxt = step(motion, prey, 0.05, np.zeros((0, 3)))
        assert np.linalg.norm(nxt - prey) <= 0.05 * 0.15 * math.sqrt(1 + 0.5**2) * 1.01
        prey = nxt
        angle = math.atan2(prey[1], prey[0] - 0.5)
        assert math.hypot(prey[0] - 0.5, prey[1]) == pytest.approx(0.5) and prey[2] == pytest.approx(
            0.2 + 0.25 * math.sin(angle))


def test_the_batched_simulator_steps_3d_runs_as_the_reference():
    scenario = get_scenario("moving-prey-3d")
    members = [Member(scenario, 0), Member(scenario, 1, FaultModel(latency=0.1, dropout=0.2, seed=1)),
               Member(get_scenario("moving-prey-3d", {"body": "double-integrator"}), 2)]
    batch = simulate_batch(members, 150, keep_trajectory=True)
    for r, m in enumerate(members):
        alone = simulate(m.scenario, m.seed, duration=150 * scenario.dt, keep_trajectory=True, faults=m.faults)
        np.testing.assert_allclose(batch.trajectory[:, r], alone.trajectory, rtol=0, atol=1e-9)
        np.testing.assert_allclose(batch.prey_trajectory[:, r], alone.prey_trajectory, rtol=0, atol=1e-12)


def test_a_3d_recording_holds_3d_states_and_replays_to_its_summary(tmp_path):
    rec = tmp_path / "mp3.rrd"
    res = run_cli("-m", "zswarm", "sim", "--scenario", "moving-prey-3d", "--duration", "20", "--record", str(rec),
                  "--json", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    live = json.loads(res.stdout)
    run = load_run(rec)
    assert run.frames[0].positions.shape == (10, 3) and run.frames[0].prey.shape == (3,)
    ref = simulate(get_scenario("moving-prey-3d"), 0, duration=20.0, keep_trajectory=True)
    np.testing.assert_array_equal(np.stack([f.positions for f in run.frames]), ref.trajectory)
    replay = run_cli("-m", "zswarm", "replay", str(rec), "--json", cwd=tmp_path)
    replayed = json.loads(replay.stdout)
    assert replayed["replay"]["matches_stored_summary"] is True and replayed["capture_time"] == live["capture_time"]
    from rerun.chunk import RrdReader

    names = {n for c in RrdReader(str(rec)).stream().to_chunks() if str(c.entity_path) == "/map/agents"
             for n in c.to_record_batch().schema.names}
    assert "Points3D:positions" in names and "Points2D:positions" not in names  # drawn in a 3-D view


def test_a_3d_scenario_is_refused_where_it_cannot_run():
    with pytest.raises(UsageError, match="a unicycle drives on the ground"):
        get_scenario("moving-prey-3d", {"body": "unicycle"})
    with pytest.raises(UsageError, match="in 3-D, prey_start must be"):
        get_scenario("moving-prey", {"dimensions": 3})


def test_a_3d_scenario_file_reads_and_runs(tmp_path):
    f = tmp_path / "hover.toml"
    f.write_text('dimensions = 3\nprey_start = [1.0, 0.0, 0.5]\nspawn = [-2.0, -0.6, -0.6, -1.0, 0.6, 0.6]\n'
                 'duration = 12.0\n[params]\nn_agents = 6\nsensing_radius = 1.2\n'
                 '[prey]\nkind = "straight"\nspeed = 0.1\nheading_deg = 90.0\nclimb_deg = 30.0\n'
                 '[[obstacles]]\nx = 0.0\ny = 0.0\nz = 1.2\nradius = 0.3\n')
    from zswarm.swarm.scenarios import load_scenario_file

    scenario = load_scenario_file(f)
    assert scenario.dimensions == 3 and scenario.obstacle_arrays()[0].tolist() == [[0.0, 0.0, 1.2]]
    run = simulate(scenario, 0, keep_trajectory=True)
    climbed = run.prey_trajectory[-1] - run.prey_trajectory[0]
    np.testing.assert_allclose(climbed, 0.1 * 12.0 * np.array([0.0, math.cos(math.pi / 6), 0.5]), atol=1e-9)
    assert run.summary["collisions"] == 0 and run.trajectory.shape == (241, 6, 3)


def test_a_3d_agent_learns_it_is_in_a_2d_run_from_the_worlds_first_answer(capsys):
    """The reverse of tests/test_space_procs.py's stranger: a 2-D world answers a query made at z in
    2-D (and says once that a 3-D agent asked); the agent's view refuses the answer and remembers why."""
    from agents.counters import Counters
    from agents.obstacle_view import ObstacleView
    from agents.sensing import Body
    from world.obstacles import ObstacleService
    from zswarm.net import messages as msg
    from zswarm.net.keys import Keys
    from zswarm.net.poses import Rejections

    service = ObstacleService(np.array([[1.0, 0.0]]), np.array([0.3]), "zswarm/r/obstacles", dims=2)
    (_, payload), = service.answer({"x": "0.5", "y": "0.0", "z": "2.0", "r": "1.0"})
    service.answer({"x": "0.5", "y": "0.0", "z": "2.0", "r": "1.0"})
    answer = msg.decode(payload)
    assert answer.dims == 2 and answer.centers == ((1.0, 0.0),)
    assert capsys.readouterr().err.count("a 3-D agent asked this 2-D run for obstacles") == 1
    view = ObstacleView(Keys("r", 1.0, dims=3), Body(0.5, 0.0, z=2.0, vz=0.0), 1.0, Counters(Rejections("t")))
    assert not view.know(answer, (0.5, 0.0, 2.0))
    assert view.foreign_dims == 2 and view.query_at is None and view.obstacles == []
    assert view.know(msg.Obstacles(((1.0, 0.0, 2.0),), (0.3,), dims=3), (0.5, 0.0, 2.0)) and view.foreign_dims == 2


def test_an_agent_in_a_3d_run_refuses_2d_poses_and_takes_3d_ones():
    import time

    from agents.sensing import Body, Sensing
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="sky", scenario_name="moving-prey-3d")
    # sensing holds no transport: samples are handed to it as the bridge would
    s = Sensing(spec, 0, Body(0.0, 0.0, z=0.0, vz=0.0), probe_latency=True)
    now = time.time()
    s.handle(("pose", spec.keys.pose((0, 0, 0), 5), msg.encode(msg.Pose(5, 1, now, -1, 0.5, 0.5, 0.0, 0.0)),
              False, now))
    s.handle(("prey", spec.keys.prey, msg.encode(msg.Prey(1, now, -1, 1.0, 0.0)), False, now))
    assert s.counters.rejections.counts == {"dimensions": 2} and 5 not in s.neighbours.entries and s.prey is None
    s.handle(("pose", spec.keys.pose((0, 0, 0), 6),
              msg.encode(msg.Pose(6, 1, now, -1, 0.5, 0.5, 0.0, 0.0, None, 0.25, 0.0)), False, now))
    s.handle(("prey", spec.keys.prey, msg.encode(msg.Prey(1, now, -1, 1.0, 0.0, 0.5)), False, now))
    assert 6 in s.neighbours.entries and s.prey == (1.0, 0.0, 0.5)
    assert s.counters.rejections.counts == {"dimensions": 2}
