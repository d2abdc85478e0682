"""Parameter sweeps and Monte Carlo studies (the application layer).

``engine``: :func:`sweep` over a :func:`grid` or any points, serially, on local process
pools or on Dask, journaled and resumable, and :func:`sweep_map` (the executors the
analyses take as ``executor=``); ``journal``: the append-only result journal;
``montecarlo``: :func:`robustness`, margins under sampled parameters; ``sweepfile``: the
SWEEP.toml schema and :func:`run_sweep_file`. Names load on first use (PEP 562).
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
