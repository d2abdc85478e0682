"""``python -m nrobust``: the same command line as ``nrobust``."""

import sys

from .cli import main

sys.exit(main())
