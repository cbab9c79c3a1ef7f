"""TLS and access control, with certificates made at test time: only agents publish poses, only the
world publishes the prey and answers obstacle queries, and a peer without rights reaches nobody."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from zswarm.args import UsageError
from zswarm.net import messages as msg
from zswarm.net.config import open_session, zenoh_config
from zswarm.net.keys import Keys
from zswarm.host.procs import Child, free_port, start_router, wait_for_port
from zswarm.net.security import write_secure_dir

from conftest import ROOT, run_cli
from swarm_procs import load_summary, processes
from spool import Spool

RUN = "sec"


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    """One shared ``agent`` identity (role-level rights), the world, and a guest with no rights."""
    d = tmp_path_factory.mktemp("certs")
    write_secure_dir(d, names=("router", "world", "agent", "guest"))
    return d


@pytest.fixture(scope="module")
def per_agent(tmp_path_factory) -> Path:
    """An identity per agent (agent-0 .. agent-5), each allowed only its own keys."""
    d = tmp_path_factory.mktemp("per-agent")
    write_secure_dir(d, names=("router", "world", "agent", "guest"), agents=6)
    return d


def start_secure_router(kids, certs: Path, acl: bool = True) -> str:
    config = certs / "router.json5"
    if not acl:
        conf = json.loads(config.read_text())
        conf["access_control"]["enabled"] = False
        config = certs / "router-open.json5"
        config.write_text(json.dumps(conf))
    return start_router(kids, proto="tls", extra=["--config", str(config)])


def session(certs: Path, role: str, endpoint: str) -> zenoh.Session:
    return open_session(zenoh_config(None, [endpoint], (), certs / f"{role}.json5"), what=role, retry_for=5.0)


def until(condition, timeout: float) -> bool:
    """Poll ``condition`` until it holds or ``timeout`` seconds pass; returns whether it held."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def probe(sender: zenoh.Session, key: str, arrived, timeout: float = 20.0) -> None:
    """Put a probe on ``key`` until ``arrived()``: the listener's subscription is in place."""
    deadline = time.monotonic() + timeout
    while not arrived():
        assert time.monotonic() < deadline, f"no probe on {key} arrived within {timeout} s"
        sender.put(key, b"probe")
        time.sleep(0.05)


def exchange(certs: Path, endpoint: str, agent_at: str | None = None, guest_at: str | None = None) -> dict:
    """Every role tries to publish a pose and the prey and to answer obstacle queries; an agent
    listens, queries, and the guest listens too. ``agent_at``, ``guest_at``: the routers the sending
    agent and the guest connect to (default ``endpoint``, the listener's and the world's)."""
    keys = Keys(RUN, 1.0)
    heard, guest_heard = [], []
    with (session(certs, "agent", endpoint) as listener, session(certs, "agent", agent_at or endpoint) as agent,
          session(certs, "world", endpoint) as world, session(certs, "guest", guest_at or endpoint) as guest):
        subs = [listener.declare_subscriber(f"{keys.root}/**",
                                            lambda s: heard.append((str(s.key_expr), s.payload.to_bytes()))),
                guest.declare_subscriber(f"{keys.root}/**", lambda s: guest_heard.append(s.payload.to_bytes()))]
        answers = [world.declare_queryable(keys.obstacles, lambda q: q.reply(keys.obstacles, b"world")),
                   guest.declare_queryable(keys.obstacles, lambda q: q.reply(keys.obstacles, b"guest")),
                   agent.declare_queryable(keys.obstacles, lambda q: q.reply(keys.obstacles, b"agent"))]
        probe(world, keys.control, lambda: any(p == b"probe" for _, p in heard))
        for name, s in (("agent", agent), ("world", world), ("guest", guest)):
            s.put(keys.pose((0, 0), 5), name.encode())
            s.put(keys.prey, name.encode())
        # each rightful sender's last word, sent after its other puts: once both are in, so is the rest
        agent.put(keys.stats(5), b"end")
        world.put(keys.control, b"end")
        assert until(lambda: sum(p == b"end" for _, p in heard) == 2, 20.0)
        until(lambda: guest_heard.count(b"end") == 2, 1.0)  # only without access control can it hear them
        replies = sorted(r.ok.payload.to_bytes().decode() for r in listener.get(
            keys.obstacles, target=zenoh.QueryTarget.ALL, consolidation=zenoh.ConsolidationMode.NONE, timeout=2.0)
                         if r.ok is not None)
        del subs, answers
    words = {b"probe", b"end"}
    return {"heard": sorted((k.rsplit("/", 1)[-1], p.decode()) for k, p in heard if p not in words),
            "guest_heard": sorted(p.decode() for p in guest_heard if p not in words), "obstacle_answers": replies}


def test_rights_follow_the_certificate(certs):
    with processes() as kids:
        secured = exchange(certs, start_secure_router(kids, certs))
        open_ = exchange(certs, start_secure_router(kids, certs, acl=False))
    # with access control: each key has exactly its one rightful publisher, and the guest hears nothing
    assert secured["heard"] == [("5", "agent"), ("prey", "world")]
    assert secured["obstacle_answers"] == ["world"]
    assert secured["guest_heard"] == ["guest", "guest"]  # its own puts, delivered inside its session
    # the same sessions without access control: everyone gets through (so the check above can fail)
    assert open_["heard"] == sorted([("5", "agent"), ("5", "world"), ("5", "guest"),
                                     ("prey", "agent"), ("prey", "world"), ("prey", "guest")])
    assert open_["obstacle_answers"] == ["agent", "guest", "world"]
    assert open_["guest_heard"] == sorted(["agent", "world", "guest"] * 2)


def start_secure_mesh(kids, certs: Path, open_last: bool = False) -> list[str]:
    """Three routers meshed over mutual TLS (``zswarm run --routers 3 --secure``), the last one's
    access control off with ``open_last`` (a node's router widened)."""
    from zswarm.host.procs import start_mesh

    endpoints = [f"tls/127.0.0.1:{free_port()}" for _ in range(3)]
    start_mesh(kids, endpoints[:2], extra=["--config", str(certs / "router.json5")])
    config = certs / "router.json5"
    if open_last:
        conf = json.loads(config.read_text())
        conf["access_control"]["enabled"] = False
        config = certs / "router-open.json5"
        config.write_text(json.dumps(conf))
    start_mesh(kids, endpoints[2:], join=endpoints[0], extra=["--config", str(config)])
    return endpoints


@pytest.mark.parametrize("open_last", [False, True], ids=["every router checks", "one router widened"])
def test_a_guest_on_any_router_of_a_mesh_reaches_nobody(certs, open_last):
    """A multi-router secure run: the listener and the world on router 0, an agent on router 1, a
    guest (a valid certificate, no rights) on router 2. The guest gets no pose, prey or answer to
    anyone; with router 2's access control off it does (so the check can fail)."""
    with processes() as kids:
        e = start_secure_mesh(kids, certs, open_last)
        got = exchange(certs, e[0], agent_at=e[1], guest_at=e[2])
    if not open_last:
        assert got["heard"] == [("5", "agent"), ("prey", "world")]
        assert got["obstacle_answers"] == ["world"]
    else:
        assert ("5", "guest") in got["heard"] and ("prey", "guest") in got["heard"]
        assert "guest" in got["obstacle_answers"]


def test_no_certificate_or_a_foreign_ca_cannot_connect(certs, tmp_path):
    foreign = tmp_path / "foreign"
    write_secure_dir(foreign, names=("router", "world", "agent"))
    with processes() as kids:
        endpoint = start_secure_router(kids, certs)
        with session(certs, "agent", endpoint):  # the real thing connects
            pass
        no_cert = zenoh_config("client", [endpoint])
        no_cert.insert_json5("transport/link/tls", json.dumps({"root_ca_certificate": str(certs / "ca.pem")}))
        for conf in (no_cert, zenoh_config(None, [endpoint], (), foreign / "agent.json5")):
            with pytest.raises(UsageError, match="cannot open a zenoh session"):
                open_session(conf, what="intruder")


def test_an_agent_can_only_speak_for_itself(per_agent):
    keys, keys3 = Keys(RUN, 1.0), Keys(RUN, 1.0, dims=3)
    heard, alive, members = [], [], []
    with processes() as kids:
        endpoint = start_secure_router(kids, per_agent)
        with (session(per_agent, "world", endpoint) as world, session(per_agent, "agent-1", endpoint) as one,
              session(per_agent, "agent", endpoint) as shared):
            sub = world.declare_subscriber(f"{keys.root}/**", lambda s: heard.append(str(s.key_expr)))
            watch = world.liveliness().declare_subscriber(keys.all_alive, lambda s: alive.append(str(s.key_expr)) if s.kind == zenoh.SampleKind.PUT else None)
            cells = world.liveliness().declare_subscriber(keys.all_members, lambda s: members.append(str(s.key_expr)) if s.kind == zenoh.SampleKind.PUT else None)
            probe(world, keys.control, lambda: keys.control in heard)
            heard.clear()
            tokens = [one.liveliness().declare_token(keys.alive(2)), one.liveliness().declare_token(keys.alive(1)),
                      one.liveliness().declare_token(keys.member((-3, 4), 2)),
                      one.liveliness().declare_token(keys.member((-3, 4), 1)),
                      one.liveliness().declare_token(keys3.member((-3, 4, 1), 1))]
            for who, s in (("shared", shared), ("one", one)):
                for agent in (2, 1):
                    s.put(keys.pose((-3, 4), agent), who.encode())
                    s.put(keys.pose((-3, 4, 1), agent), who.encode())  # a 3-D run's voxel key
                    s.put(keys.stats(agent), who.encode())
            # agent-1's own last words came after everything forbidden it sent
            assert until(lambda: keys.stats(1) in heard and keys.alive(1) in alive and len(members) >= 2, 20.0)
            until(lambda: False, 0.3)  # and the shared identity's, sent before them, had as long
            del sub, watch, tokens, cells
    # agent-1's own pose, stats and token got through; nothing it said for agent 2, and nothing from
    # the shared identity (which has no rights once agents have their own)
    assert sorted(heard) == [keys.pose((-3, 4), 1), keys.pose((-3, 4, 1), 1), keys.stats(1)]
    assert alive == [keys.alive(1)]
    assert sorted(members) == sorted([keys.member((-3, 4), 1), keys3.member((-3, 4, 1), 1)])  # its cell tokens


def test_secure_swarm_never_sees_an_intruder(per_agent, tmp_path):
    """A full run over TLS + access control (an identity per agent) while a guest (valid
    certificate, no rights) announces agent 7 and publishes plausible poses for it (with lockstep step
    numbers), a fake prey and a fake tick into every cell of the swarm, from the moment the swarm is
    under way (its 6 agents alive and the world's ticks heard) until after its end. The run is lockstep,
    so however loaded the machine, anything forged that took effect would part it from the reference."""
    port = free_port()
    endpoint = f"tls/127.0.0.1:{port}"
    record = tmp_path / "secure.rrd"
    launch = subprocess.Popen([sys.executable, str(ROOT / "launch.py"), "--secure", str(per_agent), "--listen", endpoint,
                               "--run", RUN, "--agents", "6", "--duration", "12", "--clock", "lockstep", "--record", str(record),
                               "--quiet"],
                              cwd=ROOT, stdout=(said := Spool()), stderr=subprocess.STDOUT)
    try:
        keys = Keys(RUN, 1.0)
        cells = [(cx, cy) for cx in range(-6, 0) for cy in range(-3, 3)]
        sent = 0
        alive: set[int] = set()
        prey: list[bytes] = []
        # the launcher judges the design before it starts the router: seconds on a loaded machine
        assert wait_for_port("127.0.0.1", port, 90.0, Child("launch", launch)), said.text()
        with session(per_agent, "world", endpoint) as observer:  # rights to listen: when is the swarm up?
            subs = [observer.liveliness().declare_subscriber(keys.all_alive, lambda s: (
                        alive.discard if s.kind == zenoh.SampleKind.DELETE else alive.add)(Keys.agent_of(str(s.key_expr))),
                        history=True),
                    observer.declare_subscriber(keys.tick, lambda s: prey.append(b""))]
            assert until(lambda: len(alive) >= 6 and prey, 90), (sorted(alive), len(prey))
            for sub in subs:
                sub.undeclare()
        with session(per_agent, "guest", endpoint) as guest:
            token = guest.liveliness().declare_token(keys.alive(7))
            for i in range(300):
                for cx, cy in cells:
                    guest.put(keys.pose((cx, cy), 7),
                              msg.encode(msg.Pose(7, i + 1, time.time(), i, cx + 0.5, cy + 0.5, 0.0, 0.0)))
                    sent += 1
                guest.put(keys.prey, msg.encode(msg.Prey(i, time.time(), i, -4.0, 0.0)))
                guest.put(keys.tick, msg.encode(msg.Tick(i, time.time(), -4.0, 0.0)))
                time.sleep(0.02)
            token.undeclare()
        launch.wait(timeout=120)
        err = said.text()
    finally:
        if launch.poll() is None:
            launch.kill()
            launch.wait()
    assert launch.returncode == 0, err
    s = load_summary(record.with_suffix(".json"))
    assert sent > 10000
    assert s["agents_reporting"] == 6 and s["collisions"] == 0, err[-3000:]
    heard = {int(k): set(v) for k, v in s["heard"].items()}
    assert all(h - {i} for i, h in heard.items()), "the agents heard each other"
    assert not any(7 in h for h in heard.values()), heard
    assert s["messages_rejected"] == 0, s["rejected_by_reason"]  # nothing forged even arrived
    # and the swarm moved exactly as the centralized reference does: nothing forged took effect
    assert s["capture_time"] == s["reference"]["capture_time"], (s["capture_time"], s["reference"])
    assert abs(s["vs_reference"]["final_centroid_goal_distance"]) < 1e-6, s["vs_reference"]


def test_certs_command_writes_usable_configs_and_reuses_its_ca(tmp_path, cli):
    """``zswarm certs DIR`` twice: the second keeps the CA (an earlier copy of a certificate stays valid)
    and every key; ``--force`` makes a new CA; a CA without its key is one line, exit 2."""
    from cryptography import x509

    d = tmp_path / "pki"
    made = cli("-m", "zswarm", "certs", str(d), "--router", "tls/localhost:9", "--extra", "guest")
    assert made.returncode == 0, made.stderr
    for name in ("router", "world", "agent", "guest"):
        conf = json.loads((d / f"{name}.json5").read_text())
        tls = conf["transport"]["link"]["tls"]
        assert (d / tls["connect_certificate"]).is_file() and tls["enable_mtls"] is True
        assert not Path(tls["connect_certificate"]).is_absolute()  # the folder's own, wherever it is
        assert ("access_control" in conf) == (name == "router")
    assert json.loads((d / "world.json5").read_text())["connect"]["endpoints"] == ["tls/localhost:9"]
    ca, keys = (d / "ca.pem").read_bytes(), {p.name: p.read_bytes() for p in d.glob("*.key")}
    again = cli("-m", "zswarm", "certs", str(d), "--router", "tls/localhost:9")
    assert again.returncode == 0 and "reusing the CA" in again.stdout, again.stderr
    assert (d / "ca.pem").read_bytes() == ca and {p.name: p.read_bytes() for p in d.glob("*.key")} == keys
    issuer = x509.load_pem_x509_certificate(ca).subject
    assert x509.load_pem_x509_certificate((d / "world.pem").read_bytes()).issuer == issuer
    forced = cli("-m", "zswarm", "certs", str(d), "--force")
    assert forced.returncode == 0 and (d / "ca.pem").read_bytes() != ca, forced.stderr
    (d / "ca.key").unlink()
    keyless = cli("-m", "zswarm", "certs", str(d))
    assert keyless.returncode == 2 and "not its key" in keyless.stderr and "Traceback" not in keyless.stderr
    bad = cli("-m", "zswarm", "certs", str(tmp_path / "x"), "--router", "tcp/localhost:9")
    assert bad.returncode == 2 and "must be a tls/HOST:PORT" in bad.stderr


def test_launch_passes_full_zenoh_configs_through(certs, tmp_path):
    """--router-config / --config hand each process a whole Zenoh configuration: here TLS without
    access control (so one client certificate serves world and agents), beside the files it names by
    their folder's paths. Over a tls/ endpoint the run only works if every process got its file."""
    conf = json.loads((certs / "router.json5").read_text())
    conf["access_control"]["enabled"] = False
    router_conf = certs / "router-tls.json5"
    router_conf.write_text(json.dumps(conf))
    record = tmp_path / "pass.rrd"
    res = run_cli(str(ROOT / "launch.py"), "--router-config", str(router_conf), "--config", str(certs / "agent.json5"),
                  "--listen", f"tls/127.0.0.1:{free_port()}", "--agents", "3", "--duration", "4", "--run", "passthrough",
                  "--record", str(record), "--quiet", cwd=ROOT, timeout=120)
    assert res.returncode == 0, res.stderr
    s = load_summary(record.with_suffix(".json"))
    assert s["agents_reporting"] == 3 and s["steps"] > 50


def test_a_secure_run_over_three_routers_says_so_in_its_summary(tmp_path):
    """zswarm run --routers 3 --secure DIR (an empty DIR: the CA, one identity per agent and the
    routers' configs made there): the agents on every router reach the world, and the summary's
    security block says TLS and access control."""
    record = tmp_path / "mesh.rrd"
    res = run_cli(str(ROOT / "launch.py"), "--routers", "3", "--secure", str(tmp_path / "pki"), "--agents", "6",
                  "--duration", "6", "--run", "securemesh", "--record", str(record), cwd=tmp_path, timeout=180)
    assert res.returncode == 0, res.stderr[-3000:]
    assert "open run" not in res.stdout  # a secure run does not say it believes any peer
    s = load_summary(record.with_suffix(".json"))
    assert s["security"] == {"tls": True, "acl": True, "ray_auth": None}
    assert len(s["routers"]) == 3 and all(e.startswith("tls/") for e in s["routers"])
    assert len(set(s["agent_router"].values())) == 3  # agents on every router
    assert s["agents_reporting"] == 6 and s["collisions"] == 0 and s["cross_router_heard"] > 0


def test_launch_refuses_agents_without_an_identity(per_agent, cli):
    res = cli(str(ROOT / "launch.py"), "--secure", str(per_agent), "--agents", "8")
    assert res.returncode == 2 and "none to agent 6 and others" in res.stderr, res.stderr
    assert f"zswarm certs {per_agent} --force --agents 8" in res.stderr


class DirectLink:
    """A node of a cluster reached by plain calls instead of through Ray; what crosses is kept."""

    def __init__(self, node, address: str) -> None:
        self.node, self.label, self.info, self.crossed = node, "node1", {"address": address}, []

    def call(self, method: str, *args):
        out = getattr(self.node, method)(*args)
        self.crossed.append((method, args, out))
        return out


def test_a_cluster_nodes_identities_are_made_there_and_signed_by_the_drivers_ca(certs, tmp_path):
    """``--secure`` over other machines: the node makes its router's and its agents' keys, the driver's CA
    signs their public halves, and the node's router enforces the driver's access control. No private
    key crosses (what crosses is kept and searched), the node's folder is its user's alone, and it goes
    when the node stops."""
    import os
    import shutil

    from zswarm.cluster.node import NodeActor
    from zswarm.cluster.pki import NodeIdentities

    node = NodeActor("node1")
    link = DirectLink(node, "127.0.0.1")
    ids = NodeIdentities(certs)
    ids.make(link, ["router", "agent"])
    ids.make(link, ["agent"])  # held already: nothing crosses
    folder = Path(ids.folders["node1"])
    assert [m for m, _, _ in link.crossed] == ["identities", "install"]
    assert "PRIVATE KEY" not in repr(link.crossed) and "PUBLIC KEY" in repr(link.crossed)
    assert folder.stat().st_mode & 0o777 == 0o700 and (folder / "router.key").stat().st_mode & 0o777 == 0o600
    assert (folder / "router.key").read_bytes() != (certs / "router.key").read_bytes()  # its own key
    view = tmp_path / "view"  # the node's router and agent, the driver's world, and a guest
    view.mkdir()
    for name, where in (("router", folder), ("agent", folder), ("world", certs), ("guest", certs)):
        (view / f"{name}.json5").symlink_to(where / f"{name}.json5")
    try:
        with processes() as kids:
            got = exchange(view, start_router(kids, proto="tls", extra=["--config", str(view / "router.json5")]))
    finally:
        node.stop(1.0)
    assert got["heard"] == [("5", "agent"), ("prey", "world")] and got["obstacle_answers"] == ["world"]
    assert got["guest_heard"] == ["guest", "guest"]
    assert not folder.exists()
    bare = tmp_path / "no-ca-key"
    shutil.copytree(certs, bare)
    os.unlink(bare / "ca.key")
    with pytest.raises(UsageError, match="has no ca.key"):
        NodeIdentities(bare).make(DirectLink(NodeActor("node2"), "127.0.0.1"), ["router"])


def test_a_secure_directory_without_its_cas_key_is_refused_for_other_machines(certs, tmp_path):
    """Over other machines the CA signs each node's keys: a directory without ``ca.key`` is refused in one
    line before Ray is reached (the address answers nothing)."""
    import shutil

    bare = tmp_path / "pki"
    shutil.copytree(certs, bare)
    (bare / "ca.key").unlink()
    res = run_cli(str(ROOT / "launch.py"), "--cluster", "127.0.0.1:1", "--secure", str(bare), timeout=60, cwd=tmp_path)
    assert res.returncode == 2 and res.stderr.strip().count("\n") == 0, res.stderr
    assert "has no ca.key" in res.stderr, res.stderr


def test_a_router_whose_certificate_the_mesh_refuses_is_refused_at_start(certs, tmp_path):
    """A node's router joining the first router of a --secure mesh: with a certificate of the run's CA it
    joins; with one of another CA it says so and exits 2 within its --connect-timeout, and the node's
    start refuses it in one line (instead of a mesh split in two without a word)."""
    from zswarm.cluster.node import NodeActor
    from zswarm.net.router import JOIN_FAILED

    foreign = tmp_path / "foreign"
    write_secure_dir(foreign, names=("router",))
    with processes() as kids:
        first = start_secure_router(kids, certs)
        good, bad = NodeActor("node1"), NodeActor("node2")
        try:
            assert good.start_router("127.0.0.1", first, ["--config", str(certs / "router.json5")], "tls")
            t = time.monotonic()
            with pytest.raises(RuntimeError, match="could not join .* not from one CA") as refused:
                bad.start_router("127.0.0.1", first, ["--config", str(foreign / "router.json5"),
                                                       "--connect-timeout", "2"], "tls")
            assert time.monotonic() - t < 20.0 and "\n" not in str(refused.value)
            assert bad.kids.named("router")[-1].proc.wait(timeout=10) == JOIN_FAILED
        finally:
            good.stop(1.0)
            bad.stop(1.0)


def test_certs_made_in_a_repository_stay_out_of_it_and_private(tmp_path):
    """``zswarm certs pki`` in a clone: ``git status`` shows nothing under pki/ (a ``.gitignore`` in it
    ignores everything), the folder is its owner's alone and every private key is mode 600."""
    repo = tmp_path / "clone"
    repo.mkdir()
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    res = run_cli("-m", "zswarm", "certs", "pki", cwd=repo, timeout=60)
    assert res.returncode == 0, res.stderr
    status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=all"], cwd=repo,
                            capture_output=True, text=True, check=True).stdout
    assert status == "", status
    keys = sorted((repo / "pki").glob("*.key"))
    assert {k.name for k in keys} >= {"ca.key", "router.key", "world.key"}
    assert all(k.stat().st_mode & 0o777 == 0o600 for k in keys), [(k.name, oct(k.stat().st_mode)) for k in keys]
    assert (repo / "pki").stat().st_mode & 0o777 == 0o700


def test_each_router_of_a_mesh_has_its_own_identity_and_one_left_out_is_shut_out(certs, tmp_path):
    """--routers 3 --secure (and a cluster's nodes): routers ``router``, ``router-1``, ``router-2``, each
    with its own key and certificate (made from the directory's CA), each named in the access control.
    A router left out of the first router's list is shut out: an agent on it reaches no one there, where
    it does while the router is listed."""
    import shutil

    from cryptography import x509

    from zswarm.host.procs import start_mesh
    from zswarm.net.security import router_configs, with_routers

    d = tmp_path / "pki"
    shutil.copytree(certs, d)
    configs = router_configs(d, 3)
    assert [p.name for p in configs] == ["router.json5", "router-1.json5", "router-2.json5"]
    names = [x509.load_pem_x509_certificate((d / f"{n}.pem").read_bytes()).subject.rfc4514_string()
             for n in ("router", "router-1", "router-2")]
    assert names == ["CN=router", "CN=router-1", "CN=router-2"]
    assert len({(d / f"{n}.key").read_bytes() for n in ("router", "router-1", "router-2")}) == 3
    acl = json.loads(configs[0].read_text())["access_control"]
    assert next(s for s in acl["subjects"] if s["id"] == "routers")["cert_common_names"] == [
        n[3:] for n in names] and all(
        json.loads(c.read_text())["access_control"] == acl for c in configs)
    keys = Keys(RUN, 1.0)
    for listed in (True, False):
        if not listed:  # router 0 no longer names router-2
            conf = json.loads(configs[0].read_text())
            conf["access_control"] = with_routers(acl, ["router", "router-1"])
            configs[0].write_text(json.dumps(conf))
        heard: list[bytes] = []
        with processes() as kids:
            endpoints = [f"tls/127.0.0.1:{free_port()}" for _ in range(3)]
            start_mesh(kids, endpoints, each=[["--config", str(c)] for c in configs])
            with (session(d, "agent", endpoints[0]) as listener, session(d, "world", endpoints[0]) as world,
                  session(d, "agent", endpoints[2]) as agent):
                sub = listener.declare_subscriber(f"{keys.root}/**", lambda s: heard.append(s.payload.to_bytes()))
                probe(world, keys.control, lambda: b"probe" in heard)
                deadline = time.monotonic() + (10.0 if listed else 3.0)
                while b"agent" not in heard and time.monotonic() < deadline:
                    agent.put(keys.pose((0, 0), 5), b"agent")
                    time.sleep(0.1)
                sub.undeclare()
        assert (b"agent" in heard) is listed, (listed, heard[-5:])
