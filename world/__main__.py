import sys

from world.main import main

sys.exit(main())
