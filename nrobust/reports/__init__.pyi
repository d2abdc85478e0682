# The public names of nrobust.reports, loaded on first use (nrobust/reports/__init__.py).
