# The public names of nrobust.hyperbolic.plants, loaded on first use (nrobust/hyperbolic/plants/__init__.py).
from .frontends import (
    ARZ as ARZ,
    GRAVITY as GRAVITY,
    SaintVenant as SaintVenant,
    arz as arz,
    from_riemann as from_riemann,
    saint_venant as saint_venant,
)
from .general import (
    Coefficient as Coefficient,
    GeneralHyperbolic2x2 as GeneralHyperbolic2x2,
    NormalForm as NormalForm,
    as_general as as_general,
)
from .hyperbolic2x2 import (
    Coupling as Coupling,
    Hyperbolic2x2 as Hyperbolic2x2,
    TransportSystem as TransportSystem,
)
from .law import (
    FeedbackLaw as FeedbackLaw,
    feedback_gain as feedback_gain,
)
