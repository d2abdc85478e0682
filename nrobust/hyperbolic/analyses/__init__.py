"""Analyses of a plant with a controller: delay margins (``margin``), admissible gains
(``kregion``, on the core's gain engine :mod:`nrobust.margins.gain`), charts over two
parameters (``charts``), the decay-rate/margin trade-off (``tradeoff``), the Rouché delay
bound (``rouche``), the design of ``U_BS2(K)`` (``design``) and of the filtered law over its
gain, zero and pole (``filter_design``), of a general state feedback over its gains
(``state_design``), of the collocated observer's own reflection (``observer_design``), the accuracy of an output
feedback's margin (``observer_accuracy``), and
the robustness to a mismatch of the transport speeds (``mismatch``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
