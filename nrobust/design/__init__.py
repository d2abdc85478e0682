"""Controller design with certificates, on parametrised loops ``A(s; p) + B(s; p) e^{-delta s}``.

``gain``: one gain of an affine loop (``U_BS2(K)``'s, eq. (60)), or one parameter of a loop
affine in it in both factors (:class:`AffineLoop`: the filtered law's zero or pole), exactly: the gain with the
largest delay margin (:func:`best_margin`: a kink, a pair birth, an interior maximum or an
end, solved from its equation) or the largest decay rate under a required margin
(:func:`best_decay_rate`), each design certified by :mod:`nrobust.margins`; either under a
window of delays on which the loop must be stable (``delays``, :func:`window_stability`).

``local``: several parameters of any loop family, a local nonsmooth optimisation of the decay
rate (under a required margin) or of the margin (:func:`optimize_loop`: BFGS with a weak Wolfe
line search, then a pattern search over axes and diagonals; every iterate feasible; the design certified).
``pareto``: the best decay rate under each of a list of required margins
(:func:`pareto_front`).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
