"""The PDE itself with a delayed boundary control: :func:`simulate` and its registry of schemes.

``base``: the result contract (:class:`SimulationResult`) and the scheme interface
(:class:`Scheme`); ``registry``: :data:`SCHEMES` and :func:`simulate`; the schemes:
``normal_form`` (the paper's plant along its characteristics, and a general plant with a
constant ``lam/mu`` through its normal form; the marching in ``characteristics``),
``general`` (a general plant on time-of-flight grids) and ``nplusm`` (``n + m`` systems).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
