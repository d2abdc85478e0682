# The public names of nrobust.roots, loaded on first use (nrobust/roots/__init__.py).
from .abscissa import (
    SpectralAbscissa as SpectralAbscissa,
    spectral_abscissa as spectral_abscissa,
)
from .finder import (
    RootSet as RootSet,
    find_roots as find_roots,
)
from .winding import (
    RootCount as RootCount,
    count_roots as count_roots,
)
