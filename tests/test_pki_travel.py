"""A ``--secure`` folder that travels: moved or copied, it works with its own files and nothing else; a
missing, broken, mismatched or foreign file is refused in one line before anything starts; another
machine gets a bundle without the CA's key; ``zswarm certs`` says what is wrong with its input in one line."""

from __future__ import annotations

import json
import shutil

from conftest import ROOT


def launch(cli, folder, pki, record: str):
    return cli(str(ROOT / "launch.py"), "--secure", str(pki), "--agents", "3", "--duration", "3", "--run", record,
               "--record", str(folder / f"{record}.rrd"), "--quiet", cwd=folder, timeout=120)


def refused(res, *needles: str) -> str:
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1, res.stderr[-2000:]
    assert all(n in lines[0] for n in needles), lines[0]
    return lines[0]


def test_a_moved_folder_runs_and_a_copy_uses_its_own_files(tmp_path, cli):
    made = cli("-m", "zswarm", "certs", str(tmp_path / "pA"))
    assert made.returncode == 0, made.stderr
    (tmp_path / "pA").rename(tmp_path / "pB")  # mv pA pB
    moved = launch(cli, tmp_path, tmp_path / "pB", "moved")
    assert moved.returncode == 0, moved.stderr[-2000:]
    assert json.loads((tmp_path / "moved.json").read_text())["security"]["tls"] is True

    def copy(name: str) -> object:
        shutil.copytree(tmp_path / "pB", tmp_path / name)
        return tmp_path / name

    junk = copy("junk")  # a copy whose router key is junk: refused, not run on pB's key
    (junk / "router.key").write_text("junk\n")
    refused(launch(cli, tmp_path, junk, "junk"), f"{junk / 'router.key'} is not a PEM private key")
    swapped = copy("swapped")  # a key that is another identity's
    shutil.copyfile(swapped / "agent.key", swapped / "world.key")
    refused(launch(cli, tmp_path, swapped, "swapped"), "world.key is not the key of", "world.pem")
    missing = copy("missing")
    (missing / "agent.pem").unlink()
    refused(launch(cli, tmp_path, missing, "missing"), f"names {missing / 'agent.pem'}", "No such file")
    foreign = copy("foreign")  # certificates of another CA
    cli("-m", "zswarm", "certs", str(tmp_path / "other"))
    shutil.copyfile(tmp_path / "other" / "ca.pem", foreign / "ca.pem")
    refused(launch(cli, tmp_path, foreign, "foreign"), "is not signed by the CA")
    old = copy("old")  # a config of an older zswarm, naming files by absolute path: elsewhere
    conf = json.loads((old / "world.json5").read_text())
    conf["transport"]["link"]["tls"]["connect_private_key"] = str(tmp_path / "pB" / "world.key")
    (old / "world.json5").write_text(json.dumps(conf))
    refused(launch(cli, tmp_path, old, "old"), "outside", f"zswarm certs {old}")
    assert not [p for p in tmp_path.glob("*.rrd") if p.stem != "moved"]  # nothing started


def test_certs_says_what_is_wrong_in_one_line(tmp_path, cli):
    pki = tmp_path / "pki"
    assert cli("-m", "zswarm", "certs", str(pki)).returncode == 0
    (pki / "ca.pem").write_text("-----BEGIN CERTIFICATE-----\nnot one\n")
    line = refused(cli("-m", "zswarm", "certs", str(pki)), f"{pki / 'ca.pem'} is not a readable PEM certificate")
    assert line.startswith("zswarm certs: error: ")
    bad = cli("-m", "zswarm", "certs", str(tmp_path / "new"), "--hosts", "not a host!!")
    refused(bad, "'not a host!!' is neither an IP address nor a host name")
    assert not (tmp_path / "new").exists()
    good = cli("-m", "zswarm", "certs", str(tmp_path / "ok"), "--hosts", "10.0.0.1,robot-1.lab,localhost")
    assert good.returncode == 0, good.stderr


def test_a_bundle_holds_what_another_machine_needs_and_never_the_cas_key(tmp_path, cli):
    pki, out = tmp_path / "pki", tmp_path / "elsewhere" / "b"
    assert cli("-m", "zswarm", "certs", str(pki), "--agents", "3").returncode == 0
    res = cli("-m", "zswarm", "certs", str(pki), "--bundle", str(out), "--names", "world,agent-*")
    assert res.returncode == 0 and "no ca.key" in res.stdout, res.stderr
    assert sorted(p.name for p in out.iterdir() if p.suffix != ".gitignore" and p.name != ".gitignore") == sorted(
        ["ca.pem"] + [f"{n}{ext}" for n in ("world", "agent-0", "agent-1", "agent-2") for ext in (".key", ".pem", ".json5")])
    assert (out / "world.key").stat().st_mode & 0o077 == 0  # a private key stays private
    refused(cli("-m", "zswarm", "certs", str(pki), "--bundle", str(tmp_path / "x"), "--names", "nobody"),
            "matches no identity")
    refused(cli("-m", "zswarm", "certs", str(pki), "--bundle", str(tmp_path / "x")), "--bundle needs --names")
    # a machine that runs the router and the world from a bundle without them: one line, before anything starts
    agents_only = tmp_path / "agents-only"
    cli("-m", "zswarm", "certs", str(pki), "--bundle", str(agents_only), "--names", "agent-*")
    refused(launch(cli, tmp_path, agents_only, "nobundle"), "has no router.json5", "--bundle")
