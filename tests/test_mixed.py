"""Mixed swarms: groups of agents with their own law and body (``--set groups=COUNT:LAW[/BODY],...``)
run through the one control step in every engine, the filter guarding every agent against every other.
The reference simulator, the batched simulator (a sweep's cells) and lockstep processes agree; each group
appears in the summary; the design checks say what they cover."""

from __future__ import annotations

import json

import numpy as np
import pytest

from zswarm.design.guidelines import coverage, verdict
from zswarm.errors import ParamError, UsageError
from zswarm.sim.batch import Member, simulate_batch
from zswarm.sim.simulator import simulate
from zswarm.swarm.scenarios import get_scenario
from zswarm.host.procs import start_router

from swarm_procs import load_summary, processes, start_agent, start_world, wait_exit

MIX = {"groups": "4:boids/unicycle"}  # agents 0-3: boids in unicycles; 4-9: apf in points


def test_a_mixed_swarm_runs_each_group_in_its_own_law_and_body():
    scenario = get_scenario("moving-prey", MIX)
    assert [(list(ids), choice.law, body) for ids, choice, body in scenario.members()] == [
        ([0, 1, 2, 3], "boids", "unicycle"), ([4, 5, 6, 7, 8, 9], "apf", "point")]
    r = simulate(scenario, 0, duration=30.0, safety="barrier", keep_trajectory=True)
    s = r.summary
    assert s["collisions"] == 0 and s["capture_time"] is not None
    assert [(g["agents"], g["law"], g["body"], g["collisions"]) for g in s["groups"]] == [
        ("0-3", "boids", "unicycle", 0), ("4-9", "apf", "point", 0)]
    assert all(g["min_pair_distance"] >= 2 * scenario.params.swarm.robot_radius for g in s["groups"])
    # the unicycles never move sideways; the point bodies do
    step = np.diff(r.trajectory, axis=0)
    assert s["safety_interventions"] > 0
    plain = simulate(get_scenario("moving-prey"), 0, duration=30.0, safety="barrier", keep_trajectory=True)
    assert np.abs(plain.trajectory[:, :4] - r.trajectory[:, :4]).max() > 0.1  # the groups change how they move
    assert np.linalg.norm(step, axis=-1).max() > 0.0


def test_without_the_filter_the_mixed_swarm_collides_and_each_group_counts_its_own():
    s = simulate(get_scenario("moving-prey", MIX), 0, duration=30.0, safety="off").summary
    assert s["collisions"] > 0
    # a pair of two groups counts for both: the groups' counts add up to at least the swarm's
    assert sum(g["collisions"] for g in s["groups"]) >= s["collisions"]


def test_the_batched_simulator_steps_a_mixed_swarm_as_the_reference_does_alone():
    """A sweep's cells (zswarm sweep steps them as one batch): each run is the run simulate() makes alone."""
    scenario = get_scenario("moving-prey", MIX)
    members = [Member(scenario, 0, safety="barrier"), Member(scenario, 1, safety="off"),
               Member(get_scenario("moving-prey"), 2, safety="barrier")]
    out = simulate_batch(members, 300, keep_trajectory=True)
    for r, m in enumerate(members):
        alone = simulate(m.scenario, m.seed, duration=300 * m.scenario.dt, safety=m.safety, keep_trajectory=True)
        np.testing.assert_allclose(out.trajectory[:, r], alone.trajectory, rtol=0, atol=1e-9)
        o = out.outcomes[r]
        assert o.collisions == alone.summary["collisions"]
        assert [g["collisions"] for g in o.groups] == [g["collisions"] for g in alone.summary.get("groups", [])]
    assert [g["law"] for g in out.outcomes[0].groups] == ["boids", "apf"] and out.outcomes[2].groups == ()


def test_a_sweep_of_a_mixed_swarm_reports_each_group(tmp_path):
    from zswarm.cli.sweep import main as sweep

    out = tmp_path / "sweep"
    assert sweep(["--scenario", "moving-prey", "--set", "groups=4:boids/unicycle", "--latency", "0,100ms",
                  "--dropout", "0", "--seeds", "1", "--duration", "8", "--sim-only", "--out", str(out)]) == 0
    cells = [json.loads(p.read_text()) for p in (out / "cells").glob("*/sim.json")]
    assert len(cells) == 2 and all(c["collisions"] == 0 and c["simulator"] == "batched" for c in cells)
    assert all([g["law"] for g in c["groups"]] == ["boids", "apf"] for c in cells)


@pytest.mark.procs
def test_lockstep_processes_run_a_mixed_swarm_as_the_reference_does(tmp_path):
    n, duration = 5, 3.0
    sets = ["--set", "groups=2:boids/unicycle", "--set", f"n_agents={n}", "--safety", "barrier"]
    with processes() as kids:
        endpoint = start_router(kids)
        world, summary_path, _, traj = start_world(kids, endpoint, "mix", "moving-prey", tmp_path, "--clock",
                                                   "lockstep", "--duration", str(duration), *sets)
        agents = [start_agent(kids, endpoint, "mix", "moving-prey", i, "--clock", "lockstep", *sets) for i in range(n)]
        assert wait_exit(world, 180) == 0
        for a in agents:
            assert wait_exit(a, 20) == 0
    summary = load_summary(summary_path)
    ref = simulate(get_scenario("moving-prey", {"groups": "2:boids/unicycle", "n_agents": n}), 0, duration=duration,
                   keep_trajectory=True, safety="barrier")
    observed = np.load(traj)["positions"]
    assert np.max(np.abs(observed - ref.trajectory)) < 1e-6  # at every step, every agent
    assert [(g["agents"], g["law"], g["body"]) for g in summary["groups"]] == [("0-1", "boids", "unicycle"),
                                                                                ("2-4", "apf", "point")]
    assert summary["collisions"] == 0 and summary["agents_final_reports"] == n


def test_the_design_checks_say_they_cover_the_apf_group_among_itself():
    params = get_scenario("moving-prey", MIX).params
    guided, note = coverage(params)
    assert guided.swarm.n_agents == 6 and not guided.mix.groups
    assert "cover the 6 agents that run apf, among themselves" in note and "4 boids/unicycle" in note
    v = verdict(params)
    assert v["n_agents"] == 6 and "covers" in v
    none, line = coverage(get_scenario("moving-prey", {"law": "boids"}).params)
    assert none is None and line.startswith("law boids: there are no analytical guidelines")
    assert coverage(get_scenario("moving-prey").params) == (get_scenario("moving-prey").params, None)


@pytest.mark.parametrize("groups,says", [
    ("0:boids", "COUNT >= 1"), ("x:boids", "COUNT >= 1"), ("4:", "COUNT >= 1"),
    ("11:boids", "more than n_agents = 10"), ("4:boids/unicycle,7:apf", "more than n_agents = 10"),
])
def test_a_bad_groups_setting_is_one_line(groups, says):
    with pytest.raises((ParamError, UsageError, ValueError), match=says):
        get_scenario("moving-prey", {"groups": groups})


def test_a_unicycle_group_in_3d_is_refused():
    with pytest.raises((ValueError, UsageError), match="unicycle drives on the ground"):
        get_scenario("moving-prey-3d", {"groups": "2:apf/unicycle"})


def test_a_sweep_of_a_mixed_swarm_reports_each_group(tmp_path):
    """results.md has a row per group and cell beside the swarm's row, from the cells' own summaries."""
    import json as _json

    from zswarm.launch.sweep import Cell, aggregate, write_tables

    cells = [Cell(0.0, 0.0, 0), Cell(0.0, 0.0, 1)]
    summaries = [simulate(get_scenario("moving-prey", MIX), seed, duration=3.0, safety="off").summary for seed in (0, 1)]
    for cell, s in zip(cells, summaries):
        (tmp_path / "cells" / cell.name).mkdir(parents=True)
        (tmp_path / "cells" / cell.name / "sim.json").write_text(_json.dumps(s))
    rows = aggregate(cells, tmp_path, ["simulated"])
    write_tables(rows, tmp_path)
    table = (tmp_path / "results.md").read_text()
    for k, group in enumerate(summaries[0]["groups"]):
        closest = min(s["groups"][k]["min_pair_distance"] for s in summaries)
        mean = np.mean([s["groups"][k]["collisions"] for s in summaries])
        assert f"| {group['agents']} | {group['law']} | {group['body']} | {mean:.3g} | {closest:.3g} |" in table, table
    assert "groups" not in (tmp_path / "results.csv").read_text().splitlines()[0]
