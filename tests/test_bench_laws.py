"""``zswarm bench laws``: the laws side by side on the same seeds, as rows with the keys the docs name,
each row from its own runs (a law that rushes at the target collides without the filter and not with
it), and its figure."""

from __future__ import annotations

import json

from zswarm.cli.main import main

KEYS = {"law", "latency", "dropout", "safety", "collisions", "closest_pair", "reached", "capture_median", "order",
        "groups", "stalls", "interventions"}


def test_bench_laws_rows_and_figure(tmp_path, capsys) -> None:
    law = tmp_path / "rush.py"
    law.write_text("import numpy as np\n\ndef rush(obs):\n    to = obs.target - obs.position\n"
                   "    return obs.v_max * to / max(float(np.linalg.norm(to)), 1e-9)\n")
    figure = tmp_path / "laws.png"
    argv = ["bench", "laws", "--scenario", "moving-prey", "--agents", "8", "--seeds", "2", "--duration", "5",
            "--latency", "0,200ms", "--dropout", "0.3", "--laws", f"boids,{law}:rush", "--workers", "2", "--json",
            "--figure", str(figure)]
    assert main(argv) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert len(rows) == 2 * 2 * 2 and all(set(r) >= KEYS for r in rows)
    rush = {(r["latency"], r["safety"]): r for r in rows if r["law"].endswith(":rush")}
    assert all(rush[(lat, "off")]["collisions"] > 0 for lat in (0.0, 0.2))
    assert all(rush[(lat, "barrier")]["collisions"] == 0 < rush[(lat, "barrier")]["interventions"] for lat in (0.0, 0.2))
    assert all(r["reached"] <= r["runs"] == 2 and 0.0 <= r["order"] <= 1.0 for r in rows)
    assert figure.stat().st_size > 10_000
    assert main(argv) == 2  # the figure exists: --force to overwrite
    assert "--force" in capsys.readouterr().err
