"""Bodies (zswarm.control.body): what a command does, the same in the simulators and on the wire."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zswarm.errors import ParamError
from zswarm.control import body as bodies
from zswarm.paper.params import Params
from zswarm.swarm.scenarios import get_scenario
from zswarm.net import messages as msg
from zswarm.sim.batch import Member, simulate_batch
from zswarm.sim.simulator import Simulator, simulate


def run_states(scenario, steps: int):
    """Every step's body state and the velocity it moved with, from the reference simulator."""
    sim = Simulator(scenario, 0)
    states, moved = [], []
    for _ in range(steps):
        stepped = sim.command()
        v = stepped.state.velocity[0]
        states.append(sim.state)
        moved.append(v)
        sim.advance(stepped)
        np.testing.assert_array_equal(sim.state.velocity, v)  # what advance() moves with
    states.append(sim.state)
    return states, moved


def test_the_point_body_moves_exactly_as_commanded():
    rng = np.random.default_rng(1)
    x, v = rng.normal(size=(7, 2)), rng.normal(size=(7, 2))
    spec = bodies.BodySpec("point")
    moved = bodies.step(spec, bodies.start(spec, x, np.zeros(2)), v, 0.05)
    np.testing.assert_array_equal(moved.position, x + 0.05 * v)
    np.testing.assert_array_equal(moved.velocity, v)
    assert np.isnan(moved.heading).all()


def test_a_unicycle_never_moves_sideways_and_keeps_its_limits():
    scenario = get_scenario("moving-prey", {"body": "unicycle", "turn_rate": 2.0})
    states, moved = run_states(scenario, 300)
    p = scenario.params
    turned = 0.0
    for before, after, v in zip(states, states[1:], moved):
        facing = np.column_stack([np.cos(before.heading), np.sin(before.heading)])
        sideways = facing[:, 0] * v[:, 1] - facing[:, 1] * v[:, 0]
        assert np.max(np.abs(sideways)) < 1e-12  # its velocity is along its heading, always
        np.testing.assert_allclose(after.position - before.position, scenario.dt * v, rtol=0, atol=1e-15)
        assert np.max(np.linalg.norm(v, axis=1)) <= p.swarm.v_max * (1 + 1e-12)
        rate = np.abs(bodies.wrap(after.heading - before.heading)) / scenario.dt
        assert np.max(rate) <= p.body.turn_rate * (1 + 1e-9)
        turned = max(turned, float(np.max(rate)))
    assert turned > 0.9 * p.body.turn_rate  # it did have to turn as fast as it may


def test_a_unicycle_starts_facing_the_prey_and_tracks_the_point_ahead():
    spec = bodies.BodySpec("unicycle", v_max=1.0, turn_rate=100.0, lookahead=0.2)
    state = bodies.start(spec, np.array([[0.0, 0.0]]), np.array([0.0, 5.0]))
    assert state.heading[0] == pytest.approx(math.pi / 2)
    # commanded straight ahead: full speed, no turn; commanded sideways: no speed, a turn toward it
    ahead = bodies.step(spec, state, np.array([[0.0, 0.8]]), 0.1)
    assert ahead.velocity[0] == pytest.approx([0.0, 0.8]) and ahead.heading[0] == pytest.approx(math.pi / 2)
    left = bodies.step(spec, state, np.array([[-0.8, 0.0]]), 0.1)
    assert np.allclose(left.velocity, 0.0) and left.heading[0] == pytest.approx(math.pi / 2 + 0.1 * 0.8 / 0.2)


def test_a_double_integrator_never_exceeds_its_acceleration_and_cannot_stop_at_once():
    scenario = get_scenario("moving-prey", {"body": "double-integrator", "accel": 1.5})
    states, moved = run_states(scenario, 400)
    p = scenario.params
    accel = np.array([np.linalg.norm(b - a, axis=1) / scenario.dt for a, b in zip(moved, moved[1:])])
    assert accel.max() <= p.body.accel * (1 + 1e-9)
    assert accel.max() > 0.99 * p.body.accel  # the limit did bind
    assert max(np.linalg.norm(v, axis=1).max() for v in moved) <= p.swarm.v_max * (1 + 1e-12)
    # from full speed, a command to stop takes v / accel, not one step
    spec = bodies.BodySpec(scenario.params.body.body, scenario.params.swarm.v_max, scenario.params.body.turn_rate,
                           scenario.params.body.lookahead, scenario.params.body.accel)
    state = bodies.BodyState(np.zeros((1, 2)), np.array([[1.0, 0.0]]), np.array([np.nan]))
    steps = 0
    while np.linalg.norm(state.velocity) > 0:
        state = bodies.step(spec, state, np.zeros((1, 2)), scenario.dt)
        steps += 1
    assert steps == math.ceil(1.0 / (p.body.accel * scenario.dt) - 1e-9)


@pytest.mark.parametrize("body", ["unicycle", "double-integrator"])
def test_the_demo_catches_the_prey_with_no_collision_on_every_body(body):
    result = simulate(get_scenario("moving-prey", {"body": body}), 0)
    assert result.summary["capture_time"] is not None and result.summary["collisions"] == 0
    assert result.summary["obstacle_collisions"] == 0


@pytest.mark.parametrize("body", ["point", "unicycle", "double-integrator"])
def test_the_batched_simulator_moves_every_body_as_the_reference(body):
    """A batch mixing bodies: each run is the run the reference simulator makes alone."""
    kinds = ["point", "unicycle", "double-integrator"]
    members = [Member(get_scenario("moving-prey", {"body": k}), seed=3) for k in kinds]
    batch = simulate_batch(members, 200, keep_trajectory=True)
    r = kinds.index(body)
    ref = simulate(members[r].scenario, 3, duration=200 * members[r].scenario.dt, keep_trajectory=True)
    np.testing.assert_allclose(batch.trajectory[:, r], ref.trajectory, rtol=0, atol=1e-9)
    others = [k for k in range(3) if k != r]
    assert all(np.abs(batch.trajectory[-1, r] - batch.trajectory[-1, k]).max() > 1e-3 for k in others)


def test_body_is_a_checked_parameter():
    assert Params().body.body == "point"
    assert Params().with_overrides(["body=unicycle", "turn_rate=2"]).body.turn_rate == 2.0
    for bad in (["body=tank"], ["turn_rate=0"], ["accel=-1"], ["lookahead=nan"]):
        with pytest.raises(ParamError, match=bad[0].split("=")[0]):
            Params().with_overrides(bad)


def test_a_pose_carries_its_heading_and_a_bad_heading_is_refused():
    pose = msg.Pose(3, 1, 1.0, 4, 0.5, -0.5, 0.1, 0.0, -2.5)
    assert msg.decode(msg.encode(pose)) == pose
    plain = msg.Pose(3, 1, 1.0, 4, 0.5, -0.5, 0.1, 0.0)
    assert msg.decode(msg.encode(plain)).heading is None and len(msg.encode(plain)) < len(msg.encode(pose))
    import struct

    for bad, reason in ((float("nan"), "nonfinite"), (100.0, "range")):
        data = msg.encode(pose)[:-8] + struct.pack("<d", bad)  # the heading is the record's last field
        with pytest.raises(msg.DecodeError) as err:
            msg.decode(data)
        assert err.value.reason == reason
