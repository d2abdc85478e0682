"""Linear time-invariant systems with delays: transfer functions with point and
distributed delays (``transfer``) and state-space time-delay systems (``statespace``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
