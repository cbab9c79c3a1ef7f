"""The reference simulator reproduces the paper's qualitative results, deterministically."""

import json

import numpy as np
import pytest
from swarm_procs import map_agents, scalar_series

from zswarm.args import UsageError
from zswarm.paper.field import sense_one
from zswarm.swarm.prey import step
from zswarm.swarm.scenarios import SCENARIOS, get_scenario, load_scenario_file
from zswarm.sim.simulator import Simulator, simulate


def test_goal_near_obstacle_additive_traps_multiplicative_reaches():
    """Figs 3-6: eq 12 leaves every agent stuck away from the goal; eq 14 brings each within d_m^go."""
    scenario = get_scenario("goal-near-obstacle")
    d_m_go = scenario.params.margins.d_m_go
    add = simulate(scenario, 0, combination="additive", keep_trajectory=True)
    mul = simulate(scenario, 0, combination="multiplicative", keep_trajectory=True)
    final_add = np.linalg.norm(add.trajectory[-1], axis=1)
    final_mul = np.linalg.norm(mul.trajectory[-1], axis=1)
    assert np.all(final_add > d_m_go) and np.all(final_mul < d_m_go)
    # and the additive agents' distance to the goal has stopped shrinking: a trap, not a slow approach
    earlier = np.linalg.norm(add.trajectory[-41], axis=1)
    assert np.max(np.abs(final_add - earlier)) < 2e-3


@pytest.mark.parametrize("seed", [0, 1])
def test_static_goal_splits_and_regroups_without_collisions(seed):
    """Fig 13: one group, then more than one component while passing the obstacles, then one again."""
    s = simulate(get_scenario("static-goal"), seed).summary
    assert s["max_components_after_joined"] > 1
    assert s["final_components"] == 1
    assert s["collisions"] == 0 and s["obstacle_collisions"] == 0
    assert s["capture_time"] is not None and s["final_centroid_goal_distance"] < 0.1


@pytest.mark.parametrize("name", ["moving-prey", "moving-prey-straight", "moving-prey-evasive"])
def test_moving_prey_is_tracked_with_bounded_lag(name):
    """Fig 14: the swarm catches the slower prey and stays within the capture radius afterwards."""
    scenario = get_scenario(name)
    s = simulate(scenario, 0).summary
    assert s["capture_time"] is not None and s["collisions"] == 0
    assert s["max_lag_after_capture"] <= scenario.capture_radius + 0.05


def test_same_seed_same_summary_bytes_different_seed_different_start():
    scenario = get_scenario("static-goal")
    a = json.dumps(simulate(scenario, 7, duration=5.0).summary, sort_keys=True)
    b = json.dumps(simulate(scenario, 7, duration=5.0).summary, sort_keys=True)
    assert a == b
    p7 = Simulator(scenario, 7).positions
    assert np.array_equal(p7, Simulator(scenario, 7).positions)
    assert not np.allclose(p7, Simulator(scenario, 8).positions)


def test_vectorized_step_equals_each_agent_deciding_alone():
    """The simulator's batched forces equal what each agent computes from what it alone senses."""
    scenario = get_scenario("static-goal", {"sensing_radius": 1.5})
    sim = Simulator(scenario, 3)
    for _ in range(40):
        sim.advance(sim.command())
    v = sim.command().command[0]
    centers, radii = scenario.obstacle_arrays()
    p = scenario.params.swarm
    for k, pos in enumerate(sim.positions):
        others = np.delete(sim.positions, k, axis=0)
        sensed = sense_one(pos, centers, radii, others, p.sensing_radius)
        np.testing.assert_allclose(sim.law.velocity(pos, sim.prey, sensed, p.v_max), v[k],
                                   rtol=1e-12, atol=1e-14)


def test_every_scenario_spawns_apart_and_clear_of_obstacles():
    for name in SCENARIOS:
        scenario = get_scenario(name)
        x = Simulator(scenario, 0).positions
        assert len(x) == scenario.n_agents
        d = np.linalg.norm(x[:, None] - x[None], axis=-1) + np.eye(len(x)) * 9
        assert d.min() >= 2 * scenario.params.swarm.robot_radius
        centers, radii = scenario.obstacle_arrays()
        if len(centers):
            gap = np.linalg.norm(x[:, None] - centers[None], axis=-1) - radii[None]
            assert gap.min() > 0.2


def test_large_swarm_scales_with_n():
    small, big = get_scenario("large-swarm", {"n_agents": 100}), get_scenario("large-swarm", {"n_agents": 400})
    assert small.n_agents == 100 and big.n_agents == 400 and len(big.obstacles) > len(small.obstacles)
    s = simulate(small, 0, duration=2.0)
    assert s.summary["n_agents"] == 100


def test_toml_scenario_round_trip_and_errors(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('name = "mine"\nduration = 3.0\nspawn = [-3, -1, -2, 1]\n[params]\nn_agents = 4\n'
                 'c_o = 2.5\n[prey]\nkind = "circle"\nspeed = 0.1\ncenter = [0, 0]\nradius = 0.5\n'
                 '[[obstacles]]\nx = -1.0\ny = 0.0\nradius = 0.3\n')
    s = load_scenario_file(f)
    assert s.name == "mine" and s.n_agents == 4 and s.params.potential.c_o == 2.5
    assert s.prey.kind == "circle" and s.obstacles[0].radius == 0.3
    assert simulate(get_scenario(str(f)), 0).summary["n_agents"] == 4
    for text, needle in (("nme = 1\n", "unknown keys"), ("[params]\nc_o = -1\n", "c_o must be"),
                         ("duration = [\n", "not valid TOML"), ("[prey]\nkind = 'x'\n", "prey kind")):
        f.write_text(text)
        with pytest.raises(UsageError, match=needle) as err:
            load_scenario_file(f)
        assert "\n" not in str(err.value)
    with pytest.raises(UsageError, match="does not exist"):
        load_scenario_file(tmp_path / "nope.toml")
    with pytest.raises(UsageError, match="unknown scenario"):
        get_scenario("fig-99")


def test_cli_sim_json_and_recording(cli, tmp_path):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    out = tmp_path / "run.rrd"
    res = cli("-m", "zswarm", "sim", "--scenario", "moving-prey", "--seed", "2", "--duration", "4",
              "--record", str(out), "--json")
    assert res.returncode == 0, res.stderr
    s = json.loads(res.stdout)
    for key in ("scenario", "n_agents", "seed", "potential", "final_mean_goal_distance",
                "final_centroid_goal_distance", "capture_time", "min_pair_distance", "collisions",
                "min_obstacle_clearance", "obstacle_collisions", "max_components", "final_components",
                "max_cohesion", "epsilon"):
        assert key in s
    assert s["scenario"] == "moving-prey" and s["seed"] == 2 and s["steps"] == 80
    assert s["design"] == {"ok": True, "failures": [], "paper_failures": ["prop3"], "interaction": "paper",
                           "n_agents": 10} and "warning" not in res.stderr
    crushed = cli("-m", "zswarm", "sim", "--set", "n_agents=100", "--set", "interaction=paper", "--duration", "0.5",
                  "--json")
    design = json.loads(crushed.stdout)["design"]
    assert crushed.returncode == 0 and not design["ok"] and "swarm" in design["failures"]
    assert crushed.stderr.count("\n") == 1 and "warning: the design fails for this run" in crushed.stderr
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    verify = subprocess.run([rerun, "rrd", "verify", str(out)], capture_output=True, text=True, timeout=60)
    assert verify.returncode == 0, verify.stderr
    # the scalar series, sent as columns every few steps: one row for every step, the last one included
    series = scalar_series(out)
    for path in ("metrics/centroid_goal_distance", "thresholds/capture_radius", "safety/filtered"):
        steps = [step for step, _ in series[path]]
        assert steps == list(range(81)), (path, steps)
    assert series["metrics/centroid_goal_distance"][-1][1] == pytest.approx(s["final_centroid_goal_distance"])
    # the map's agents: labelled once (nobody came or went), their positions at every step
    points = map_agents(out)
    assert [k for k, _, _ in points] == list(range(81)) and all(n == 10 for _, n, _ in points)
    assert [(k, text) for k, _, text in points if text is not None] == [(0, [str(i) for i in range(10)])]


def test_the_maps_labels_are_logged_when_the_agents_change_and_always_name_the_points_shown(tmp_path):
    """zswarm.record.swarm_log.Labels: labels go with the positions when the set of agents changes (a
    departure, a return), and only then; at every step the newest labels name as many agents as the
    newest positions place, in the same order."""
    import rerun as rr

    from zswarm.record import swarm_log

    out = tmp_path / "labels.rrd"
    rec = rr.RecordingStream("zswarm-test-labels")
    rec.save(str(out))
    labels, series = swarm_log.Labels(), swarm_log.Series(rec, every=4)
    agents = [[0, 1, 2]] * 4 + [[0, 2]] * 3 + [[0, 1, 2]] * 2  # agent 1 leaves at step 4, is back at 7
    for k, ids in enumerate(agents):
        ids = np.array(ids)
        swarm_log.set_time(rec, k, 0.05 * k, series)
        positions = np.column_stack([ids + 0.1 * k, np.zeros(len(ids))])
        swarm_log.log_swarm(series, 0.05 * k, ids, positions, np.zeros_like(positions), labels=labels)
    series.flush()
    rec.flush()
    rec.disconnect()
    points = map_agents(out)
    assert [k for k, _, text in points if text is not None] == [0, 4, 7]
    newest = None
    for (k, n, text), ids in zip(points, agents):
        newest = text if text is not None else newest
        assert newest == [str(i) for i in ids] and n == len(ids), k


def test_cli_scenarios_and_bench(cli):
    listing = cli("-m", "zswarm", "scenarios", "--json")
    assert {s["name"] for s in json.loads(listing.stdout)} == set(SCENARIOS)
    bench = cli("-m", "zswarm", "bench", "sim", "--sizes", "10,50", "--steps", "5", "--json")
    out = json.loads(bench.stdout)
    assert [r["n_agents"] for r in out["runs"]] == [10, 50]
    assert all(r["steps_per_second"] > 0 and r["steps"] == 5 for r in out["runs"])
    assert out["cost_ratio_10000_1000"] is None


def test_replay_reproduces_the_simulator_summary_and_compare_prints_both(cli, tmp_path):
    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    assert cli("-m", "zswarm", "sim", "--scenario", "static-goal", "--duration", "6", "--record", str(a)).returncode == 0
    assert cli("-m", "zswarm", "sim", "--scenario", "static-goal", "--duration", "6", "--seed", "1",
               "--record", str(b)).returncode == 0
    res = cli("-m", "zswarm", "replay", str(a), "--json")
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    direct = simulate(get_scenario("static-goal"), 0, duration=6.0).summary
    assert out["replay"]["matches_stored_summary"] is True and out["replay"]["frames"] == 121
    for key in ("min_pair_distance", "final_energy", "max_cohesion", "final_centroid_goal_distance"):
        assert out[key] == direct[key]
    cmp = cli("-m", "zswarm", "compare", str(a), str(b), "--json")
    both = json.loads(cmp.stdout)
    assert both[str(a)]["min_pair_distance"] == direct["min_pair_distance"]
    assert both[str(a)]["min_pair_distance"] != both[str(b)]["min_pair_distance"]
    assert "differ" not in cmp.stderr  # the same scenario, seeds apart: like for like
    c = tmp_path / "c.rrd"  # a 3-D run of another law beside a 2-D one: said in one line
    assert cli("-m", "zswarm", "sim", "--scenario", "moving-prey-3d", "--law", "boids", "--duration", "1",
               "--record", str(c)).returncode == 0
    odd = cli("-m", "zswarm", "compare", str(a), str(c))
    assert odd.returncode == 0 and "warning: the two runs differ in scenario static-goal and moving-prey-3d, " \
        "dimensions 2 and 3, law apf and boids" in odd.stderr, odd.stderr
    missing = cli("-m", "zswarm", "replay", str(tmp_path / "nope.rrd"))
    assert missing.returncode == 2 and "does not exist" in missing.stderr
    (tmp_path / "junk.rrd").write_bytes(b"not a recording")
    junk = cli("-m", "zswarm", "replay", str(tmp_path / "junk.rrd"))
    assert junk.returncode == 2 and "Traceback" not in junk.stderr


def test_spawning_a_large_swarm_takes_memory_in_proportion_to_n():
    """Clearing spawn cells of obstacles used an N x obstacles matrix: 100,000 agents took 24 GB."""
    import tracemalloc

    scenario = get_scenario("large-swarm", {"n_agents": 20000})  # 1,000 obstacles
    tracemalloc.start()
    try:
        positions = scenario.initial_positions(np.random.default_rng(0))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert positions.shape == (20000, 2)
    assert peak < 50e6, f"{peak / 1e6:.0f} MB"  # the N x obstacles way took over 700 MB here


def test_the_arena_frames_every_agent_obstacle_and_the_prey_all_run_long():
    for name in SCENARIOS:
        scenario = get_scenario(name)
        box = scenario.arena(margin=0.0)  # (x0, y0[, z0], x1, y1[, z1])
        d = scenario.dimensions
        assert len(box) == 2 * d, name
        sim = Simulator(scenario, 0)
        inside = lambda p: all(box[k] - 1e-9 <= p[k] <= box[d + k] + 1e-9 for k in range(d))  # noqa: E731
        assert all(inside(p) for p in sim.positions), name
        assert all(inside((o.x + dx * o.radius, o.y + dy * o.radius, o.z + dz * o.radius)) for o in scenario.obstacles
                   for dx, dy, dz in ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1))), name
        prey_framed = name != "bench-field"  # its prey is out of reach on purpose, and out of the frame
        prey = sim.prey
        for _ in range(scenario.steps):  # wherever its motion takes it during the run (agents held at spawn)
            assert inside(prey) == prey_framed, (name, prey)
            prey = step(scenario.prey, prey, scenario.dt, sim.positions)


def test_the_reference_of_a_run_that_ends_after_the_capture_ends_by_the_same_rule():
    """``--end-after-capture 2`` on moving-prey (the reference catches the prey at 26.7 s of 30): a run
    that caught it at 23.35 s ended at 25.35 s, where the reference has caught nothing; its reference is
    simulated to 2 s after its own capture instead. A run without the rule keeps its own duration."""
    from swarm_procs import split_spec

    from zswarm.launch.reference import reference_comparison

    spec = split_spec("r", "moving-prey", "--duration", "30", "--safety", "barrier")[0]
    run = {"duration": 25.35, "capture_time": 23.35, "end_after_capture": 2.0}
    ref = reference_comparison(run, spec)["reference"]
    alone = simulate(get_scenario("moving-prey"), 0, duration=30.0, safety="barrier").summary
    assert ref["capture_time"] == alone["capture_time"] == pytest.approx(26.7)
    ended = simulate(get_scenario("moving-prey"), 0, duration=28.7, safety="barrier").summary
    assert ref == {k: ended[k] for k in ref}  # ended 2 s after its capture, not at 30
    assert ref["min_pair_distance"] == ended["min_pair_distance"]
    cut = reference_comparison({**run, "end_after_capture": None}, spec)["reference"]
    assert cut["capture_time"] is None  # cut at the run's own 25.35 s
