import sys

from zswarm.cli.main import main

sys.exit(main())
