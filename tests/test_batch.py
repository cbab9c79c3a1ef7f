"""The batched simulator: every run of a batch is the run simulate() makes alone."""

from __future__ import annotations

import numpy as np
import pytest

from zswarm.swarm.faults import FaultModel
from zswarm.swarm.scenarios import get_scenario
from zswarm.sim.batch import Member, simulate_batch
from zswarm.sim.simulator import simulate

STEPS = 700  # 35 s: long enough for captures, a collision and every prey motion


def _mixed_batch() -> list[Member]:
    prey = get_scenario("moving-prey")
    return [
        Member(prey, 0),
        Member(prey, 1),
        Member(get_scenario("static-goal"), 2),  # three obstacles beside moving-prey's two (padding)
        Member(get_scenario("moving-prey-evasive"), 3),
        Member(prey, 4, FaultModel(latency=0.1, jitter=0.05, dropout=0.3, seed=4)),
        Member(prey, 5, FaultModel(latency=0.05, dropout=0.3, burst=4, distance_loss=0.5, seed=9)),
        Member(get_scenario("moving-prey", {"c_o": 5.0, "l_a": 2.0}), 6, combination="additive"),
        Member(get_scenario("moving-prey-straight"), 7),
        Member(prey, 8,
               FaultModel(dropout=0.5, seed=8)),
        # the interactions of zswarm.paper.neighbour_law, a faulty one among them
        Member(get_scenario("moving-prey", {"interaction": "mean+gate"}), 9),
        Member(get_scenario("moving-prey", {"interaction": "cutoff+nearest", "k_nearest": 3}), 10,
               FaultModel(latency=0.1, dropout=0.3, seed=10)),
        Member(get_scenario("moving-prey", {"interaction": "mean+gate", "gate": 0.6}), 11),
    ]


def test_each_run_matches_its_run_alone_at_every_step() -> None:
    members = _mixed_batch()
    batch = simulate_batch(members, STEPS, keep_trajectory=True)
    captured = collided = 0
    for r, m in enumerate(members):
        alone = simulate(m.scenario, m.seed, combination=m.combination, duration=STEPS * m.scenario.dt,
                         keep_trajectory=True, faults=m.faults)
        np.testing.assert_allclose(batch.trajectory[:, r], alone.trajectory, rtol=0, atol=1e-9,
                                   err_msg=f"run {r} ({m.scenario.name}, seed {m.seed})")
        np.testing.assert_allclose(batch.prey_trajectory[:, r], alone.prey_trajectory, rtol=0, atol=1e-9)
        got, want = batch.outcomes[r], alone.summary
        assert got.capture_time == want["capture_time"]
        assert got.collisions == want["collisions"]
        assert got.obstacle_collisions == want["obstacle_collisions"]
        assert got.min_pair_distance == pytest.approx(want["min_pair_distance"], abs=1e-9)
        if want["min_obstacle_clearance"] is None:
            assert got.min_obstacle_clearance is None
        else:
            assert got.min_obstacle_clearance == pytest.approx(want["min_obstacle_clearance"], abs=1e-9)
        assert got.final_centroid_goal_distance == pytest.approx(want["final_centroid_goal_distance"], abs=1e-9)
        captured += got.capture_time is not None
        collided += got.collisions > 0
    assert captured >= 3 and collided >= 1  # the comparison covered captures and a collision


def test_faulty_runs_differ_from_fault_free_ones() -> None:
    prey = get_scenario("moving-prey")
    out = simulate_batch([Member(prey, 0), Member(prey, 0, FaultModel(latency=0.2, dropout=0.3))], 100,
                         keep_trajectory=True)
    assert np.abs(out.trajectory[-1, 0] - out.trajectory[-1, 1]).max() > 1e-3


def test_runs_of_different_sizes_cannot_share_a_batch() -> None:
    with pytest.raises(ValueError, match="same N"):
        simulate_batch([Member(get_scenario("moving-prey"), 0), Member(get_scenario("narrow-passage"), 0)], 5)


def test_every_law_runs_in_a_batch_as_alone_with_faults_and_a_law_without_a_batched_form(tmp_path) -> None:
    """Runs of the built-in laws other than apf (their batched forms, grouped by law), a user's
    function law (no batched form: the per-agent loop), faults among them: each the run simulate()
    makes alone, with the filter on."""
    law_file = tmp_path / "rush.py"
    law_file.write_text("import numpy as np\n\ndef rush(obs):\n    to = obs.target - obs.position\n"
                        "    d = float(np.linalg.norm(to))\n    return obs.v_max * to / d if d > 0 else 0 * to\n")
    faults = FaultModel(latency=0.1, jitter=0.05, dropout=0.3, seed=4)
    members = [Member(get_scenario("moving-prey", {"law": name}), seed, f, safety="barrier")
               for name, seed, f in (("olfati-saber", 0, None), ("vasarhelyi", 1, None), ("boids", 2, faults),
                                     ("olfati-saber", 3, faults), (f"{law_file}:rush", 4, None),
                                     ("vasarhelyi", 5, faults))]
    members.append(Member(get_scenario("moving-prey-evasive", {"law": "boids"}), 6))
    steps = 200
    batch = simulate_batch(members, steps, keep_trajectory=True)
    for r, m in enumerate(members):
        alone = simulate(m.scenario, m.seed, duration=steps * m.scenario.dt, keep_trajectory=True, faults=m.faults,
                         safety=m.safety)
        np.testing.assert_allclose(batch.trajectory[:, r], alone.trajectory, rtol=0, atol=1e-9,
                                   err_msg=f"run {r} ({m.scenario.params.law.law}, seed {m.seed})")
        assert batch.outcomes[r].collisions == alone.summary["collisions"]
        assert batch.outcomes[r].safety_interventions == alone.summary.get("safety_interventions", 0), r
    assert np.ptp(batch.trajectory[-1, :, :, 0]) > 0.1  # the laws moved the swarms differently


def test_the_tally_counts_onsets_per_run_and_a_single_run_is_a_batch_of_one() -> None:
    """The one tally: a pair in contact for three steps is one collision, of its own run only; the same
    pair index in another run is another pair. And run_outcome (the grid simulator as a batch of one)
    gives the outcome the batched simulator gives that run."""
    from zswarm.sim.outcome import run_outcome
    from zswarm.swarm.tally import OutcomeTally, Sensed

    tally = OutcomeTally(2, 3, 0.1, np.array([0.5, 0.5]), np.array([0.1, 0.1]))
    none = np.zeros(0, dtype=np.intp)
    x, prey = np.zeros((2, 3, 2)), np.ones((2, 2))
    for step, (runs, dist) in enumerate((([0, 1], [0.15, 0.5]), ([0, 1], [0.1, 0.15]), ([0, 1], [0.12, 0.1]),
                                         ([0, 1], [0.5, 0.1]), ([0, 1], [0.1, 0.1]))):
        runs = np.array(runs)
        tally.observe(step, x, prey, Sensed(runs, np.zeros(len(runs), dtype=np.intp), np.ones(len(runs), dtype=np.intp),
                                            np.array(dist), none, none, none, np.zeros(0)))
    assert tally.collisions.tolist() == [2, 1]  # run 0: steps 0 and 4; run 1: from step 1 on, never apart
    assert tally.min_pair.tolist() == [0.1, 0.1]

    scenario = get_scenario("moving-prey", {"c_a": 5.0})  # an attraction that crushes two pairs
    alone, batched = run_outcome(scenario, 0), simulate_batch([Member(scenario, 0)], scenario.steps).outcomes[0]
    assert alone.collisions == batched.collisions > 0 and alone.capture_time == batched.capture_time
    assert alone.final_components == batched.final_components
    assert alone.min_pair_distance == pytest.approx(batched.min_pair_distance, abs=1e-9)
    assert alone.final_median_nearest == pytest.approx(batched.final_median_nearest, abs=1e-9)
