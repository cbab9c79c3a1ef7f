"""Reaching a Ray cluster from the driver: an existing one (``ADDRESS`` or ``auto``), or one started
here (``local``: this machine as one node; ``local:K``: K nodes on this machine,
:mod:`zswarm.cluster.local_nodes`).

Every Ray process started here gets the offline environment of :mod:`zswarm.cluster.ray_env`. Ray is
imported only here and in :mod:`zswarm.cluster.hosts`, lazily: ``zswarm`` runs without it.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from zswarm.cluster.local_nodes import RAY_LOOPBACK, LocalNodes, read_until
from zswarm.cluster.ray_env import offline_env
from zswarm.errors import UsageError
from zswarm.ports import LOOPBACK

INSTALL = 'Ray is not installed: pip install -e ".[cluster]" (or pip install "ray==2.60.*") on every node'
ADDRESS = re.compile(r"^(auto|local(:\d+)?|[\w.\-\[\]:]+:\d+)$")


def parse_cluster(text: str) -> str:
    """``--cluster`` values: ``auto``, ``local``, ``local:K`` (1 <= K <= 16), or ``HOST:PORT``."""
    if not ADDRESS.match(text):
        raise UsageError(f"--cluster takes HOST:PORT of a Ray head (ray start --head prints it), auto, local or "
                         f"local:K (got {text!r})")
    if text.startswith("local:") and not 1 <= int(text.split(":")[1]) <= 16:
        raise UsageError(f"--cluster local:K starts K nodes on this machine: 1 to 16 (got {text!r})")
    return text


def local_nodes(address: str, cores: int) -> tuple[int, int]:
    """A cluster started on this machine (``local`` or ``local:K``): its K nodes, and the cores each
    gets of this machine's ``cores`` (``cores // K``, at least 1)."""
    k = int(address.split(":")[1]) if ":" in address else 1
    return k, max(cores // k, 1)


def local_cores(address: str, cores: int) -> int:
    """The cores such a cluster has in all: its nodes' (:func:`local_nodes`), no more than the machine's."""
    k, each = local_nodes(address, cores)
    return min(k * each, cores)


def import_ray() -> Any:
    try:
        import ray
    except ImportError:
        raise UsageError(INSTALL) from None
    return ray


@dataclass
class RayCluster:
    """The driver's connection; ``local`` holds the nodes started here (:class:`LocalNodes`, stopped by
    :meth:`close`); ``auth``: "token" when the cluster wants a token (one made for a cluster started here), "off" when
    anyone who reaches its head may run code on it (run only with ``--cluster-insecure-ok``)."""

    address: str
    run_dir: Path | None  # a cluster started here: its folder (RAY_TMPDIR, HOME)
    local: Any = None
    nodes: list[dict] = field(default_factory=list)
    auth: str = "token"

    def alive_nodes(self) -> list[dict]:
        """Ray's record of each live node: NodeID, NodeManagerAddress, Resources (CPU)."""
        ray = import_ray()
        return sorted((n for n in ray.nodes() if n.get("Alive")), key=lambda n: n["NodeID"])

    def driver_node(self) -> str:
        ray = import_ray()
        return ray.get_runtime_context().get_node_id()

    def close(self) -> None:
        ray = import_ray()
        with contextlib.suppress(Exception):
            ray.shutdown()
        if self.local is not None:
            self.local.close()
        if self.run_dir is not None:
            shutil.rmtree(self.run_dir, ignore_errors=True)


#: What Ray's C++ core prints while it starts in a process, before it reads RAY_BACKEND_LOG_LEVEL: that
#: its UDP connect towards 8.8.8.8 (which sends no packet) found no route, and that it set the log level.
RAY_STARTUP_NOISE = re.compile(rb"network_util\.cc:\d+: Failed to determine local IP|logging\.cc:\d+: Set ray log level")


@contextlib.contextmanager
def ray_startup_filter():
    """This process's standard error (file descriptor 2, where Ray's C++ core writes) through a filter
    while Ray starts here: :data:`RAY_STARTUP_NOISE` is dropped, every other line passes. Processes
    started meanwhile keep writing through it (it lives as long as they do)."""
    read, write = os.pipe()
    terminal = os.dup(2)

    def pump() -> None:  # keeps draining whatever happens: a full pipe would block whoever writes to it
        with os.fdopen(read, "rb") as lines:
            for line in lines:
                if not RAY_STARTUP_NOISE.search(line):
                    try:
                        os.write(terminal, line)
                    except OSError:
                        pass

    sys.stderr.flush()
    os.dup2(write, 2)
    os.close(write)
    threading.Thread(target=pump, daemon=True).start()
    try:
        yield
    finally:
        sys.stderr.flush()
        os.dup2(terminal, 2)


@contextlib.contextmanager
def _signals_interrupt():
    """While the cluster starts: SIGTERM as Ctrl-C (KeyboardInterrupt), so that either ends the nodes
    started so far, at once (the run's own handlers take over once it runs)."""
    import signal

    def interrupt(*_: object) -> None:
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def reachable(address: str, timeout: float = 5.0) -> tuple[str, str]:
    """The head's ``HOST:PORT`` for ``address`` (``auto``: ``RAY_ADDRESS``, or the cluster ``ray start``
    left on this machine), once its port answers, and this machine's address on the way there (the
    driver's node address: Ray would otherwise find it by a probe towards 8.8.8.8); UsageError (one
    line) otherwise. Ray itself would retry an address that does not answer for minutes."""
    import socket

    found = address == "auto"
    if found:
        address = auto_address()
    host, _, port = address.rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout) as s:
            own = s.getsockname()[0]
    except (OSError, ValueError) as exc:
        if found:
            raise UsageError(f"--cluster auto found no running Ray cluster: the last one ray start left on this "
                             f"machine, {address}, does not answer ({exc.strerror or exc}); start it again, or give "
                             "HOST:PORT, or use --cluster local") from None
        raise UsageError(f"cannot reach the Ray cluster at {address} ({exc.strerror or exc}): is its head "
                         "running (ray start --head) and the port open? or use --cluster local") from None
    return address, own


def auto_address() -> str:
    """``--cluster auto``: ``RAY_ADDRESS``, else the cluster ``ray start --head`` left on this machine (its
    bootstrap file). Never Ray's own fallback, a scan of the machine's processes for any running Ray head:
    that finds another program's private cluster (a ``--cluster local`` run of another checkout)."""
    from ray._private.services import find_bootstrap_address

    address = os.environ.get("RAY_ADDRESS", "").strip() or find_bootstrap_address(None)
    if not address:
        raise UsageError("--cluster auto found no Ray cluster on this machine (RAY_ADDRESS is unset and "
                         "ray start --head was not run here): give HOST:PORT, or --cluster local")
    return address


AUTH_VARS = ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH")
#: The Ray release whose internals the token check reads (Ray has no public call that asks a head
#: whether it wants a token): ``ray._raylet.GcsClient`` and ``AuthenticationTokenLoader``. Another
#: release is refused before the check runs, with both versions in the line; pyproject pins the same.
RAY_RELEASE = "2.60"


def check_ray_release() -> None:
    """UsageError (one line) unless the installed Ray is :data:`RAY_RELEASE`: the token check would
    read internals another release may have moved, and must not pass by accident."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        have = version("ray")
    except PackageNotFoundError:
        raise UsageError('--cluster needs Ray: pip install -e ".[cluster]"') from None
    if ".".join(have.split(".")[:2]) != RAY_RELEASE:
        raise UsageError(f"this is Ray {have}; zswarm's check of a head's token authentication reads Ray "
                         f"{RAY_RELEASE}'s internals (ray._raylet.GcsClient, AuthenticationTokenLoader): install "
                         f"ray=={RAY_RELEASE}.* (pip install -e \".[cluster]\")")


#: Asks the head's GCS for one key, as a Ray node does when it joins, as a driver without a token; when
#: the head refuses that and the driver holds a token (handed over as ``ZSWARM_PROBE_RAY_AUTH_*``), asks
#: again in token mode, in the same interpreter (one import of Ray). Prints a line per ask: "ok", "auth"
#: when the head refuses the token (or its absence), or "error ..."; a driver in token mode with no
#: token at all makes Ray abort.
_PROBE = """
import os
held = {{k[13:]: os.environ.pop(k) for k in list(os.environ) if k.startswith("ZSWARM_PROBE_")}}
try:
    from ray._raylet import GcsClient, AuthenticationTokenLoader, Config
except ImportError as exc:
    print("internals " + str(exc)[:160], flush=True)
    raise SystemExit(0)
print("imported", flush=True)

def ask():
    try:
        GcsClient(address={address!r}).internal_kv_get(b"zswarm", None, timeout=3)
        return "ok"
    except Exception as exc:
        return "auth" if type(exc).__name__ == "AuthenticationError" else "error " + str(exc)[:160]

answer = ask()
print(answer, flush=True)
if answer == "auth" and held:
    os.environ.update(held)  # token mode, with this driver's token: Ray reads both again
    Config.initialize("")
    AuthenticationTokenLoader.instance().reset_cache()
    print(ask(), flush=True)
"""
AUTH_TIMEOUT = 5.0
#: How long the probe may take to import Ray, on a machine however busy.
IMPORT_TIMEOUT = 60.0


def _probe(address: str, token: dict[str, str]) -> list[str]:
    """What the head at ``address`` answered a driver without a token, then (where it refused that and
    ``token`` holds this driver's token settings) one with it: "ok", "auth" or "error ..." each. The head
    has :data:`AUTH_TIMEOUT` seconds from the moment the probe has imported Ray (which a busy machine
    may take seconds for: that is no silence of the head)."""
    env = {k: v for k, v in os.environ.items() if k not in AUTH_VARS}
    env.update({f"ZSWARM_PROBE_{k}": v for k, v in token.items()})  # not RAY_AUTH_*: the first ask goes without
    proc = subprocess.Popen([sys.executable, "-c", _PROBE.format(address=address)], env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        said = read_until(proc, b"imported\n", IMPORT_TIMEOUT)
        if said.startswith(b"imported\n"):
            said = said[len(b"imported\n"):] + read_until(proc, None, AUTH_TIMEOUT)
        proc.wait(timeout=1.0)  # it said all it had to: it ends
    except subprocess.TimeoutExpired:
        return [f"error no answer in {AUTH_TIMEOUT:g} s"]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return said.decode(errors="replace").strip().splitlines() or ["auth"]  # Ray aborted: token mode, no token


def head_auth(address: str) -> str:
    """Whether the head at ``address`` wants a token ("token") or lets anyone in ("off"), and, when it
    wants one, that this driver holds the right one (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH`` or
    ``~/.ray/auth_token``, as Ray reads it): UsageError in one line, within seconds, otherwise. Ray's
    own driver fails at once without a token but only after about 20 s with a wrong one."""
    has = any(os.environ.get(k) for k in AUTH_VARS[1:]) or (Path.home() / ".ray" / "auth_token").is_file()
    token = {k: os.environ[k] for k in AUTH_VARS[1:] if os.environ.get(k)} | {"RAY_AUTH_MODE": "token"} if has else {}
    check_ray_release()
    answers = _probe(address, token)
    if answers[0].startswith("internals"):
        from importlib.metadata import version

        raise UsageError(f"Ray {version('ray')} has moved what the token check reads ({answers[0][10:]}): install "
                         f"ray=={RAY_RELEASE}.*")
    if answers[0] == "ok":
        return "off"
    if answers[0] != "auth":
        raise UsageError(f"cannot reach the Ray cluster at {address}: {answers[0][6:]} (is its head running?)")
    if has and answers[-1] == "ok":
        os.environ["RAY_AUTH_MODE"] = "token"  # for ray.init below
        return "token"
    why = "a wrong token" if has else "no token"
    raise UsageError(f"the Ray cluster at {address} wants a token and this driver has {why}: set RAY_AUTH_TOKEN_PATH "
                     "(or RAY_AUTH_TOKEN) to the cluster's token, the one ray get-auth-token prints on its head "
                     "(docs/cluster.md)")


def connect(address: str, cores: int, insecure_ok: bool = False) -> RayCluster:
    """Start or join the cluster at ``address`` (:func:`parse_cluster`); ``cores``: this machine's, shared
    by the nodes of ``local:K``. UsageError (one line) when it cannot be reached or will not let this
    driver in. A cluster started here wants a token made for the run (``RAY_AUTH_MODE=token``, the token
    in the environment of every Ray process it starts, never in a file); one that wants none is refused
    in one line unless ``insecure_ok``."""
    own = LOOPBACK
    auth = "token"
    if not address.startswith("local"):
        address, own = reachable(address)
        auth = head_auth(address)
        if auth == "off" and not insecure_ok:
            raise UsageError(f"the Ray cluster at {address} has token authentication off: anyone who can reach its "
                             "head can run code on every node; start it with a token (docs/cluster.md), or give "
                             "--cluster-insecure-ok to run on it anyway (the summary says \"ray_auth\": \"off\")")
    else:
        import secrets

        os.environ.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
        os.environ.pop("RAY_AUTH_TOKEN_PATH", None)
    ray = import_ray()
    if auth == "token":  # Ray reads the mode and caches the token when it is imported: read them again
        from ray._raylet import AuthenticationTokenLoader, Config

        Config.initialize("")
        AuthenticationTokenLoader.instance().reset_cache()
    local = address.startswith("local")
    # a cluster started here gets a folder of its own, named for its driver; short: Ray's socket paths are limited
    run_dir = Path(tempfile.mkdtemp(prefix=f"zs-ray-{os.getpid()}-", dir="/tmp")) if local else None
    offline_env(run_dir)
    quiet = {"configure_logging": True, "logging_level": "ERROR", "log_to_driver": False}
    cluster = RayCluster(address, run_dir, auth=auth)
    if local:  # a guard that kills the nodes started here if this driver dies
        subprocess.Popen([sys.executable, "-m", "zswarm.cluster.reaper", str(os.getpid()), str(run_dir)],
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, start_new_session=True,
                         env={k: v for k, v in os.environ.items() if k != "ZSWARM_RAY_RUN"})
    try:
        with ray_startup_filter(), _signals_interrupt():
            if local:
                k, each = local_nodes(address, cores)
                cluster.local = LocalNodes()
                head = cluster.local.start(k, each)
                ray.init(address=head, _node_ip_address=RAY_LOOPBACK, **quiet)
            else:
                ray.init(address=address, _node_ip_address=own, **quiet)
    except (ConnectionError, RuntimeError, TimeoutError, ValueError) as exc:
        cluster.close()
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise UsageError(f"cannot reach the Ray cluster at {address}: {first[:160]} (start it with "
                         "ray start --head, or use --cluster local)") from None
    except BaseException:
        cluster.close()
        raise
    return cluster
