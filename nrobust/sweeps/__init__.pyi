# The public names of nrobust.sweeps, loaded on first use (nrobust/sweeps/__init__.py).
