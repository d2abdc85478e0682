"""The PDE itself with a delayed boundary control: the paper's plant along its
characteristics (``normal_form``) and a general plant on time-of-flight grids (``general``).
"""

from .general import GeneralSimulation, simulate_general
from .normal_form import DEFAULT_CELLS, MAX_UPDATES, Simulation, simulate, v_nodes

__all__ = ["DEFAULT_CELLS", "GeneralSimulation", "MAX_UPDATES", "Simulation", "simulate", "simulate_general", "v_nodes"]
