"""Certified roots of quasi-polynomials: counts (``winding``), roots (``finder``) and
the spectral abscissa (``abscissa``)."""

from .abscissa import SpectralAbscissa, spectral_abscissa
from .finder import RootSet, find_roots
from .winding import RootCount, count_roots

__all__ = ["RootCount", "RootSet", "SpectralAbscissa", "count_roots", "find_roots", "spectral_abscissa"]
