"""The notebook API: ``import zswarm`` is cheap, and the documented example runs and is right."""

from __future__ import annotations

import subprocess
import sys

from conftest import ROOT


def test_importing_zswarm_loads_nothing_heavy():
    code = "import sys, zswarm; print(sorted(m for m in ('numpy', 'zenoh', 'rerun') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_the_notebook_example_runs_and_finds_what_it_says(tmp_path):
    out = subprocess.run([sys.executable, str(ROOT / "examples" / "notebook.py"), str(tmp_path)],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    lines = out.stdout
    assert "defaults pass: True" in lines and "formation" in lines
    assert "collisions: 0" in lines and "captured at None" not in lines
    assert "trajectory (801, 10, 2)" in lines
    assert "same positions as simulated: True" in lines
    assert (tmp_path / "notebook.rrd").exists() and f"recording written to {tmp_path / 'notebook.rrd'}" in lines


def test_the_api_names_resolve():
    import zswarm

    for name in zswarm.__all__:
        assert getattr(zswarm, name) is not None
    assert zswarm.load_scenario("bench-field", n_agents=12).n_agents == 12

