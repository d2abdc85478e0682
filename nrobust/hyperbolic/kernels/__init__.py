"""Backstepping kernels of 2x2 plants: constant speeds on the paper's triangle
(``constant``) and varying speeds (``varying``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
