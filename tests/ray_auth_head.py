"""Run inside a loopback-only network namespace by tests/test_cluster.py: a Ray head started as
docs/cluster.md says (``ray start --head`` with token authentication, or without), then ``zswarm run
--cluster ADDRESS`` against it with no token, a wrong token and the right one; prints one JSON object of
what each did (exit code, seconds, last line of stderr)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PORT = "6391"


def main() -> int:
    secured = sys.argv[1] == "token"
    out_dir = Path(sys.argv[2])
    tmp = Path(tempfile.mkdtemp(prefix="zs-auth-", dir="/tmp"))
    home = tmp / "home"
    home.mkdir()
    (home / "ray_bootstrap_config.yaml").write_text("provider: {type: local}\n")
    token = tmp / "token"
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_AUTH")}
    env.update(HOME=str(home), RAY_TMPDIR=str(tmp / "ray"), RAY_USAGE_STATS_ENABLED="0",
               RAY_USAGE_STATS_PROMPT_ENABLED="0", RAY_USAGE_STATS_REPORT_URL="http://127.0.0.1:9/")
    head_env = dict(env)
    if secured:  # the recipe of docs/cluster.md: one token, made once, the same file on every node
        token.write_text(subprocess.run([sys.executable, "-c", "import secrets; print(secrets.token_hex(32))"],
                                        capture_output=True, text=True).stdout.strip())
        token.chmod(0o600)
        head_env.update(RAY_AUTH_MODE="token", RAY_AUTH_TOKEN_PATH=str(token))
    ray = [sys.executable, "-m", "ray.scripts.scripts"]
    started = subprocess.run([*ray, "start", "--head", "--port", PORT, "--node-ip-address", "127.0.0.1",
                              "--num-cpus", "2", "--include-dashboard", "false", "--object-store-memory",
                              str(80 * 2**20)], env=head_env, capture_output=True, text=True)
    results = {"head": started.returncode}
    # what a driver takes before it asks the head anything (the interpreter, zswarm's command line, Ray's
    # import), here and now: on a loaded machine it is seconds, which the 5 s of the probe do not include
    t = time.monotonic()
    subprocess.run([sys.executable, "-c", "import ray, zswarm.cli.main"], env=env, capture_output=True, cwd=out_dir)
    results["startup"] = time.monotonic() - t
    wrong = tmp / "wrong"
    wrong.write_text("0" * 64)
    cases = {"none": {}, "wrong": {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(wrong)},
             "right": {"RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token)}} if secured else \
        {"open": {}, "open-ok": {}}
    try:
        for name, extra in cases.items():
            # an open head: refused, secure run or not, unless the user says --cluster-insecure-ok
            flags = {"open": ["--secure", str(out_dir / "pki")],
                     "open-ok": ["--secure", str(out_dir / "pki"), "--cluster-insecure-ok"]}.get(name, [])
            t = time.monotonic()
            run = subprocess.run([sys.executable, "-m", "zswarm", "run", "--cluster", f"127.0.0.1:{PORT}",
                                  "--agents", "3", *flags, "--duration", "3",
                                  "--record", str(out_dir / f"{name}.rrd"), "--quiet"],
                                 env={**env, **extra}, capture_output=True, text=True, timeout=180, cwd=out_dir)
            err = [line for line in run.stderr.splitlines() if line.strip()]
            results[name] = {"rc": run.returncode, "seconds": time.monotonic() - t, "stderr": err[-40:]}
    finally:  # this head's processes only (``ray stop`` would stop every Ray node of the machine)
        from ray_procs import kill_all, node_processes

        kill_all(node_processes(tmp))
    print(json.dumps(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
