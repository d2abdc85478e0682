# The public names of nrobust.plots, loaded on first use (nrobust/plots/__init__.py).
