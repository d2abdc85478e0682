"""The plants: the paper's 2x2 system in normal form (``hyperbolic2x2``), general 2x2
plants and their normal form (``general``), physical front ends (``frontends``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
