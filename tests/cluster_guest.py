"""Run inside a loopback-only network namespace by tests/test_cluster.py: ``zswarm run --cluster local:2
--secure DIR``, and, while it runs, a guest (a certificate of the run's CA, no rights) on the second
node's router that publishes agent 1's pose far away, the prey far away and a final tick. Prints the
run's exit code and the guest's count of puts as one JSON object."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import zenoh


def main() -> int:
    out = Path(sys.argv[1])
    pki = out / "pki"
    from zswarm.net.security import write_secure_dir

    write_secure_dir(pki, names=("router", "world", "agent", "guest"), agents=8)  # as zswarm certs makes it
    run = subprocess.Popen([sys.executable, "-m", "zswarm", "run", "--cluster", "local:2", "--secure", str(pki),
                            "--agents", "8", "--duration", "20", "--run", "guested", "--record", str(out / "g.rrd")],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=out)
    routers, puts = [], 0
    deadline = time.monotonic() + 150
    for line in run.stdout:
        routers += re.findall(r"router (tls/[\d.]+:\d+)", line)
        if "world: started" in line or time.monotonic() > deadline:
            break
    if len(routers) >= 2:
        from zswarm.net import messages as msg
        from zswarm.net.config import zenoh_config
        from zswarm.net.keys import Keys

        keys = Keys("guested", 1.0)
        with zenoh.open(zenoh_config(None, [routers[1]], (), pki / "guest.json5")) as guest:
            end = time.monotonic() + 5.0
            while time.monotonic() < end:
                guest.put(keys.pose(keys.cell(500.0, 500.0), 1),
                          msg.encode(msg.Pose(1, 10**6 + puts, time.time(), -1, 500.0, 500.0, 0.0, 0.0)))
                guest.put(keys.prey, msg.encode(msg.Prey(10**6 + puts, time.time(), -1, 500.0, 500.0)))
                guest.put(keys.tick, msg.encode(msg.Tick(10**6, time.time(), 500.0, 500.0, final=True)))
                puts += 3
                time.sleep(0.05)
    rest = run.communicate(timeout=200)[0]
    print(json.dumps({"rc": run.returncode, "routers": routers, "puts": puts, "tail": rest.splitlines()[-3:]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
