"""The plants: the paper's 2x2 system in normal form (``hyperbolic2x2``), general 2x2
plants and their normal form (``general``), physical front ends (``frontends``).
"""

from .frontends import ARZ, GRAVITY, SaintVenant, arz, from_riemann, saint_venant
from .general import Coefficient, GeneralHyperbolic2x2, NormalForm, as_general
from .hyperbolic2x2 import Coupling, Hyperbolic2x2, TransportSystem
from .law import FeedbackLaw, feedback_gain

__all__ = [
    "ARZ",
    "Coefficient",
    "Coupling",
    "FeedbackLaw",
    "GRAVITY",
    "GeneralHyperbolic2x2",
    "Hyperbolic2x2",
    "NormalForm",
    "SaintVenant",
    "TransportSystem",
    "arz",
    "as_general",
    "feedback_gain",
    "from_riemann",
    "saint_venant",
]
