# The public names of nrobust.hyperbolic.simulate, loaded on first use (nrobust/hyperbolic/simulate/__init__.py).
from .base import (
    Scheme as Scheme,
    SimulationResult as SimulationResult,
)
from .general import (
    GeneralSimulation as GeneralSimulation,
    simulate_general as simulate_general,
)
from .normal_form import (
    DEFAULT_CELLS as DEFAULT_CELLS,
    MAX_UPDATES as MAX_UPDATES,
    Simulation as Simulation,
    simulate_runs as simulate_runs,
    v_nodes as v_nodes,
)
from .nplusm import (
    NPlusMSimulation as NPlusMSimulation,
    simulate_nplusm as simulate_nplusm,
)
from .registry import (
    SCHEMES as SCHEMES,
    simulate as simulate,
)
