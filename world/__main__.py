import os
import sys

from zswarm.process import one_blas_thread

one_blas_thread(os.environ)  # before numpy is imported: its pool would spin on every core

from world.main import main  # noqa: E402

sys.exit(main())
