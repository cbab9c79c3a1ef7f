"""One run specification: every valid spec survives the trip through a child's command line."""

from __future__ import annotations

import argparse

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from zswarm.args import Parser
from zswarm.launch.chaos import Event, Pause, schedule
from zswarm.errors import UsageError
from zswarm.swarm.faults import FaultModel
from zswarm.net.runspec import CLOCKS, RunSpec, add_run_args, spec_from_args


def parse(argv: list[str]) -> argparse.Namespace:
    parser = Parser(prog="test")
    add_run_args(parser)
    return parser.parse_args(argv)


positive = st.floats(1e-3, 1e3, allow_nan=False, allow_infinity=False)
faults = st.builds(FaultModel, latency=st.floats(0, 2, allow_nan=False), jitter=st.floats(0, 1, allow_nan=False),
                   dropout=st.floats(0, 0.99), burst=st.one_of(st.just(0.0), st.floats(1, 20)),
                   distance_loss=st.floats(0, 1))
specs = st.builds(
    RunSpec,
    run=st.from_regex(r"[A-Za-z0-9_.-]{1,20}", fullmatch=True).filter(lambda r: not r.startswith("-")),
    scenario_name=st.sampled_from(["moving-prey", "static-goal", "bench-field", "goal-near-obstacle"]),
    overrides=st.dictionaries(st.sampled_from(["c_o", "c_g", "l_a", "v_max", "sensing_radius"]),
                              st.floats(0.05, 5, allow_nan=False), max_size=3).map(lambda d: tuple(d.items())),
    seed=st.integers(0, 2**63 - 1), potential=st.sampled_from([None, "additive", "multiplicative"]),
    clock=st.sampled_from(CLOCKS), time_scale=st.floats(0.01, 999, allow_nan=False),
    duration=st.one_of(st.none(), positive), faults=faults)


@settings(max_examples=300, deadline=None)
@given(spec=specs)
def test_a_spec_survives_its_command_line(spec):
    try:
        spec.scenario  # noqa: B018  (a valid spec: its scenario can be built)
    except UsageError:
        assume(False)
    assert spec_from_args(parse(spec.to_argv())) == spec


def test_the_defaults_and_the_scenario_come_back_too():
    spec = RunSpec(scenario_name="bench-field", overrides=(("n_agents", 7),), seed=3)
    back = spec_from_args(parse(spec.to_argv()))
    assert back == spec and back.scenario.n_agents == 7 and back.faults.seed == 3
    assert spec_from_args(parse([])) == RunSpec()


def test_an_interaction_and_its_settings_come_back():
    spec = RunSpec(overrides=(("interaction", "mean+gate"), ("gate", 0.7), ("k_nearest", 4), ("n_agents", 20)))
    back = spec_from_args(parse(spec.to_argv()))
    assert back == spec
    assert back.scenario.params.interaction.spec.gate and back.scenario.params.interaction.gate == 0.7


@pytest.mark.parametrize("kwargs,needle", [
    ({"seed": -1}, "--seed"), ({"seed": 2**63}, "--seed"), ({"run": "a b"}, "run id"),
    ({"time_scale": 0.0}, "--time-scale"), ({"duration": -1.0}, "--duration"), ({"clock": "wall"}, "--clock"),
])
def test_invalid_specs_are_usage_errors(kwargs, needle):
    with pytest.raises(UsageError, match=needle):
        RunSpec(**kwargs)


def test_chaos_is_a_schedule_of_events_in_time_order():
    events = schedule(kill=(2, 10.0), restart_after=5.0, world_outage=(3.0, 4.0), world_crash=(8.0, 1.0),
                      pauses=[Pause("agent-4", 9.5, 0.5)])
    assert events == [Event(3.0, "pause", what="world"), Event(7.0, "unpause", what="world"), Event(8.0, "kill_world"),
                      Event(9.0, "resume_world"), Event(9.5, "pause", what="agent-4"), Event(10.0, "kill_agents", 2),
                      Event(10.0, "unpause", what="agent-4"), Event(15.0, "restart_agents")]
    assert schedule() == [] and schedule(kill=(1, 2.0)) == [Event(2.0, "kill_agents", 1)]
    assert schedule(world_crash=(4.0, None)) == [Event(4.0, "kill_world")]
