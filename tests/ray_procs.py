"""Helpers of the tests that run Ray clusters (tests/test_cluster.py): Ray starts only inside a network
namespace that looks like a user's machine, an interface and a default route into a gateway that
forwards nothing (:func:`hostlike`), or inside two namespaces joined by a veth pair (:func:`start_ray`), and every process of a test's run carries its mark, so that
each test finds its own run's processes and no other's."""

from __future__ import annotations

import atexit
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

import zswarm
from conftest import ROOT

NO_RAY = importlib.util.find_spec("ray") is None


def can_make_hosts() -> bool:
    if os.geteuid() != 0 or shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    return subprocess.run(["unshare", "--net", "true"], capture_output=True).returncode == 0


#: The marks of every test that runs a cluster.
RAY_TESTS = [pytest.mark.skipif(NO_RAY, reason='Ray is not installed (pip install -e ".[cluster]")'),
             pytest.mark.skipif(not can_make_hosts(), reason="needs root and iproute2 for network namespaces (Ray "
                                                           "must not reach past them)")]

#: The namespaces :func:`hostlike` made (each with its gateway), removed by :func:`remove_hostlike`.
_MADE: list[str] = []
#: What a host-like namespace has: an interface, its address, and its gateway (the default route).
ETH0, GATEWAY = "10.231.0.2", "10.231.0.1"


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, timeout=30)


def make_hostlike(records: Path | None = None) -> str:
    """A network namespace that looks like a user's machine (as ``hostlike`` does): loopback, and
    ``eth0`` at :data:`ETH0`/24 with a default route via :data:`GATEWAY`, a second namespace that
    forwards nothing, so nothing sent there leaves this machine. ``records``: a folder that gets the
    namespace's addresses (``links.txt``) and routes (``routes.txt``). Its name, for ``ip netns exec``."""
    name = f"zshl{os.getpid()}-{len(_MADE)}"
    gw, tmp = f"{name}g", f"zv{os.getpid() % 100000}{len(_MADE)}"
    _MADE.append(name)
    _ip("netns", "add", name)
    _ip("netns", "add", gw)
    _ip("link", "add", tmp, "netns", name, "type", "veth", "peer", "name", "gw0", "netns", gw)
    _ip("-n", name, "link", "set", tmp, "name", "eth0")
    _ip("-n", name, "addr", "add", f"{ETH0}/24", "dev", "eth0")
    _ip("-n", gw, "addr", "add", f"{GATEWAY}/24", "dev", "gw0")
    for ns, dev in ((name, "lo"), (name, "eth0"), (gw, "lo"), (gw, "gw0")):
        _ip("-n", ns, "link", "set", dev, "up")
    _ip("-n", name, "route", "add", "default", "via", GATEWAY)
    if records is not None:
        for what, file in (("addr", "links.txt"), ("route", "routes.txt")):
            out = subprocess.run(["ip", "-n", name, "-o", what], capture_output=True, text=True, timeout=30).stdout
            (records / file).write_text(out)
    return name


def remove_hostlike() -> None:
    while _MADE:
        name = _MADE.pop()
        for ns in (name, f"{name}g"):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)


atexit.register(remove_hostlike)


def hostlike(cwd: Path, *argv: str, mark: str) -> tuple[list[str], dict[str, str]]:
    """``python ARGV`` in a new :func:`make_hostlike` namespace, its records in ``cwd``: the command
    line (``ip netns exec`` execs it: the process started is python itself) and its environment."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ZSWARM_TEST_MARK": mark}
    return ["ip", "netns", "exec", make_hostlike(cwd), sys.executable, *argv], env


#: What the calls below learned of whose each process is (pid or Ray run folder -> mark): a process is
#: seen while its run is alive, and still known once its run's other processes, which told whose it
#: is, are gone.
_OWNER: dict[int, str] = {}
_RUN_OWNER: dict[bytes, str] = {}


def _processes() -> dict[int, tuple[bytes, list[bytes], int]]:
    out = {}
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            cmd, env = (d / "cmdline").read_bytes(), (d / "environ").read_bytes().split(b"\0")
            ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, ValueError, IndexError):
            continue
        if cmd:
            out[int(d.name)] = (cmd, env, ppid)
    return out


def _var(env: list[bytes], name: bytes) -> bytes | None:
    return next((e[len(name) + 1:] for e in env if e.startswith(name + b"=")), None)


def owners(procs: dict[int, tuple[bytes, list[bytes], int]]) -> dict[int, str]:
    """Whose run each process is (its test's mark): its own ``ZSWARM_TEST_MARK``, else that of a process
    of the same Ray run folder (``ZSWARM_RAY_RUN``), of its raylet (``RAY_RAYLET_PID``) or of its parent.
    Ray's agents write their titles over the start of their environment, the mark with it."""
    owner = {pid: _OWNER[pid] for pid in procs if pid in _OWNER}
    for pid, (_, env, _) in procs.items():
        if (mark := _var(env, b"ZSWARM_TEST_MARK")) is not None:
            owner[pid] = mark.decode()
    run = {pid: r for pid, (_, env, _) in procs.items() if (r := _var(env, b"ZSWARM_RAY_RUN")) is not None}
    raylet = {pid: int(r) for pid, (_, env, _) in procs.items() if (r := _var(env, b"RAY_RAYLET_PID") or b"").isdigit()}
    changed = True
    while changed:
        changed = False
        _RUN_OWNER.update({run[pid]: owner[pid] for pid in run if pid in owner})
        for pid, (_, _, ppid) in procs.items():
            if pid not in owner:
                found = _RUN_OWNER.get(run.get(pid)) or owner.get(raylet.get(pid)) or owner.get(ppid)
                if found is not None:
                    owner[pid], changed = found, True
    _OWNER.update(owner)
    return owner


def left_behind(mark: str) -> list[str]:
    """Processes of a run still there: every process that is the run's (:func:`owners`: the world, the
    routers, the fleets, the agents, Ray's nodes), and any Ray process that is nobody's (a test of another
    module may run a cluster meanwhile: its processes are its own)."""
    procs = _processes()
    owner = owners(procs)
    out = []
    for pid, (cmd, _, _) in procs.items():
        ray = cmd.startswith(b"ray::") or b"/site-packages/ray/" in cmd
        if owner.get(pid) == mark or (ray and pid not in owner):
            out.append(f"{pid}: {cmd.replace(bytes(1), b' ')[:120].decode(errors='replace')}")
    return out


def end_run(driver: subprocess.Popen, mark: str) -> None:
    """Whatever a test leaves when it fails: the driver, and every process of its run (its own only:
    another module's cluster may be running)."""
    if driver.poll() is None:
        driver.kill()
    procs = _processes()
    owner = owners(procs)
    kill_all([pid for pid in procs if owner.get(pid) == mark])


def wait_gone(mark: str, seconds: float) -> list[str]:
    deadline = time.monotonic() + seconds
    while (left := left_behind(mark)) and time.monotonic() < deadline:
        time.sleep(0.2)
    return left


HEAD, WORKER = "10.77.0.1", "10.77.0.2"
FAST_HEALTH = '{"health_check_initial_delay_ms": 0, "health_check_period_ms": 200, ' \
              '"health_check_timeout_ms": 300, "health_check_failure_threshold": 3}'


def ray_node_env(folder: Path, mark: str) -> dict[str, str]:
    """What docs/cluster.md tells users to give ``ray start``: zswarm's offline settings, a HOME with the
    bootstrap file (no cloud-metadata probe), a RAY_TMPDIR of the node's own, and token authentication
    with the cluster's one token (a file beside the nodes' folders, mode 600)."""
    import secrets

    from zswarm.cluster.ray_env import offline_env

    token = folder.parent / "token"
    if not token.exists():
        token.parent.mkdir(parents=True, exist_ok=True)
        token.write_text(secrets.token_hex(32))
        token.chmod(0o600)
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    return dict(offline_env(folder, {**env, "PYTHONPATH": str(ROOT), "ZSWARM_TEST_MARK": mark,
                                     "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)}))


def in_ns(ns: str, *argv: str) -> list[str]:
    return ["ip", "netns", "exec", ns, *argv]


def start_ray(ns: str, env: dict[str, str], *args: str) -> None:
    ray = str(Path(sys.executable).parent / "ray")
    res = subprocess.run(in_ns(ns, ray, "start", *args, "--num-cpus", "1", "--object-store-memory", str(80 * 2**20),
                               "--disable-usage-stats"), env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]


def node_processes(folder: Path) -> list[int]:
    """The Ray processes of the node(s) whose RAY_TMPDIR is under ``folder``: those that name it (the
    raylet, in its command line; the processes it started, in their environment), and those that
    name such a raylet as theirs (``RAY_RAYLET_PID``: Ray's agents set their titles over the start of
    their environment, the folder with it) or have it as their parent."""
    tag = str(folder).encode()
    procs = _processes()
    named = [pid for pid, (cmd, env, _) in procs.items() if tag in cmd or any(tag in e for e in env)]
    marks = {f"{pid}".encode() for pid in named}
    return named + [pid for pid, (_, env, ppid) in procs.items() if pid not in named
                    and (ppid in named or _var(env, b"RAY_RAYLET_PID") in marks)]


def kill_all(pids: list[int]) -> None:
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def read_until(proc: subprocess.Popen, needle: str, seconds: float) -> list[str]:
    """Lines of ``proc``'s output up to the first holding ``needle`` (AssertionError at the deadline)."""
    import selectors

    lines, deadline = [], time.monotonic() + seconds
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    while time.monotonic() < deadline:
        if sel.select(timeout=0.5):
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if needle in line:
                return lines
    raise AssertionError(f"no {needle!r} in time; got {''.join(lines)[-2000:]}")


def stale_keys(since: float) -> list[Path]:
    """Node key folders made since ``since`` whose actor is gone."""
    from zswarm.cluster.node import KEYS_PREFIX

    return [p for p in Path(tempfile.gettempdir()).glob(f"{KEYS_PREFIX}*") if p.stat().st_mtime >= since
            and not Path(f"/proc/{p.name[len(KEYS_PREFIX):].split('-')[0]}").exists()]


def fake_zswarm(folder: Path, version: str) -> Path:
    """A folder to put first on a node's PYTHONPATH: this zswarm with another version number."""
    package = folder / "zswarm"
    shutil.copytree(ROOT / "zswarm", package, ignore=shutil.ignore_patterns("__pycache__"))
    init = package / "__init__.py"
    init.write_text(init.read_text().replace(f'__version__ = "{zswarm.__version__}"', f'__version__ = "{version}"'))
    return folder


def is_zswarm(line: str) -> bool:
    """A process line of zswarm's own (the world, routers, fleets, agents, a driver), not of Ray."""
    return any(k in line for k in ("-m world", "zswarm.net.router", "agents.fleet", "-m agents", "-m zswarm"))
