"""Shared test helpers: run the project's programs as real subprocesses with hard timeouts."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from zswarm.process import one_blas_thread

ROOT = Path(__file__).resolve().parents[1]


#: What the running test's processes printed, for its report should it fail (:func:`pytest_runtest_makereport`):
#: (title, text) or (title, path of a log file); the test's processes (:func:`swarm_procs.processes`) and
#: its commands (:func:`run_cli`) add to it, and it is cleared after each test.
PROCESS_LOGS: list[tuple[str, str | Path]] = []
#: The lines of each that a failing test's report keeps, the last ones.
LOG_TAIL = 200


def tail(text: str, lines: int = LOG_TAIL) -> str:
    kept = text.splitlines()[-lines:]
    return "\n".join(kept)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failing test's report ends with the last :data:`LOG_TAIL` lines of what each process it started
    printed (one section each); the logs are let go after the test."""
    outcome = yield
    report = outcome.get_result()
    if report.failed:
        for title, log in PROCESS_LOGS:
            text = log if isinstance(log, str) else log.read_text(errors="replace") if log.is_file() else ""
            if title and text.strip():
                report.sections.append((f"last {LOG_TAIL} lines of {title}", tail(text)))
    if call.when == "teardown":
        for _, log in PROCESS_LOGS:
            if isinstance(log, Path) and log.is_dir():
                shutil.rmtree(log, ignore_errors=True)
        PROCESS_LOGS.clear()


#: This worker's idle fork servers (:class:`forked_cli.ForkServer`): one, or more while tests run commands
#: from several threads at once.
_FORKS: list = []
_FORKS_LOCK = threading.Lock()


def run_cli(*args: str, timeout: float = 120.0, cwd: Path | None = None,
            fresh: bool = False) -> subprocess.CompletedProcess:
    """Run ``python ARGS`` (``-m MODULE ...`` or a script) to completion, as ``subprocess.run`` would with
    its output captured as text; killed (with what it started) on timeout, which raises
    ``subprocess.TimeoutExpired``. Each command is a process of its own, forked from an interpreter that
    imported the project once (:class:`forked_cli.ForkServer`), with this process's environment; ``fresh``:
    in an interpreter of its own, for a command whose end matters (a fork leaves by ``os._exit``, without
    the interpreter's finalization: a live Rerun stream once arrived without its agents that way)."""
    from forked_cli import ForkServer

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if fresh:
        res = subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=timeout,
                             cwd=cwd or ROOT, env=env)
        return _logged(res)
    with _FORKS_LOCK:
        server = _FORKS.pop() if _FORKS else None
    if server is None:
        server = ForkServer(ROOT)
    try:
        res = server.run(list(args), cwd or ROOT, env, timeout)
    except subprocess.TimeoutExpired:  # the server killed the command, and serves on
        _idle(server)
        raise
    except BaseException:
        server.close()
        raise
    _idle(server)
    return _logged(res)


def _logged(res: subprocess.CompletedProcess) -> subprocess.CompletedProcess:
    """``res``'s output, kept for the test's report (:data:`PROCESS_LOGS`)."""
    what = " ".join(map(str, res.args[1:5]))  # the command without the interpreter
    PROCESS_LOGS.append((f"{what} (exit {res.returncode})", f"{res.stdout or ''}{res.stderr or ''}"))
    return res


def _idle(server) -> None:
    with _FORKS_LOCK:
        _FORKS.append(server)


def pytest_unconfigure(config) -> None:
    while _FORKS:
        _FORKS.pop().close()
    if not hasattr(config, "workerinput") and _CACHE:
        shutil.rmtree(_CACHE.pop(), ignore_errors=True)


#: The suite's own cache of results (:mod:`zswarm.cache`), shared by its workers and what they start, made
#: empty for each session and removed after it: the user's cache is neither read nor written.
_CACHE: list[str] = []


@pytest.fixture
def cli():
    return run_cli


def free_port() -> int:
    """A TCP port nothing listens on now (for a router or a viewer a test starts), from this worker's
    own range when the suite runs in parallel (:func:`pytest_configure`)."""
    from zswarm.ports import free_port as pick

    return pick()


#: Modules whose tests start routers, worlds, agents or launches (a test elsewhere that runs a command
#: through the ``cli`` fixture is marked too).
PROCESS_MODULES = {
    "test_distributed", "test_reliability", "test_hostile", "test_space_procs", "test_usage", "test_experiments",
    "test_robots", "test_security", "test_netns", "test_render", "test_install", "test_routers", "test_migration",
    "test_faults", "test_monitor", "test_live", "test_latency", "test_api", "test_export", "test_bench", "test_soak",
    "test_tune", "test_study", "test_cluster", "test_joining", "test_fleet", "test_law_processes",
    "test_secure_options", "test_stopping", "test_asks",
}

#: Of those, the modules whose tests run swarms (a world and its agents, free-running or lockstep): at most
#: one worker a core runs them at once (:func:`pytest_xdist_make_scheduler`). The others start routers,
#: commands that refuse a mistake, or a swarm simulated in the test's own process.
SWARM_MODULES = PROCESS_MODULES - {"test_usage", "test_tune", "test_asks", "test_api", "test_stopping", "test_export"}


#: The modules that take longest, longest first: first the second tier's own (by the worker-seconds each
#: took alone on 2 cores, 2026-12-05), then the first tier's (2026-12-07, a slow hour: the wall each
#: took in the README's command). Under ``--dist loadfile`` each module goes whole to one worker, in this
#: order, to whichever worker is free: the long ones first, so that what is handed out last, when the
#: workers run out of work unevenly, is short. Modules not named (a few seconds or less) keep their order,
#: after these. A long module left out of it is handed out late and becomes the suite's tail.
LONGEST_FIRST = (
    "test_cluster", "test_space_procs", "test_secure_options", "test_install", "test_render", "test_netns",
    "test_hostile", "test_study", "test_routers",
    "test_distributed", "test_reliability", "test_design", "test_experiments", "test_sim", "test_security",
    "test_usage", "test_messages", "test_robots", "test_mixed", "test_law_processes", "test_migration",
    "test_law_loading", "test_body", "test_forged_pose", "test_tune", "test_monitor", "test_scaling", "test_faults",
    "test_pose_batch", "test_pki_travel", "test_bench_laws", "test_fleet", "test_space", "test_safety", "test_live",
    "test_bridge", "test_design_swarm", "test_one_law", "test_batch", "test_architecture", "test_bench", "test_asks",
    "test_control_step", "test_potentials", "test_cells",
)


#: The second tier (``-m deep``, which ``.ci/run`` runs after the README's command): process tests that
#: hold at length what a cheaper test of the first tier holds, and the optional extras. Whole modules, or
#: single tests (by name, with or without their parameters).
DEEP_MODULES = {
    "test_cluster",  # Ray clusters in network namespaces: the cluster extra
    "test_secure_options",  # each option again under --secure: test_security holds TLS and the access control
    "test_install",  # a wheel installed elsewhere: CI's own install of the package does the same
    "test_netns",  # hosts in network namespaces (root)
    "test_render",  # the real Rerun viewer, headless
    "test_study",  # the guideline study's table
}
DEEP_TESTS = {
    "test_the_grown_set_passes_the_design_checks_at_that_size[large-swarm-1000]",  # N = 100 holds the check
    "test_an_interrupted_tune_resumes_to_the_same_result_losing_no_evaluation",  # tune's resume, at length
    "test_a_tune_that_does_not_beat_the_start_keeps_the_start_and_says_so",
    "test_interrupted_distributed_sweep_resumes",  # the simulated sweep's resume holds it
    "test_random_scenario_files_are_run_or_refused_in_one_line_leaving_nothing_behind",  # the listed mistakes hold it
    "test_flood_of_hostile_messages_changes_nothing",  # test_forged_pose and the decoder's fuzzing hold it
    # 3-D as processes again: test_distributed's 3-D lockstep run holds it
    "test_the_3d_demo_runs_as_processes_and_catches_the_prey",
    "test_faults_a_crash_a_2d_stranger_and_the_monitor_in_3d",
    "test_the_3d_demo_recording_opens_in_a_3d_view",
    # a world replaced: test_world_killed_at_once_is_replaced_and_the_run_still_adds_up holds it
    "test_world_killed_and_restarted_continues_the_run_in_a_new_segment",
    # the same plumbing for other interactions and a static goal: the simulators' tests hold those
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[static-goal-15.0-paper-point-off]",
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[moving-prey-10.0-mean+gate-point-barrier]",
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[moving-prey-6.0-mean+gate+swirl-point-barrier]",
    # the 30 s chase: the 3-D and double-integrator lockstep runs hold it
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[moving-prey-30.0-paper-point-barrier]",
    # the mixed swarm's lockstep run holds unicycles as processes (test_mixed); the simulators hold the trap
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[moving-prey-5.0-paper-unicycle-barrier]",
    "test_lockstep_swarm_reproduces_the_reference_and_catches_the_prey[goal-near-obstacle-8.0-paper-point-barrier]",
    # the free-running run ends 2 s after its capture (--end-after-capture); the simulator's rule: test_sim
    "test_a_run_ends_the_time_asked_after_the_capture",
    # test_every_law_runs_in_a_batch_as_alone_with_faults_and_a_law_without_a_batched_form holds it
    "test_each_run_matches_its_run_alone_at_every_step",
    # the swarm check at N = 100 and beyond: test_the_swarm_check_runs_the_law_in_use_at_30 holds the check
    "test_the_swarm_check_knows_what_n_it_cannot_reach",
    # a sweep with and without the filter: test_a_users_law_runs_in_a_sweep_and_collides_only_without_the_filter
    "test_a_sweep_puts_the_safety_filter_beside_the_law_alone",
    # TLS and access control: test_secure_swarm_never_sees_an_intruder; three meshed routers: test_migration
    "test_a_secure_run_over_three_routers_says_so_in_its_summary",
    # test_killed_agent_leaves_neighbour_sets_within_a_second_and_a_restarted_one_returns holds it
    "test_killing_one_agent_leaves_the_others_running_and_is_recorded",
    "test_three_meshed_routers_carry_one_swarm_that_catches_the_prey",  # test_migration's three routers hold it
    # the monitor against a summary (test_monitor) and a secure run (test_security) hold it
    "test_the_monitor_command_a_secure_run_prints_works_as_printed",
    # growing a set: the cases at N = 10 and 30 hold it
    "test_the_grown_set_passes_the_design_checks_at_that_size[moving-prey-100]",
    "test_the_grown_set_passes_the_design_checks_at_that_size[bench-field-100]",
    "test_prop1_bound_flips_goal_reachability[0.2]",  # the same flip at 0.1 holds it
    # a handoff's failures: test_agents_move_between_routers_as_the_swarm_moves_and_nothing_is_lost holds the move
    "test_a_handoff_the_taker_never_confirms_leaves_the_report_with_the_running_process",
    "test_a_look_the_world_does_not_answer_is_said_and_counted",
    # one law, one tutorial law, one signal, one clock hold the same plumbing: the laws' own tests hold the rest
    "test_lockstep_processes_run_each_law_as_the_reference_does[vasarhelyi]",
    "test_lockstep_processes_run_each_law_as_the_reference_does[olfati-saber]",
    "test_the_tutorials_laws_run_as_lockstep_processes[seek-moving-prey]",
    "test_launch_stopped_by_a_signal_leaves_a_valid_recording_and_reaps_everyone[SIGTERM]",
    "test_an_agent_whose_world_vanished_leaves_in_one_line[lockstep]",
}


def pytest_collection_modifyitems(config, items) -> None:
    """The ``procs`` marker: ``-m "not procs"`` is the quick tier (the math, the messages, the checks);
    the ``deep`` marker: the second tier (:data:`DEEP_MODULES`, :data:`DEEP_TESTS`).
    The order: :data:`LONGEST_FIRST`, then the rest (a stable sort: tests keep their order in a module)."""
    for item in items:
        if item.module.__name__ in PROCESS_MODULES or "cli" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.procs)
        if item.module.__name__ in DEEP_MODULES or item.name in DEEP_TESTS or item.originalname in DEEP_TESTS:
            item.add_marker(pytest.mark.deep)
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.module.__name__, len(LONGEST_FIRST)))


#: ``-n auto`` (the README's command): this many pytest-xdist workers on 2 cores. Workers beyond the cores
#: fill the time tests spend waiting on the wall clock (free-running swarms, Ray nodes starting) with other
#: tests' work; a fifth, even on a machine idle as the suite starts, starved the free-running swarms in a
#: slow hour (docs/benchmarks.md, "The suite").
WORKERS = 4


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist: pytest without it (-p no:xdist) runs too
def pytest_xdist_auto_num_workers(config) -> int | None:
    """``-n auto``: :data:`WORKERS` workers; ``PYTEST_XDIST_AUTO_NUM_WORKERS``, where set, decides."""
    return None if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS") else WORKERS


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile``: modules whole to a worker, as pytest-xdist hands them out, but a module of
    :data:`SWARM_MODULES` only while fewer workers hold one than the machine has cores
    (:class:`swarm_schedule.SwarmCapped`). A free-running swarm paces itself by the wall clock and lags
    when it gets less than a core (docs/benchmarks.md, "The suite"); the other workers meanwhile run the
    tests that start no swarm."""
    if config.getvalue("dist") != "loadfile":
        return None
    from swarm_schedule import SwarmCapped
    from zswarm.launch.plan import available_cores

    return SwarmCapped(config, log, swarm=lambda scope: Path(scope).stem in SWARM_MODULES, cap=available_cores())


def pytest_configure(config) -> None:
    """Under pytest-xdist each worker, and every process it starts, picks ports from a range of its own
    (``ZSWARM_PORTS``, :mod:`zswarm.ports`), below the kernel's ephemeral range: two workers never pick
    the same free port before one of them binds it.

    pytest-xdist hands modules out largest first (by test count) unless told not to; the suite's own
    order (:data:`LONGEST_FIRST`, by time) is the one kept. And a suite started where SIGINT is ignored
    (``nohup``, ``cmd &`` in a script) would pass that on to every process it starts, which then could
    not be interrupted as the tests interrupt them: SIGINT is given its Python default back. The
    session's cache of results is a folder of its own (:data:`_CACHE`)."""
    if not hasattr(config, "workerinput"):  # once, in the process that starts the workers
        compile_tree()
        rewrite_tests_once(config)
        one_blas_thread(os.environ)  # the workers and what they start, as zswarm's own processes do
        import tempfile

        from zswarm.cache import ENV

        _CACHE.append(tempfile.mkdtemp(prefix="zs-cache-"))
        os.environ[ENV] = _CACHE[0]
    if hasattr(config.option, "loadscopereorder"):
        config.option.loadscopereorder = False
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and "ZSWARM_PORTS" not in os.environ:
        k = int(worker[2:]) % 11  # 10000-31999: below the kernel's ephemeral ports (32768-)
        lo = 10_000 + 2_000 * k
        os.environ["ZSWARM_PORTS"] = f"{lo}-{lo + 1_999}"


def compile_tree() -> None:
    """Byte-compile the project's modules into ``__pycache__``. Where ``PYTHONDONTWRITEBYTECODE`` is set (CI
    images often set it), a fresh clone has no compiled modules and none is ever written, so each of the
    hundreds of processes the suite starts (worlds, routers, fleets, commands) would compile every
    module it imports again; compiled once here, they all read it."""
    import compileall

    for folder in ("zswarm", "agents", "world"):
        compileall.compile_dir(str(ROOT / folder), quiet=2)


def rewrite_tests_once(config) -> None:
    """Write each test module's assert-rewritten code into the cache pytest reads it from. pytest
    rewrites the asserts of every test module as it collects it, in every worker, and caches the result
    only where it may write bytecode: under ``PYTHONDONTWRITEBYTECODE`` (CI images often set it) five
    workers each rewrote all of them, about 2.4 CPU-seconds each as the suite starts. The cache is read
    whatever that setting says, and an entry is used only for the source it was made from (its hash), so
    written once here the workers read it. Skipped where pytest's internals differ (they rewrite, as
    before)."""
    try:
        from _pytest.assertion.rewrite import (PYC_TAIL, _read_pyc, _rewrite_test, _write_pyc, assertstate_key,
                                               get_cache_dir)

        state = config.stash[assertstate_key]  # absent under --assert=plain
        for fn in sorted((ROOT / "tests").glob("*.py")):
            if not (fn.name.startswith("test_") or fn.name == "conftest.py"):
                continue  # the helpers are not rewritten
            pyc = get_cache_dir(fn) / (fn.name[:-3] + PYC_TAIL)
            if _read_pyc(fn, pyc) is None:
                pyc.parent.mkdir(exist_ok=True)
                source_hash, code = _rewrite_test(fn, config)
                _write_pyc(state, code, source_hash, pyc)
    except (ImportError, KeyError, AttributeError, TypeError, OSError):
        return  # another pytest's internals, or a folder it may not write: the workers rewrite, as before


def wait_for_port(port: int, timeout: float = 30.0) -> None:
    """Until something listens on 127.0.0.1:``port`` (a router, a viewer), or fail after ``timeout``."""
    import socket
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    raise AssertionError(f"nothing listens on port {port} after {timeout:g} s")
