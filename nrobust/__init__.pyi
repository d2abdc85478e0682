# The public names of nrobust and where they live. nrobust/__init__.py loads each on first
# use (lazy_loader reads this file), so `import nrobust` loads no numerical module.
from . import plots as plots
from ._version import __version__ as __version__
