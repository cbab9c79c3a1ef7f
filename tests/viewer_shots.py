"""Screenshots of the real Rerun viewer, rendered headless (xvfb-run and a software Vulkan driver; a test
that needs one is skipped, with the reason, without them)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

RERUN = Path(sys.executable).with_name("rerun")
NO_XVFB = pytest.mark.skipif(shutil.which("xvfb-run") is None,
                             reason="xvfb-run is missing: apt-get install xvfb xauth mesa-vulkan-drivers")


def render(recording: Path, out: Path) -> np.ndarray:
    from PIL import Image

    from conftest import free_port

    # a port of its own: two renders at once (the suite runs in parallel) must not find each other's viewer.
    # 960x600 points (the viewer draws them at twice that, 1920x1200 pixels): the layouts are the same as
    # at 1280x800, and the software rasterizer costs a third less CPU (24 s against 36, the three renders)
    res = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 960x600x24", str(RERUN), str(recording),
                          "--screenshot-to", str(out), "--window-size", "960x600", "--port", str(free_port())],
                         capture_output=True, text=True, timeout=120)
    if not out.exists():
        pytest.skip(f"the viewer could not render headless here (exit {res.returncode}): {res.stderr[-300:]}")
    return np.asarray(Image.open(out).convert("RGB")).astype(int)


def colored(region: np.ndarray) -> int:
    """Pixels of a saturated colour (agents, series lines), not greys."""
    return int(((region.max(-1) - region.min(-1)) > 80).sum())
