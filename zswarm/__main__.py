import sys

from zswarm.cli import main

sys.exit(main())
