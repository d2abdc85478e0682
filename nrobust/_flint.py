"""Access to python-flint (FLINT's Arb ball arithmetic): loading it, its working precision, the
ball of a coefficient known to a radius, the doubles outside a ball (:func:`ball_lower`,
:func:`ball_upper`: ``float`` rounds an end to nearest), and Krawczyk's test.

python-flint is the optional extra ``nrobust[rigorous]``. Every module that computes in
ball arithmetic loads it with :func:`require_flint` (an ``ImportError`` that says how to
install it) and proves isolated simple zeros with :func:`krawczyk`: the root finder
(:mod:`nrobust.roots.finder`) and the spectral bound of difference operators
(:mod:`nrobust.difference`), each coefficient known to a radius as :func:`radius_acb`.
:mod:`nrobust.balls` re-exports these names; this module
sits below it because ``nrobust.difference``, which ``nrobust.balls`` depends on through
``nrobust.quasipoly``, needs them too.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

from ._validate import positive_int

__all__ = [
    "INSTALL_HINT",
    "acb_box",
    "krawczyk",
    "krawczyk_image",
    "ball_lower",
    "precision",
    "radius_acb",
    "require_flint",
    "ball_upper",
    "working_precision",
]

#: Message of the error raised when python-flint is missing.
INSTALL_HINT = "rigorous=True needs python-flint (ball arithmetic): pip install nrobust[rigorous]"


def require_flint() -> ModuleType:
    """Import python-flint, or raise an ``ImportError`` that says how to install it.

    Raises
    ------
    ImportError
        python-flint is not installed (``pip install nrobust[rigorous]``).
    """
    try:
        import flint
    except ImportError as exc:
        raise ImportError(INSTALL_HINT) from exc
    return flint


class precision:
    """Context in which ``flint`` computes with ``prec`` bits (not validated); restored on exit.

    A class rather than a generator: every ball evaluation enters it, and this costs a third as much.
    """

    __slots__ = ("_ctx", "_old", "_prec")

    def __init__(self, flint: ModuleType, prec: int) -> None:
        self._ctx = flint.ctx
        self._prec = prec

    def __enter__(self) -> None:
        self._old = self._ctx.prec
        self._ctx.prec = self._prec

    def __exit__(self, *exc: object) -> None:
        self._ctx.prec = self._old


def ball_upper(ball: Any) -> float:
    """A double at or above every point of the arb ``ball`` (``float`` rounds its upper end to nearest)."""
    return math.nextafter(float(ball.upper()), math.inf)


def ball_lower(ball: Any) -> float:
    """A double at or below every point of the arb ``ball``."""
    return math.nextafter(float(ball.lower()), -math.inf)


@contextmanager
def working_precision(prec: int = 53) -> Iterator[ModuleType]:
    """Context in which python-flint computes with ``prec`` bits; yields the ``flint`` module.

    The previous precision is restored on exit (python-flint's precision is global).
    """
    flint = require_flint()
    with precision(flint, positive_int("prec", prec, minimum=16, maximum=4096)):
        yield flint


def acb_box(x0: float, x1: float, y0: float, y1: float) -> Any:
    """The ``acb`` ball containing the rectangle ``[x0, x1] x [y0, y1]`` (end points exact).

    A degenerate side (``x0 == x1``) is an exact real or imaginary part, so a vertical
    segment is enclosed with no width in ``Re s``.
    """
    flint = require_flint()
    arb = flint.arb
    re = arb(x0) if x0 == x1 else arb(x0).union(arb(x1))
    im = arb(y0) if y0 == y1 else arb(y0).union(arb(y1))
    return flint.acb(re, im)


def radius_acb(flint: ModuleType, c: Any, r: float) -> Any:
    """The ``acb`` of a point coefficient ``c`` within ``r`` (real and imaginary parts each): real for a
    real ``c`` (the function stays real); the exact point ``c`` when ``r`` is 0."""
    z = complex(c)
    rad = float(r)
    if z.imag:
        return flint.acb(flint.arb(z.real, rad), flint.arb(z.imag, rad)) if rad else flint.acb(z.real, z.imag)
    return flint.acb(flint.arb(z.real, rad)) if rad else flint.acb(z.real)


def krawczyk(
    box: tuple[float, float, float, float],
    center: Any,
    value: Any,
    derivative: Callable[[Any], Any],
    inverse: Any = None,
    prec: int | None = None,
) -> bool:
    """Krawczyk's test: True when the rectangle ``box`` provably holds exactly one zero of ``F``, simple.

    With ``X`` the rectangle, ``c`` a point of it and ``y ~ 1/F'``,
    ``K(X) = c - y F(c) + (1 - y F'(X)) (X - c)`` contains every zero of ``F`` in ``X``;
    if ``K(X)`` lies in the interior of ``X``, ``X`` holds exactly one zero and ``F'`` does
    not vanish on ``X`` (the zero is simple).

    Parameters
    ----------
    box : (x0, x1, y0, y1)
        The rectangle ``X``.
    center : acb
        The point ``c`` (in ``X``).
    value : acb
        An enclosure of ``F(c)``.
    derivative : callable
        Encloses ``F'`` on an ``acb`` rectangle (called once, on ``X``).
    inverse : acb, optional
        The preconditioner ``y``; default the inverse of the midpoint of the enclosure of
        ``F'(X)`` (the test then fails when that midpoint is 0 or an enclosure is not finite).
    prec : int, optional
        Bits of the arithmetic of ``K(X)`` (default: the current precision).

    Returns
    -------
    bool
        True when the test proves the zero; False when it fails or does not apply.
    """
    K = krawczyk_image(box, center, value, derivative, inverse, prec)
    if K is None:
        return False
    x0, x1, y0, y1 = box
    re, im = K.real, K.imag
    return bool(re > x0 and re < x1 and im > y0 and im < y1)


def krawczyk_image(
    box: tuple[float, float, float, float],
    center: Any,
    value: Any,
    derivative: Callable[[Any], Any],
    inverse: Any = None,
    prec: int | None = None,
) -> Any:
    """Krawczyk's operator ``K(X) = c - y F(c) + (1 - y F'(X)) (X - c)`` on the rectangle ``box`` (an ``acb``).

    ``K(X)`` holds every zero of ``F`` in ``X`` (for any ``c`` in ``X`` and ``y != 0``), so
    ``K(X) & X`` is a smaller enclosure of a zero already proven in ``X``; :func:`krawczyk`
    proves one. Parameters as there; None when the default ``y`` does not exist (a zero
    midpoint of ``F'(X)``, or an enclosure that is not finite).
    """
    flint = require_flint()
    X = acb_box(*box)
    dfx = derivative(X)
    if inverse is None:
        slope = complex(float(dfx.real.mid()), float(dfx.imag.mid()))
        if slope == 0 or not (value.is_finite() and dfx.is_finite()):
            return None
        inverse = flint.acb(1.0 / slope)
    with precision(flint, flint.ctx.prec if prec is None else prec):
        return center - inverse * value + (1 - inverse * dfx) * (X - center)
