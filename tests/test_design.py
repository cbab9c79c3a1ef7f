"""Design guidelines: exact values, and each bound checked by brute force on the potentials themselves."""

import json
import math

import numpy as np
import pytest

from zswarm.design.guidelines import check, prop1_curve
from zswarm.paper.formation import epsilon
from zswarm.paper.formation import closed_form_spacing, equilibria, pair_potential
from zswarm.paper.params import DEFAULT_PARAMS, PAPER_PARAMS, PotentialParams
from zswarm.paper.field import field
from zswarm.paper.potentials import formation_terms, goal_terms, obstacle_terms, saturate

PAPER = PAPER_PARAMS.potential


def integrate_1d(p: PotentialParams, starts, goal_x, obstacle_x, t_end=80.0, dt=2e-3, v_max=1.0):
    """Move robots along x under the full 2-D multiplicative field; return final and closest-to-obstacle x."""
    x = np.column_stack([np.asarray(starts, float), np.zeros(len(starts))])
    n = len(x)
    closest = np.full(n, np.inf)
    idx = np.arange(n)
    none, empty = np.zeros(0, dtype=np.intp), np.zeros((0, 2))
    for _ in range(int(t_end / dt)):
        psi_o = x - np.array([obstacle_x, 0.0])
        closest = np.minimum(closest, np.linalg.norm(psi_o, axis=1))
        _, f = field(x - np.array([goal_x, 0.0]), idx, psi_o, none, empty, p, "multiplicative")
        v = saturate(f, v_max)
        if np.max(np.abs(v)) < 1e-9:  # every robot at rest: the rest of t_end moves none by 1e-5
            break
        x = x + dt * v
    return x[:, 0], closest


# --- Section 3.2.3 worked example (l_g = 2, l_o = 0.2, d_m^go = d_m^ro = 0.2) ----------------------

def test_section_323_exact_values():
    r = check(PAPER_PARAMS)
    # Independent brute force: the maximum of eq 18 on a very fine grid.
    x = np.linspace(1e-7, 2.0, 4_000_001)
    assert r.prop1["lower_bound"] == pytest.approx(prop1_curve(x, 0.2, PAPER).max(), rel=1e-9)
    assert r.prop1["lower_bound"] == pytest.approx(0.019408, abs=2e-6)  # the paper read 0.022 off Fig 9
    assert r.prop1["d_0_go"] == pytest.approx(0.123436, abs=2e-6)  # paper: 0.122
    assert r.prop2["upper_bound"] == pytest.approx(0.382793, abs=2e-6)  # paper: 0.383
    assert r.prop2["d_0_ro_at_bound"] == pytest.approx(0.259497, abs=2e-6)  # paper: 0.281
    no_margin = check(PAPER_PARAMS.with_values({"d_m_go": 0.0}))
    assert no_margin.prop1["lower_bound"] == pytest.approx(0.138060, abs=2e-6)  # paper: 0.151


def test_alpha_changes_sign_at_d_0_go():
    r = check(PAPER_PARAMS)
    d0 = r.prop1["d_0_go"]
    # At d_0^go the net collinear force vanishes for c_g = 0 (obstacle push = obstacle's goal-term pull)
    p = PAPER.__class__(**{**PAPER.__dict__, "c_g": 1e-12})
    for s, sign in ((d0 * 0.99, -1), (d0 * 1.01, 1)):
        x = np.array([[-s, 0.0]])
        _, f = field(x, np.zeros(1, dtype=np.intp), x - np.array([0.2, 0.0]), np.zeros(0, dtype=np.intp),
                     np.zeros((0, 2)), p, "multiplicative")
        assert np.sign(f[0, 0]) == -sign  # pushed away (left) inside d_0^go, towards the goal beyond


# --- Prop 1 and Prop 2 flip where the bounds say ---------------------------------------------------

STARTS = np.linspace(-1.5, -0.3, 7)


@pytest.mark.parametrize("d_go", [0.2, 0.1])
def test_prop1_bound_flips_goal_reachability(d_go):
    """R-G-O collinear (Fig 7): above the lower bound every start reaches the goal; below, some stall."""
    lb = check(PAPER_PARAMS.with_values({"d_m_go": d_go})).prop1["lower_bound"]
    c_g = PAPER.c_g
    above = PAPER.__class__(**{**PAPER.__dict__, "c_o": c_g / (lb * 1.05)})
    below = PAPER.__class__(**{**PAPER.__dict__, "c_o": c_g / (lb * 0.95)})
    final_above, _ = integrate_1d(above, STARTS, 0.0, d_go)
    final_below, _ = integrate_1d(below, STARTS, 0.0, d_go)
    assert np.all(np.abs(final_above) < 0.02)
    assert np.any(np.abs(final_below) > 0.05)


def test_prop2_exact_bound_flips_obstacle_clearance_and_eq22_is_sufficient():
    """R-O-G collinear (Fig 8): the robot stops at d_0^ro >= d_m^ro iff c_g/c_o <= exact bound."""
    r = check(PAPER_PARAMS)
    d_ro, exact, eq22 = 0.2, r.prop2["exact_upper_bound"], r.prop2["upper_bound"]
    assert eq22 <= exact
    kw = PAPER.__dict__
    runs = {name: PAPER.__class__(**{**kw, "c_o": PAPER.c_g / ratio})
            for name, ratio in (("eq22", eq22 * 0.99), ("in", exact * 0.98), ("out", exact * 1.02))}
    start = [-1.5]
    for name, p in runs.items():
        _, closest = integrate_1d(p, start, 0.2, 0.0, t_end=30.0)
        if name == "out":
            assert closest[0] < d_ro
        else:
            assert closest[0] >= d_ro
    # and the robot rests at d_0^ro for the actual paper ratio
    final, _ = integrate_1d(PAPER, start, 0.2, 0.0, t_end=30.0)
    assert -final[0] == pytest.approx(r.prop2["d_0_ro"], abs=1e-3)


# --- Props 3-5 against their force balances --------------------------------------------------------

def test_epsilon_eq_34_from_numeric_maxima():
    p, n = PAPER, 10
    r = np.linspace(0, 10, 1_000_001)
    rep = np.max(2 * p.c_r / p.l_r**2 * r * np.exp(-r**2 / p.l_r**2))
    att = np.max(2 * p.c_a / p.l_a**2 * r * np.exp(-r**2 / p.l_a**2))
    assert epsilon(p, n) == pytest.approx((n - 1) * (rep + att) / (2 * p.c_a_prime * n), rel=1e-6)
    assert epsilon(p, 1) == 0.0 and math.isinf(epsilon(p.__class__(**{**p.__dict__, "c_a_prime": 0.0}), 5))


def test_prop3_swarm_settles_inside_epsilon():
    """All-to-all swarm under eq 28 alone: every agent ends within epsilon of the centre."""
    p, n = DEFAULT_PARAMS.potential, 10
    rng = np.random.default_rng(3)
    x = rng.uniform(-4, 4, (n, 2))
    i, k = np.nonzero(~np.eye(n, dtype=bool))
    for _ in range(4000):
        _, f = formation_terms(x[i] - x[k], p)
        x = x + 0.01 * np.stack([np.bincount(i, f[:, 0], n), np.bincount(i, f[:, 1], n)], axis=1)
    spread = np.linalg.norm(x - x.mean(axis=0), axis=1).max()
    assert spread <= epsilon(p, n)


def test_prop3_fails_when_sensing_radius_is_below_two_epsilon():
    eps = epsilon(DEFAULT_PARAMS.potential, 10)
    assert check(DEFAULT_PARAMS.with_values({"sensing_radius": 2 * eps * 1.01})).prop3["holds"]
    assert not check(DEFAULT_PARAMS.with_values({"sensing_radius": 2 * eps * 0.99})).prop3["holds"]


def test_prop4_flips_with_the_force_balance_at_the_worst_distances():
    """Eq 37 is eq 39 at |psi_o| = l_o/sqrt2 and |psi_f| = l_a/sqrt2: obstacle push vs c_p agents' pull."""
    r = check(PAPER_PARAMS).prop4
    assert r["c_p"] == 10 and r["lhs"] == pytest.approx(15.0)
    for factor, expect in ((1.02, True), (0.98, False)):
        c_o = r["rhs"] * PAPER.l_o * factor
        p = PAPER.__class__(**{**PAPER.__dict__, "c_o": c_o})
        assert check(PAPER_PARAMS.with_values({"c_o": c_o})).prop4["holds"] is expect
        push = obstacle_terms(np.array([[p.l_o / math.sqrt(2), 0.0]]), p)[1][0, 0]
        no_repulsion = PAPER.__class__(**{**p.__dict__, "c_r": 0.0})
        pull = -formation_terms(np.array([[p.l_a / math.sqrt(2), 0.0]]), no_repulsion)[1][0, 0]
        assert bool(push > r["c_p"] * pull) is expect


def test_prop5_flips_with_pair_repulsion_vs_goal_pull():
    base = DEFAULT_PARAMS
    r = check(base).prop5
    d_mf, d_r = r["d_m_f"], base.swarm.robot_radius
    for factor, expect in ((1.02, True), (0.98, False)):
        p = base.potential.__class__(**{**base.potential.__dict__, "c_r": r["rhs"] * factor,
                                        "c_a": 0.0, "c_a_prime": 0.0})
        repulsion = formation_terms(np.array([[d_mf, 0.0]]), p)[1][0, 0]
        goal_pull = -goal_terms(np.array([[d_r, 0.0]]), p)[1][0, 0]
        assert bool(repulsion > goal_pull) is expect


def test_contact_criterion_flips_where_a_touching_pair_stops_separating():
    """Two agents 1e-4 apart at the goal, N - 2 others far away (only c'_a reaches them)."""
    base = DEFAULT_PARAMS
    p, n = base.potential, base.swarm.n_agents
    c_r_star = p.l_r**2 / 2 * (p.c_a_prime * n + p.c_g / p.l_g**2 + 2 * p.c_a / p.l_a**2)
    others = 20.0 * np.column_stack([np.cos(np.arange(n - 2)), np.sin(np.arange(n - 2))])
    for factor, expect in ((1.03, True), (0.97, False)):
        q = p.__class__(**{**p.__dict__, "c_r": c_r_star * factor})
        assert check(base.with_values({"c_r": q.c_r}), swarm=False).contact["holds"] is expect
        x = np.vstack([[[5e-5, 0.0], [-5e-5, 0.0]], others])
        i, k = np.nonzero(~np.eye(n, dtype=bool))
        _, f = formation_terms(x[i] - x[k], q)
        force = np.stack([np.bincount(i, f[:, 0], n), np.bincount(i, f[:, 1], n)], axis=1)
        force += goal_terms(x, q)[1]
        separating = (force[0, 0] - force[1, 0]) > 0
        assert bool(separating) is expect


def test_swarm_check_catches_what_props_1_to_5_miss():
    """A set that passes Props 1-5 and the pair spacing can still crush agents together in a swarm."""
    nearest_two = PAPER_PARAMS.with_values({"l_a": 1.228, "l_r": 0.5493})
    r = check(nearest_two)
    assert all(r.to_json()[f"prop{i}"]["holds"] for i in range(1, 6)) and r.formation["stable"]
    assert not r.swarm["holds"] and r.swarm["min_pair_distance"] < 2 * nearest_two.swarm.robot_radius
    assert check(DEFAULT_PARAMS).swarm["holds"]


# --- formation spacing --------------------------------------------------------------------------------

def test_paper_pair_potential_has_no_stable_spacing():
    r = np.linspace(0, 10, 200_001)
    u = pair_potential(r, PAPER)
    assert np.argmin(u) == 0 and np.all(np.diff(u) > 0)  # monotone: collapse
    eq = equilibria(PAPER)
    assert eq.attracts_at_contact and not eq.is_stable
    report = check(PAPER_PARAMS)
    assert report.formation["stable"] is False and not report.ok and "formation" in report.failures()
    assert report.formation["closed_form_spacing"] == pytest.approx(math.sqrt(math.log(6) / 3))


def test_default_spacing_is_the_brute_force_minimum():
    p = DEFAULT_PARAMS.potential
    r = np.linspace(1e-6, 10, 2_000_001)
    spacing = check(DEFAULT_PARAMS).formation["equilibrium_spacing"]
    assert spacing == pytest.approx(r[np.argmin(pair_potential(r, p))], abs=1e-5)
    assert check(DEFAULT_PARAMS).ok


def test_closed_form_is_exact_without_quadratic_term():
    p = PotentialParams(l_a=1.0, l_r=0.5, c_a=0.5, c_r=1.0, c_a_prime=0.0)
    assert closed_form_spacing(p) == pytest.approx(equilibria(p).spacing, rel=1e-9)


# --- CLI -------------------------------------------------------------------------------------------

def test_cli_json_keys_and_exit_codes(cli):
    ok = cli("-m", "zswarm", "design", "--json")
    assert ok.returncode == 0, ok.stderr
    out = json.loads(ok.stdout)
    assert out["ok"] is True
    assert {"lower_bound", "d_0_go", "holds", "detail"} <= out["prop1"].keys()
    assert {"upper_bound", "d_0_ro"} <= out["prop2"].keys() and "epsilon" in out["prop3"]
    for k in ("prop4", "prop5"):
        assert {"lhs", "rhs", "holds"} <= out[k].keys()
    assert {"equilibrium_spacing", "closed_form_spacing", "stable"} <= out["formation"].keys()
    assert set(out["params"]) >= {"l_o", "c_a_prime", "n_agents", "d_m_ro"}
    paper = cli("-m", "zswarm", "design", "--paper", "--json")
    assert paper.returncode == 1 and json.loads(paper.stdout)["formation"]["equilibrium_spacing"] is None


def test_cli_save_writes_a_valid_recording(cli, tmp_path):
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    out = tmp_path / "design.rrd"
    res = cli("-m", "zswarm", "design", "--save", str(out))
    assert res.returncode == 0 and out.stat().st_size > 1000
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    verify = subprocess.run([rerun, "rrd", "verify", str(out)], capture_output=True, text=True, timeout=60)
    assert verify.returncode == 0, verify.stderr
    bad = cli("-m", "zswarm", "design", "--save", str(tmp_path / "missing" / "x.rrd"))
    assert bad.returncode == 2 and "cannot write" in bad.stderr


def test_cli_figure_marks_the_exact_bounds_on_labelled_axes(cli, tmp_path):
    import json

    import numpy as np
    from PIL import Image

    report = json.loads(cli("-m", "zswarm", "design", "--set", "c_o=2.5", "--json").stdout)
    svg, png = tmp_path / "design.svg", tmp_path / "design.png"
    for path in (svg, png):
        res = cli("-m", "zswarm", "design", "--set", "c_o=2.5", "--figure", str(path))
        assert res.returncode == 1 and path.exists(), res.stderr  # Prop 2 fails at c_o = 2.5: exit 1, figure made
    text = svg.read_text()
    assert f"bound {report['prop1']['lower_bound']:.4g} at |psi_g| = {report['prop1']['argmax']:.4g}" in text
    assert f"bound {report['prop2']['upper_bound']:.4g} (eq 22)" in text
    for label in ("|psi_g|: distance to the goal", "|psi_o|: distance to the obstacle",
                  "r = |psi_f|: distance between two agents", "c_g / c_o", "force (positive: repulsive)"):
        assert label in text, label
    pixels = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert pixels.shape[0] > 500 and pixels.std() > 20  # drawn, not blank


def test_cli_judges_a_scenarios_own_set_and_finds_a_nearest_set_that_passes(cli):
    own = cli("-m", "zswarm", "design", "--scenario", "moving-prey", "--set", "n_agents=30", "--json")
    assert own.returncode == 0, own.stderr
    out = json.loads(own.stdout)
    assert out["params"]["n_agents"] == 30 and out["params"]["interaction"] == "mean+gate"
    assert out["step"]["holds"] and out["ok"] and "prop3" in out["paper_failures"]
    res = cli("-m", "zswarm", "design", "--set", "n_agents=12", "--nearest", "--json")
    assert res.returncode == 1, res.stderr  # the set itself fails; the search reports what passes
    out = json.loads(res.stdout)
    assert not out["ok"] and out["nearest"]["ok"] is True
    assert out["nearest"]["changed"] == {"interaction": "mean+gate"}  # the paper's law cannot hold 12; the scalable one does
    assert "nearest:" in res.stderr  # progress, on stderr
    again = cli("-m", "zswarm", "design", *sum((["--set", f"{k}={v}"] for k, v in out["nearest"]["params"].items()),
                                                []), "--json")
    assert again.returncode == 0 and json.loads(again.stdout)["ok"]


def test_every_parameter_set_the_tools_print_is_accepted_back(cli, tmp_path):
    """What `design --json` prints as a set (params, and nearest.params) is read back unchanged as a
    TOML file for --params, every field included (names such as body and interaction too)."""
    from zswarm.args import read_params_file
    from zswarm.paper.params import FIELDS, Params

    printed = json.loads(cli("-m", "zswarm", "design", "--set", "body=unicycle", "--set", "interaction=mean+gate",
                             "--set", "k_nearest=7", "--json").stdout)["params"]
    assert set(printed) == set(FIELDS)  # the whole set is printed
    path = tmp_path / "set.toml"
    path.write_text("[params]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in printed.items()))
    assert Params().with_overrides(read_params_file(str(path))).flat() == printed
    again = cli("-m", "zswarm", "design", "--params", str(path), "--json")
    assert again.returncode in (0, 1), again.stderr
    assert json.loads(again.stdout)["params"] == printed


def test_the_table_states_one_verdict_and_the_papers_column_sums_up_as_printed(cli):
    """`design --paper`: the last two lines say what the table's columns say, and no row of ours (contact)
    carries a paper verdict the summary would then contradict."""
    for args in (["--paper"], ["--scenario", "large-swarm", "--set", "n_agents=300"]):
        out = cli("-m", "zswarm", "design", *args).stdout.splitlines()
        rows = [line.split() for line in out if line[:10].strip() in
                ("Prop 1", "Prop 2", "Prop 3", "Prop 4", "Prop 5", "Formation", "Contact", "Swarm", "Body")]
        ours = {r[0] + (r[1] if r[0] == "Prop" else "") for r in rows if "FAILS" in r[1:3]}
        paper = {r[0] + r[1] for r in rows if r[0] == "Prop" and r[3] == "FAILS"}
        assert not any(r[0] in ("Formation", "Contact", "Swarm", "Body") and r[2] in ("holds", "FAILS") for r in rows)
        verdict, summary = out[-2], out[-1]
        named = {w.strip(",").replace("prop", "Prop") for w in verdict.split()[2:]} if "fails" in verdict else set()
        assert {n.lower() for n in named} == {n.lower() for n in ours}, (verdict, ours)
        assert ("all hold" in summary) == (not paper), (summary, paper)
        assert all(p.lower() in summary.lower() for p in paper)


def test_nearest_says_what_blocks_when_nothing_passes():
    from zswarm.design.nearest import REMEDIES, NoPassingSet, nearest_passing

    hopeless = DEFAULT_PARAMS.with_values({"robot_radius": 5.0})  # agents wider than their spacing
    found = nearest_passing(hopeless, names=["c_o"], squeezes=1)
    assert isinstance(found, NoPassingSet) and found.blocking and set(found.blocking) <= set(REMEDIES)
    text = found.explain()
    assert "\n" not in text and all(f"{b}: {REMEDIES[b]}" in text for b in found.blocking)
