"""nrobust: delay-robustness analysis of boundary-controlled hyperbolic PDEs.

The reference is Auriol, Aarsnes, Martin and Di Meglio, "Delay-robust control design
for two heterodirectional linear coupled hyperbolic PDEs": a 2x2 hyperbolic system is
mapped to a neutral equation with distributed delay, whose characteristic
quasi-polynomial decides stability with and without a delay in the loop.

The public names are listed in ``nrobust/__init__.pyi`` with their homes and load on first
use (PEP 562), so ``import nrobust`` is fast and loads neither the plants nor matplotlib.
The layers and the data flow are in ``docs/architecture.md``.
"""

import lazy_loader as _lazy

from . import _moved
from ._version import __version__ as __version__

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
_moved.install()
