"""Figures of nrobust (the application layer): each plot draws what an analysis computed.

Names load on first use (PEP 562), so importing nrobust never loads matplotlib.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
