"""The real Rerun viewer, rendered headless, opens our recordings in their default blueprints: not
blank, and the map, plots and figure where the blueprint puts them. Needs xvfb-run and a software
Vulkan driver (``.ci/run`` installs them when it runs as root); skipped, with the reason, without."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from conftest import run_cli
from viewer_shots import NO_XVFB, colored, render

pytestmark = NO_XVFB


def _simulated_run(tmp_path: Path, scenario: str) -> tuple[np.ndarray, np.ndarray]:
    """3 s of ``scenario`` recorded and rendered; the map (left 3/5) and the plots (right 2/5), without
    the top and bottom bars."""
    rec = tmp_path / f"{scenario}.rrd"
    assert run_cli("-m", "zswarm", "sim", "--scenario", scenario, "--duration", "3", "--record", str(rec),
                   cwd=tmp_path).returncode == 0
    image = render(rec, tmp_path / f"{scenario}.png")
    h, w, _ = image.shape
    assert image.std() > 10, "blank screenshot"
    band = image[int(0.08 * h):int(0.92 * h)]
    return band[:, :int(0.55 * w)], band[:, int(0.62 * w):]


def test_a_run_opens_with_the_map_left_and_the_plots_right(tmp_path):
    map_, plots = _simulated_run(tmp_path, "moving-prey")
    assert colored(map_) > 500, "no agents in the map (left 3/5 of the window)"
    assert colored(plots) > 500, "no plotted series (right 2/5 of the window)"


def test_the_design_view_opens_with_the_figure_left_and_the_verdicts_right(tmp_path):
    rec = tmp_path / "design.rrd"
    assert run_cli("-m", "zswarm", "design", "--save", str(rec), cwd=tmp_path).returncode == 0
    gray = render(rec, tmp_path / "design.png").mean(axis=-1)
    h, w = gray.shape
    rows = slice(int(0.1 * h), int(0.9 * h))
    assert gray[rows, int(0.05 * w):int(0.7 * w)].mean() > 150, "the (white) design figure is not on the left"
    assert gray[rows, int(0.8 * w):].mean() < 100, "the verdict and report panels are not on the right"


def test_a_3d_run_opens_in_a_3d_view_with_the_plots_right(tmp_path):
    """moving-prey-3d: the map is a 3-D view (its ground grid, the spheres, the agents), the plots beside it."""
    map_, plots = _simulated_run(tmp_path, "moving-prey-3d")
    assert colored(map_) > 500, "no agents in the 3-D map"
    grey = (map_.max(-1) - map_.min(-1) < 20) & (map_.mean(-1) > 120)  # the lit spheres
    assert grey.sum() > 5000, "no obstacles (grey spheres) in the 3-D map"
    assert colored(plots) > 500, "no plotted series (right 2/5 of the window)"
