"""Certified roots of quasi-polynomials: counts (``winding``), the search for roots
(``search``) and the roots with their proofs (``finder``), the spectral abscissa
(``abscissa``); ``_common`` holds the rounding model, the work budget and the argument checks."""

from .abscissa import SpectralAbscissa, spectral_abscissa
from .finder import RootSet, find_roots
from .winding import RootCount, count_roots

__all__ = ["RootCount", "RootSet", "SpectralAbscissa", "count_roots", "find_roots", "spectral_abscissa"]
