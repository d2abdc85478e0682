"""Delay margins of loops ``F(s; delta) = A(s) + B(s) e^{-delta s}``: the loop on the
imaginary axis and its frequency bound (``axis``), the certified search of the zeros of
``|A(i w)|^2 - |B(i w)|^2`` (``search``), the crossings with their delays and directions
(``crossing``), the count of unstable zeros (``count``), the margin and its stability windows
(``margin``), the same proven in ball arithmetic (``proven``), the crossings of matrix
loops ``det(M_0 + e^{-delta s} M_1)`` (``matrix``), and for an affine gain family
``A + (B_0 + K R) e^{-delta s}`` the exact ends of the admissible gain intervals (``gain``)
and the verdict at one gain (``admissible``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
