"""The PDE layer: boundary-controlled hyperbolic systems on top of the core.

``plants/``: the paper's 2x2 plant (:class:`Hyperbolic2x2`, :class:`TransportSystem`), general
2x2 plants (varying speeds, diagonal terms, any length) and their normal form, physical
front ends (Saint-Venant, ARZ traffic, characteristic forms) and the state feedback a
controller applies (:class:`FeedbackLaw`); ``kernels/``: the backstepping kernels ``K`` and
inverse kernels ``L`` (constant and varying speeds); ``loops/``: from a plant and a
controller to the loop ``F = A + B e^{-delta s}`` (the controllers, any state feedback, the
delay form of eq. (39), the kernel-free Laplace route, the transfer functions);
``analyses/``: delay margins of a plant with a controller, admissible gains, charts,
trade-offs and the Rouché bound; ``nplusm/``: ``n + m`` systems (Hu et al. 2016);
``simulate/``: the PDE itself with a delayed boundary control, one :func:`~nrobust.hyperbolic.simulate.simulate` over a
registry of schemes.
Names load on first use (PEP 562), from ``__init__.pyi``.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
