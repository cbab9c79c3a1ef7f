"""``python launch.py ...`` is ``zswarm run ...`` (and ``python launch.py sweep ...`` is ``zswarm sweep``)."""

import sys

from zswarm.cli.main import launch_main

if __name__ == "__main__":
    sys.exit(launch_main())
