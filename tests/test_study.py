"""zswarm bench guidelines and zswarm bench interactions, small: what they report is what happened."""

from __future__ import annotations

import json

from zswarm.design.guidelines import check
from zswarm.paper.params import Params
from zswarm.swarm.scenarios import get_scenario
from zswarm.sim.outcome import run_outcome
from zswarm.sim.simulator import simulate


def test_the_lean_outcome_is_the_simulators_summary():
    scenario = get_scenario("moving-prey", {"interaction": "mean+gate"})
    lean = run_outcome(scenario, 3)
    full = simulate(scenario, 3).summary
    assert lean.collisions == full["collisions"] and lean.capture_time == full["capture_time"]
    assert lean.obstacle_collisions == full["obstacle_collisions"]
    assert lean.final_components == full["final_components"]
    assert abs(lean.min_pair_distance - full["min_pair_distance"]) < 1e-12
    assert abs(lean.final_median_nearest - full["final_median_nearest"]) < 1e-12


def test_the_guideline_study_tabulates_verdicts_against_outcomes(cli, tmp_path):
    out = tmp_path / "study"
    res = cli("-m", "zswarm", "bench", "guidelines", "--agents", "10", "--sets", "3", "--seeds", "1",
              "--scenarios", "moving-prey", "--workers", "1", "--out", str(out), "--json", timeout=300)
    assert res.returncode == 0, res.stderr
    table = {r["scenario"]: r for r in json.loads(res.stdout)["table"]}
    study = json.loads((out / "study.json").read_text())
    sets = study["sets"]
    assert len(sets) == 5 and (out / "guidelines.png").stat().st_size > 10_000
    row = table["moving-prey"]
    passed = [s for s in sets if s["design_ok"]]
    assert row["passed"] == len(passed) and row["sets"] == len(sets)
    assert row["false_safe"] == sum(s["collided"] for s in passed)
    assert row["conservative"] == sum(not s["collided"] for s in sets if not s["design_ok"])
    for s in sets[:3]:  # each verdict is zswarm design's, each outcome the simulator's
        params = Params.from_flat(s["params"])
        assert check(params, dt=0.05).ok == s["design_ok"]
        outcome = run_outcome(get_scenario("moving-prey").with_params(params), 0)
        assert (outcome.collisions > 0) == s["collided"]


def test_bench_interactions_runs_each_interaction_on_the_same_seeds(cli):
    res = cli("-m", "zswarm", "bench", "interactions", "--scenario", "moving-prey", "--agents", "10",
              "--interactions", "paper,scalable", "--seeds", "2", "--workers", "1", "--json", timeout=300)
    assert res.returncode == 0, res.stderr
    rows = {r["interaction"]: r for r in json.loads(res.stdout)["rows"]}
    assert set(rows) == {"paper", "scalable"} and all(r["runs"] == 2 for r in rows.values())
    alone = run_outcome(get_scenario("moving-prey", {"interaction": "paper"}), 1)
    assert rows["paper"]["collisions"] >= alone.collisions
    assert rows["paper"]["reached"] == 2  # it catches the prey at 26.7 s of its 60 s
    short = cli("-m", "zswarm", "bench", "interactions", "--scenario", "moving-prey", "--agents", "10",
                "--interactions", "paper", "--seeds", "1", "--duration-factor", "0.25", "--json", timeout=300)
    row = json.loads(short.stdout)["rows"][0]
    assert row["reached"] == 0 and row["final_distance"]["max"] > get_scenario("moving-prey").capture_radius


def test_bench_bodies_reports_each_body_as_it_ran_and_its_check(cli):
    res = cli("-m", "zswarm", "bench", "bodies", "--scenarios", "moving-prey", "--seeds", "1",
              "--set", "accel=0.5", "--json", timeout=300)
    assert res.returncode == 0, res.stderr
    rows = {r["body"]: r for r in json.loads(res.stdout)["rows"]}
    assert set(rows) == {"point", "unicycle", "double-integrator"}
    alone = run_outcome(get_scenario("moving-prey", {"body": "double-integrator", "accel": 0.5}), 0)
    row = rows["double-integrator"]
    assert row["median_capture_time"] == alone.capture_time and row["collisions"] == alone.collisions
    # the point body passes its check; a double integrator that needs 1.0 to stop does not (slack 0.658)
    assert rows["point"]["body_check"] and not rows["double-integrator"]["body_check"]
    assert rows["unicycle"]["median_capture_time"] != rows["point"]["median_capture_time"]
