import math

import pytest

from zswarm.paper.params import (
    DEFAULT_PARAMS,
    FIELDS,
    MAX_AGENTS,
    PAPER_PARAMS,
    ParamError,
    Params,
    PotentialParams,
    SwarmParams,
    parse_assignments,
)


def test_paper_values_are_the_printed_ones():
    p = PAPER_PARAMS.potential
    assert (p.l_o, p.l_g, p.l_a, p.l_r) == (0.2, 2.0, 0.5, 1.0)
    assert (p.c_o, p.c_g, p.c_a, p.c_a_prime) == (3.0, 1.0, 0.5, 0.1)
    assert math.isclose(p.c_r, 1 / 3)
    assert PAPER_PARAMS.swarm.n_agents == 10


def test_defaults_differ_from_paper_in_the_documented_values():
    paper, default = PAPER_PARAMS.flat(), DEFAULT_PARAMS.flat()
    changed = {k for k in FIELDS if FIELDS[k].group == "potential" and paper[k] != default[k]}
    assert changed == {"l_a", "l_r", "c_r"}  # README, "Defaults"


@pytest.mark.parametrize("name,value", [("l_o", 0.0), ("l_g", -1.0), ("c_g", 0.0), ("c_o", -0.1),
                                        ("c_r", math.nan), ("v_max", math.inf), ("n_agents", 0),
                                        ("robot_radius", 0.0), ("d_m_go", -0.2)])
def test_out_of_range_values_name_the_field_and_range(name, value):
    with pytest.raises(ParamError) as err:
        Params().with_values({name: value})
    msg = str(err.value)
    assert msg.startswith(name + " must be") and "\n" not in msg
    assert (">" in msg) and repr(value) in msg


def test_dataclasses_validate_on_construction():
    with pytest.raises(ParamError, match="l_a must be"):
        PotentialParams(l_a=-1.0)
    with pytest.raises(ParamError, match="n_agents must be an integer"):
        SwarmParams(n_agents=2.5)


def test_unknown_name_lists_known_ones():
    with pytest.raises(ParamError, match="unknown parameter 'c_x'.*c_a_prime"):
        Params().with_overrides(["c_x=1"])


def test_overrides_parse_fractions_ints_and_keep_the_rest():
    p = Params().with_overrides(["c_r=1/3", "n_agents=25", "l_o=0.25"])
    assert math.isclose(p.potential.c_r, 1 / 3) and p.swarm.n_agents == 25 and p.potential.l_o == 0.25
    assert p.potential.l_g == Params().potential.l_g
    assert isinstance(p.swarm.n_agents, int)


@pytest.mark.parametrize("bad", ["c_r", "=1", "c_r=abc", "c_r=1/0", "n_agents=2.5", "c_r=nan"])
def test_malformed_assignments_are_one_line_errors(bad):
    with pytest.raises(ParamError) as err:
        Params().with_overrides([bad])
    assert "\n" not in str(err.value)


def test_flat_round_trip():
    p = Params().with_overrides(["c_o=4", "sensing_radius=3"])
    assert Params.from_flat(p.flat()) == p


def test_an_integer_written_as_a_float_is_an_integer():
    assert parse_assignments(["n_agents=1e3", "n_agents=20.0"]) == {"n_agents": 20}
    assert parse_assignments(["n_agents=1e5"]) == {"n_agents": 100000}
    with pytest.raises(ParamError, match="n_agents must be an integer"):
        parse_assignments(["n_agents=2.5"])


def test_the_swarm_size_has_a_stated_bound():
    assert parse_assignments([f"n_agents={MAX_AGENTS}"]) == {"n_agents": MAX_AGENTS}
    with pytest.raises(ParamError, match=f"<= {MAX_AGENTS}"):
        parse_assignments([f"n_agents={MAX_AGENTS + 1}"])
