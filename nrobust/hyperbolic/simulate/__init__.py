"""The PDE itself with a delayed boundary control: :func:`simulate` and its registry of schemes.

``base``: the result contract (:class:`SimulationResult`) and the scheme interface
(:class:`Scheme`); ``registry``: :data:`SCHEMES` and :func:`simulate`; the schemes:
``normal_form`` (the paper's plant along its characteristics, and a general plant with a
constant ``lam/mu`` through its normal form; the marching in ``characteristics``),
``general`` (a general plant on time-of-flight grids) and ``nplusm`` (``n + m`` systems).
"""

from .base import Scheme, SimulationResult
from .general import GeneralSimulation, simulate_general
from .normal_form import DEFAULT_CELLS, MAX_UPDATES, Simulation, simulate_runs, v_nodes
from .nplusm import NPlusMSimulation, simulate_nplusm
from .registry import SCHEMES, simulate

__all__ = [
    "DEFAULT_CELLS",
    "GeneralSimulation",
    "MAX_UPDATES",
    "NPlusMSimulation",
    "SCHEMES",
    "Scheme",
    "Simulation",
    "SimulationResult",
    "simulate",
    "simulate_general",
    "simulate_nplusm",
    "simulate_runs",
    "v_nodes",
]
