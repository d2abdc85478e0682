"""``python -m nrobust``: the same command line as ``nrobust``.

Importing the module (as documentation tools that walk the package do) runs nothing.
"""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
