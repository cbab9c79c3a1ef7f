"""zswarm from Python: check a design, simulate a scenario, read a recording back.

    python examples/notebook.py [WORKDIR]

Each step is what a notebook cell would do; it prints what it found. The recording goes to
WORKDIR/notebook.rrd (default: a new temporary folder), and the script says where.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import zswarm

# 1. Check a parameter set against the paper's guidelines before running anything.
report = zswarm.check(zswarm.DEFAULT_PARAMS)
print("defaults pass:", report.ok)
paper = zswarm.check(zswarm.PAPER_PARAMS)
print("paper's set fails:", paper.failures())

# 2. Load a scenario (a registered name or a .toml file), with overrides, and simulate it.
scenario = zswarm.load_scenario("moving-prey", n_agents=10, c_o=3.0)
workdir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp())
record = workdir / "notebook.rrd"
result = zswarm.simulate(scenario, seed=1, duration=40.0, keep_trajectory=True, record=record)
print("recording written to", record)
print("captured at", result.summary["capture_time"], "s; collisions:", result.summary["collisions"])
print("trajectory", result.trajectory.shape, "prey", result.prey_trajectory.shape)
closest = np.asarray(result.metrics.series["min_pair_distance"]).min()
print(f"closest pair over the run: {closest:.3f}")

# 3. Read the recording back: its configuration, summary and every step as arrays.
run = zswarm.read_recording(record)
last = run.frames[-1]
print("recorded", len(run.frames), "steps; last at t =", round(last.t, 2), "with", len(last.ids), "agents")
print("same positions as simulated:", bool(np.array_equal(last.positions, result.trajectory[-1])))
