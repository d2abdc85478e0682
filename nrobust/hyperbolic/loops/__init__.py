"""From a plant and a controller to the loop ``F(s; delta) = A(s) + B(s) e^{-delta s}``:
the controllers (``controllers``), any state feedback (``feedback``), output feedback from the
unactuated boundary (``output_feedback``, its observer's term proven in ``observer_proof``) and from the
actuated one (``collocated``), the delay form of
eq. (39) (``delay_form``; ``varying_form`` for varying speeds), the kernel-free Laplace
route (``laplace``) and the loops' transfer functions (``transfer``).
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
