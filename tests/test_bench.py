"""The network benchmark's bookkeeping: repeats folded into medians, every repeat's ratio kept."""

from zswarm.bench.net import _medians


def test_repeats_fold_into_medians_key_by_key():
    runs = [{"n_agents": 50, "cpu": 1.0, "latency_ms": {"p50": 0.25, "p99": None}, "ok": True, "gone": None},
            {"n_agents": 50, "cpu": 3.0, "latency_ms": {"p50": 0.75, "p99": 2.0}, "ok": False, "gone": None},
            {"n_agents": 50, "cpu": 2.0, "latency_ms": {"p50": 0.5, "p99": 6.0}, "ok": True, "gone": 7}]
    out = _medians(runs)
    assert out["cpu"] == 2.0 and out["n_agents"] == 50
    assert out["latency_ms"] == {"p50": 0.5, "p99": 4.0}  # a repeat without a figure is left out
    assert out["ok"] is True and out["gone"] == 7


def test_bench_world_measures_a_world_fed_by_crowds_and_a_crowd_refuses_ids_beyond_the_run(cli):
    """``zswarm bench world``: crowd processes carry N agents' poses to a real world over a real router;
    the world takes in what they send, keeps its clock and reports its own CPU; a crowd asked to stand
    in for agents the run does not have refuses in one line."""
    import json

    res = cli("-m", "zswarm", "bench", "world", "--agents", "12", "--duration", "2", "--intake", "batch", "--json",
              timeout=120)  # a tick's poses at once (--intake auto does so from N = 100)
    assert res.returncode == 0, res.stderr
    (r,) = json.loads(res.stdout)["runs"]
    assert r["n_agents"] == 12 and r["rate_hz"] == 40.0 and r["poses_per_s_sent"] == 480.0 and r["intake"] == "batch"
    assert 0.8 * 480 < r["poses_per_s_taken_in"] < 1.3 * 480, r  # every agent's poses reached the world
    assert r["world_ticks"] >= 40 and 0.0 < r["world_cpu_share"] < 2.0 and r["recording_mb"] > 0
    bad = cli("-m", "zswarm.bench.crowd", "--first", "10", "--count", "5", "--scenario", "large-swarm",
              "--set", "n_agents=12", "--connect", "tcp/127.0.0.1:1")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "beyond the run's 12 agents" in bad.stderr


def test_compare_refuses_in_one_line_and_tables_both_sides_medians(cli):
    """``bench net --compare REF``: a ref the clone lacks, or more than one N, is one line and exit 2
    before anything starts; the table holds each side's median and every run (a whole comparison runs
    six swarms: docs/benchmarks.md has one)."""
    from zswarm.bench.compare import FIGURES, table

    bad = cli("-m", "zswarm", "bench", "net", "--compare", "no-such-ref-anywhere", "--agents", "5")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "no commit 'no-such-ref-anywhere'" in bad.stderr
    two = cli("-m", "zswarm", "bench", "net", "--compare", "HEAD", "--agents", "5,10")
    assert two.returncode == 2 and "one N" in two.stderr
    each = {label: {"ref": [1.0, 2.0, 3.0], "this": [0.5, 0.25, 4.0]} for label, _, _ in FIGURES}
    out = {"ref": "v1", "commit": "0123456789abcdef", "runs": 3, "each": each,
           "medians": {label: {"ref": 2.0, "this": 0.5} for label, _, _ in FIGURES}}
    rows = table(out).splitlines()
    assert rows[0].startswith("| figure | v1 (0123456) | this tree |") and len(rows) == 2 + len(FIGURES)
    assert rows[2] == "| agent CPU per tick (ms) | 2.000 | 0.500 | 1.000, 2.000, 3.000; 0.500, 0.250, 4.000 |"


def test_the_bench_hands_its_world_the_verdict_as_zswarm_run_does(tmp_path):
    """The bench's world is started as ``zswarm run`` starts it, with the set's design verdict judged
    before anything starts: a world left to judge it spent a core beside the swarm it measured."""
    import json

    from zswarm.bench.net import field_spec, start_field
    from zswarm.design.guidelines import verdict
    from zswarm.host.procs import Children

    spec = field_spec(3, "judged", 2.0)
    kids = Children()
    try:
        _, world, _ = start_field(kids, spec, tmp_path / "s.json")
        argv = open(f"/proc/{world.pid}/cmdline", "rb").read().decode().split("\0")
    finally:
        kids.stop_all(grace=3.0)
    given = json.loads(argv[argv.index("--design") + 1])
    assert given == json.loads(json.dumps(verdict(spec.scenario.params, spec.scenario.dt, spec.safety)))
