"""What the counting engine, the root finder and the spectral abscissa share: the rounding
model of a sample of ``F``, the work budget and the checks of the arguments ``F`` and ``rigorous``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ..balls import require_flint
from ..errors import CertificationError, ParameterError
from ..qpmatrix import CharacteristicFunction, ExpandedDeterminant, QuasiPolynomialMatrix
from ..quasipoly import QuasiPolynomial

__all__ = ["EPS", "ROUNDING", "Budget", "check_function", "check_rigorous", "magnitude"]

EPS = float(np.finfo(float).eps)
# Rounding allowance on |F| at a sample, relative to the sum of the moduli of its terms.
ROUNDING = 64 * EPS


class Budget:
    """Counts evaluations of ``F`` (and of its derivative bound) against a maximum."""

    def __init__(self, max_evals: int) -> None:
        self.max_evals = max_evals
        self.used = 0

    def spend(self, n: int, what: str | Callable[[], str]) -> None:
        """Charge ``n`` evaluations; ``what`` (or what it returns, formatted only on failure) names the work."""
        self.used += int(n)
        if self.used > self.max_evals:
            what = what() if callable(what) else what
            raise CertificationError(
                f"work bound max_evals={self.max_evals} exhausted while {what}; raise max_evals or use a smaller region"
            )


def magnitude(F: QuasiPolynomial, s: NDArray[np.complex128]) -> NDArray[np.float64]:
    """The scale of the rounding error of ``F(s)`` (:meth:`QuasiPolynomial.magnitude`: the sum
    of the moduli of the monomials; for a matrix, :meth:`~nrobust.qpmatrix.QuasiPolynomialMatrix.magnitude`)."""
    return F.magnitude(s)


def check_rigorous(F: Any, rigorous: Any) -> bool:
    """Validate the ``rigorous`` switch; with it on, python-flint must be installed and ``F`` a
    QuasiPolynomial, a QuasiPolynomialMatrix or a characteristic function with a method
    ``ball_function(prec)`` (the functions :func:`nrobust.balls.ball_function` encloses)."""
    if not isinstance(rigorous, (bool, np.bool_)):
        raise ParameterError("rigorous", "True or False", rigorous)
    if rigorous:
        require_flint()
        own = callable(getattr(F, "ball_function", None))
        if not (own or isinstance(F, QuasiPolynomial | QuasiPolynomialMatrix)):
            raise ParameterError(
                "F",
                "a QuasiPolynomial, a QuasiPolynomialMatrix or a function with a method ball_function(prec) "
                "for rigorous=True (ball evaluation)",
                type(F).__name__,
            )
    return bool(rigorous)


def check_function(F: Any) -> QuasiPolynomial:
    """``F`` itself; a QuasiPolynomialMatrix (or another CharacteristicFunction) is used
    through the members of the protocol only, which the counting engine restricts itself to."""
    if isinstance(F, QuasiPolynomial):
        if not F.point_terms and not F.distributed:
            raise ParameterError("F", "not identically zero (every point would be a root)", F)
        return F
    # the classes of nrobust that implement the protocol first (the check of a runtime protocol is slow)
    if not isinstance(F, (QuasiPolynomialMatrix, ExpandedDeterminant)) and not isinstance(F, CharacteristicFunction):
        raise ParameterError("F", "a QuasiPolynomial or QuasiPolynomialMatrix", type(F).__name__)
    return cast(QuasiPolynomial, F)
