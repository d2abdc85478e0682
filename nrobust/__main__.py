"""``python -m nrobust``: the same command line as ``nrobust``.

Importing the module (as documentation tools that walk the package do) runs nothing.
"""

from .cli import run

if __name__ == "__main__":
    run()
