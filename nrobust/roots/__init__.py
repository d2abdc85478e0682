"""Certified roots of quasi-polynomials: counts (``winding``), the search for roots
(``search``) and the roots with their proofs (``finder``), the spectral abscissa
(``abscissa``); ``_common`` holds the rounding model, the work budget and the argument checks.
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
