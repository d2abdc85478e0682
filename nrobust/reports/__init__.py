"""Certificates, reports and the commands that write them (the application layer).

``certificate``: :func:`certify`, every claim about a loop with how it is known;
``report``: the Markdown and HTML report with figures; ``outputs``: output directories
written as one atomic set with a manifest; ``analyze``: ``nrobust analyze`` on a
SYSTEM.toml; ``nplusm``: the same for ``n + m`` plants; ``paper``: the reference paper's
example end to end. Names load on first use (PEP 562).
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
