"""Loading a user's law: a file, a module, an installed entry point, a notebook function; every
mistake (a file that does not import, a missing attribute, a function of the wrong shape, an answer of
the wrong length, NaN or infinity, an unknown name, a parameter the law does not have) refused in one
line with exit 2 before anything runs."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import zswarm
from zswarm.cli.main import main
from zswarm.laws.registry import bind, known, resolve

from conftest import ROOT

LAWS = {
    "ok.py": "import numpy as np\n\ndef rush(obs):\n    to = obs.target - obs.position\n"
             "    return obs.v_max * to / max(float(np.linalg.norm(to)), 1e-9)\n",
    "broken.py": "import numpy as np\n\ndef rush(obs)\n    return obs.target\n",
    "raises.py": "raise RuntimeError('no robots today')\n",
    "law.txt": "def rush(obs):\n    return obs.target\n",
    "shapes.py": "import math\n\ndef two(obs, extra):\n    return (0.0, 0.0)\n\ndef short(obs):\n    return (1.0,)\n\n"
                 "def nan(obs):\n    return (math.nan, 0.0)\n\ndef inf(obs):\n    return (0.0, math.inf)\n\n"
                 "def text(obs):\n    return 'fast'\n\ndef boom(obs):\n    return 1 / 0\n\nNOT_A_LAW = 3\n",
}


@pytest.fixture()
def law_dir(tmp_path):
    for name, text in LAWS.items():
        (tmp_path / name).write_text(text)
    return tmp_path


@pytest.mark.parametrize("law,says", [
    ("broken.py:rush", "does not import: SyntaxError"),
    ("raises.py:rush", "does not import: RuntimeError: no robots today"),
    ("ok.py:missing", "'missing' is not defined there (it defines: rush)"),
    ("nowhere.py:rush", "no file"),
    ("shapes.py:two", "a law function takes one argument"),
    ("shapes.py:NOT_A_LAW", "it names a value of type int, not a function"),
    ("law.txt:rush", "a law file is Python source whose name ends in .py (got law.txt)"),
    ("ok.py", "name the law in the file too: --law ok.py:NAME"),
    ("shapes.py:short", "shape (1,) in a 2-D run"),
    ("shapes.py:nan", "not finite"),
    ("shapes.py:inf", "not finite"),
    ("shapes.py:text", "not a sequence of 2 numbers"),
    ("shapes.py:boom", "raised ZeroDivisionError: division by zero (shapes.py:"),
    ("no_such_law", "unknown law 'no_such_law'"),
    ("no_such_module_zz:law", "does not import: ModuleNotFoundError"),
])
def test_a_bad_law_is_refused_in_one_line_with_exit_2(law_dir, monkeypatch, capsys, law, says) -> None:
    monkeypatch.chdir(law_dir)
    resolve.cache_clear()
    assert main(["sim", "--scenario", "moving-prey", "--law", law, "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and says in err and "Traceback" not in err, err


def test_a_law_parameter_is_checked_in_one_line(capsys) -> None:
    assert main(["sim", "--law", "boids", "--set", "law.w_nope=1", "--duration", "1"]) == 2
    assert "law boids has no parameter 'w_nope'" in capsys.readouterr().err
    assert main(["sim", "--law", "boids", "--set", "law.f_max=-1", "--duration", "1"]) == 2
    assert "law.f_max must be a finite number > 0" in capsys.readouterr().err
    assert main(["sim", "--set", "law.f_max=1", "--duration", "1"]) == 2  # apf's are the scenario's
    assert "apf takes its parameters from the scenario" in capsys.readouterr().err


def test_a_law_parameter_set_from_a_file_and_the_command_line_changes_the_run(tmp_path, capsys) -> None:
    params = tmp_path / "boids.toml"
    params.write_text('[law]\nname = "boids"\nw_sep = 3.0\n')
    summaries = []
    for extra in ([], ["--params", str(params)], ["--params", str(params), "--set", "law.w_tgt=0.5"]):
        assert main(["sim", "--scenario", "moving-prey", "--law", "boids", "--duration", "3", "--json", *extra]) == 0
        summaries.append(json.loads(capsys.readouterr().out))
    assert [s["law"]["params"]["w_sep"] for s in summaries] == [1.5, 3.0, 3.0]
    assert summaries[2]["law"]["params"]["w_tgt"] == 0.5 and summaries[2]["law"]["settings"] == {"w_sep": 3.0,
                                                                                                   "w_tgt": 0.5}
    assert len({s["final_centroid_goal_distance"] for s in summaries}) == 3  # each setting moved the swarm


def test_a_law_from_an_installed_package_is_found_by_its_entry_point(tmp_path) -> None:
    """A distribution on the path that registers ``zswarm.laws`` (as ``pip install`` would leave it)."""
    (tmp_path / "herdlaws.py").write_text(LAWS["ok.py"].replace("rush", "herd"))
    info = tmp_path / "herdlaws-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: herdlaws\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[zswarm.laws]\nherd = herdlaws:herd\n")
    code = ("import json, sys; from zswarm.cli.main import main; sys.exit(main(['laws', '--json']))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    laws = {law["name"]: law for law in json.loads(out.stdout)["laws"]}
    assert list(laws)[:4] == ["apf", "olfati-saber", "vasarhelyi", "boids"]
    assert laws["herd"]["source"] == "entry point herdlaws:herd" and not laws["herd"]["batched"]
    code = ("import sys; from zswarm.cli.main import main; sys.exit(main(['sim', '--law', 'herd', '--duration', '2',"
            " '--json']))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60,
                         env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0 and json.loads(out.stdout)["law"]["source"] == "entry point herdlaws:herd"


def test_zswarm_laws_lists_the_four_built_ins_with_their_needs(capsys) -> None:
    assert main(["laws", "--json"]) == 0
    laws = {law["name"]: law for law in json.loads(capsys.readouterr().out)["laws"]}
    assert {"apf", "olfati-saber", "vasarhelyi", "boids"} <= set(laws) and known()[:4] == list(laws)[:4]
    assert "neighbour velocities" in laws["vasarhelyi"]["needs"] and laws["apf"]["guidelines"]
    assert all(laws[n]["batched"] for n in ("apf", "olfati-saber", "vasarhelyi", "boids"))
    scaled = laws["vasarhelyi"]["fitted"]
    assert scaled["scaled"]["r0_rep"] == pytest.approx(0.758, abs=1e-3)  # the spacing of moving-prey


def test_a_notebook_function_runs_in_the_simulator() -> None:
    def rush(obs):
        to = obs.target - obs.position
        return obs.v_max * to / max(float(np.linalg.norm(to)), 1e-9)

    globals()["rush_for_the_notebook"] = rush
    rush.__qualname__ = "rush_for_the_notebook"
    scenario = zswarm.load_scenario("moving-prey", law=rush)
    assert bind(scenario).source == f"module {__name__}"
    alone = zswarm.simulate(scenario, 0, duration=4.0).summary
    filtered = zswarm.simulate(scenario, 0, duration=4.0, safety="barrier").summary
    assert alone["collisions"] > 0 and filtered["collisions"] == 0  # it rushes; the filter keeps it apart


def test_a_law_that_fails_during_a_simulation_is_said_in_one_line(tmp_path, monkeypatch, capsys) -> None:
    (tmp_path / "late.py").write_text("calls = 0\n\ndef late(obs):\n    global calls\n    calls += 1\n"
                                      "    if calls > 50:\n        raise ValueError('tired')\n    return 0 * obs.position\n")
    monkeypatch.chdir(tmp_path)
    resolve.cache_clear()
    assert main(["sim", "--law", "late.py:late", "--duration", "5"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[0].startswith("note: law late.py:late: there are no analytical guidelines")
    assert len(lines) == 2 and "law late.py:late raised ValueError: tired (late.py:7) at t = 0.20 s" in lines[1], lines


def test_design_and_tune_say_what_they_cover_for_another_law(tmp_path, capsys) -> None:
    assert main(["design", "--law", "vasarhelyi", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["ok"] is None and "no analytical guidelines" in out["note"] and "safety filter" in out["note"]
    assert main(["design"]) == 0 and "Prop" in capsys.readouterr().out  # apf: the guidelines as before
    assert main(["tune", "--law", "boids", "--tune", "c_o", "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "law boids declares ranges for w_sep, w_ali, w_coh, w_tgt" in err
    (tmp_path / "rush.py").write_text(LAWS["ok.py"])
    assert main(["tune", "--law", f"{tmp_path / 'rush.py'}:rush", "--out", str(tmp_path / "t")]) == 2
    assert "declares no ranges for its parameters, so there is nothing to tune" in capsys.readouterr().err
    assert main(["sim", "--law", "boids", "--duration", "1", "--require-design"]) == 2
    assert "no analytical guidelines" in capsys.readouterr().err
    # the note says what keeps the agents apart in this run: the filter, or nothing when it is off
    for safety, says in (("barrier", "the safety filter is the guarantee"),
                         ("off", "with --safety off nothing keeps them apart")):
        assert main(["sim", "--law", "boids", "--duration", "0.1", "--safety", safety]) == 0
        note = next(line for line in capsys.readouterr().err.splitlines() if "no analytical guidelines" in line)
        assert says in note and ("guarantee" in note) == (safety == "barrier"), note


def test_tune_searches_a_laws_own_ranges_behind_the_filter(tmp_path, capsys) -> None:
    """A law that declares ranges is tuned within them, simulated behind the safety filter (no
    guidelines to reject a set); best.toml holds a [law] table that every command reads back."""
    out = tmp_path / "t"
    assert main(["tune", "--law", "boids", "--scenario", "moving-prey", "--tune", "w_sep,w_tgt", "--budget", "6",
                 "--seeds", "2", "--validate", "2", "--holdout", "2", "--finalists", "2", "--duration", "8",
                 "--popsize", "3", "--out", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["law"] == "boids" and result["safety"] == "barrier" and result["rejected"] == 0
    best = result["best"]["values"]
    assert set(best) == {"w_sep", "w_tgt"} and 0.5 <= best["w_sep"] <= 4.0 and 0.2 <= best["w_tgt"] <= 4.0
    assert best != {"w_sep": 1.5, "w_tgt": 1.0}
    assert main(["sim", "--scenario", "moving-prey", "--params", str(out / "best.toml"), "--duration", "2",
                 "--json"]) == 0
    law = json.loads(capsys.readouterr().out)["law"]
    assert law["name"] == "boids" and law["settings"] == pytest.approx(best)
    assert "no analytical guidelines" in (out / "design.txt").read_text()
