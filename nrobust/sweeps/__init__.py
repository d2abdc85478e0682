"""Parameter sweeps and Monte Carlo studies (the application layer).

``executors``: where points run (serially, on local process pools that die with their
parent, on any Executor or on Dask) and :func:`sweep_map`, the ``map`` the analyses take
as ``executor=``; ``grids``: the lazy :func:`grid`; ``result``: :class:`SweepResult`, the
table of a sweep; ``engine``: :func:`sweep` over a grid or any points, sized before it
runs, journaled and resumable; ``journal``: the append-only result journal;
``montecarlo``: :func:`robustness`, margins under sampled parameters; ``sweepfile``: the
SWEEP.toml schema and :func:`run_sweep_file`. Names load on first use (PEP 562).
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
