"""Numbers printed with the digits their accuracy supports: ``0.22953913028 +- 2e-12``."""

from __future__ import annotations

import math
from decimal import ROUND_CEILING, ROUND_FLOOR, Decimal

__all__ = ["inner_interval_text", "lower_bound_text", "upper_bound_text", "with_accuracy"]


def with_accuracy(value: float, accuracy: float | None, *, significant: int = 6) -> str:
    """``value`` rounded to the decimal place of its accuracy, followed by ``+- accuracy``.

    The accuracy is rounded up to one significant digit and the value to the same decimal
    place, so the last printed digit is uncertain by at most a few units and no digit beyond
    the accuracy is printed.

    Parameters
    ----------
    value : float
        The number.
    accuracy : float or None
        A bound (proven, or a conservative estimate) of ``|value - truth|``; 0 for an exact
        value (printed in full); None when it is not known (``significant`` digits, marked).
        A value that rounds to 0 at the place of the accuracy is printed ``0``.
    significant : int, default 6
        Significant digits printed when the accuracy is not known.

    Examples
    --------
    >>> with_accuracy(0.22953913027614878, 1.6e-12)
    '0.229539130276 +- 2e-12'
    >>> with_accuracy(0.22953913027614878, None)
    '0.229539 (accuracy not estimated)'
    >>> with_accuracy(5.55e-17, 1.3e-15)
    '0 +- 2e-15'
    """
    if not math.isfinite(value):
        return "inf" if value > 0 else ("-inf" if value < 0 else "nan")
    if accuracy is None or not math.isfinite(accuracy):
        return f"{value:.{significant}g} (accuracy not estimated)"
    if accuracy <= 0.0:
        return repr(float(value))
    bound, exponent = _bound_text(accuracy)
    if accuracy <= abs(value) * 2.0**-52 or accuracy < 1e-300:  # below the double's own resolution
        return f"{float(value)!r} +- {bound}" if value else f"0 +- {bound}"
    if abs(value) < 0.5 * 10.0**exponent:  # zero to its accuracy: no string of zeros, no digit below the bound
        return f"0 +- {_bound_text(float(Decimal(abs(value)) + Decimal(accuracy)))[0]}"  # 0 holds the value too
    if abs(value) >= 1e15 or (value != 0.0 and abs(value) < 1e-4):
        digits = max(0, math.floor(math.log10(abs(value))) - exponent) if value else 0
        return f"{value:.{digits}e} +- {bound}"
    decimals = max(0, -exponent)
    rounded = round(value, -exponent) if exponent > 0 else value
    return f"{rounded:.{decimals}f} +- {bound}"


def _bound_text(accuracy: float) -> tuple[str, int]:
    """``accuracy`` (``> 0``) with its leading digit rounded up, as printed, and its decimal exponent."""
    exact = Decimal(float(accuracy))  # subnormal accuracies too
    exponent = exact.adjusted()
    lead = math.ceil(float(exact.scaleb(-exponent)) - 1e-9)
    if lead >= 10:
        lead, exponent = 1, exponent + 1
    return f"{lead}e{exponent:+03d}".replace("e+0", "e+").replace("e-0", "e-"), exponent


def lower_bound_text(value: float, digits: int = 6) -> str:
    """``value`` to ``digits`` significant digits, rounded down: a printed lower bound stays one.

    A proven lower bound (the Rouché ``delta_0``) printed by ordinary rounding may print a
    number above what is proven (``0.0123456789`` to 6 digits is ``0.0123457``); rounded
    towards ``-inf`` every printed digit is true: the printed number is at most ``value``.
    The rounding is done on the exact binary value of the float (:class:`decimal.Decimal`).

    Parameters
    ----------
    value : float
        The lower bound (``inf``, ``-inf`` and 0 are printed as they are).
    digits : int, default 6
        Significant digits printed (at least 1).

    Examples
    --------
    >>> lower_bound_text(0.0123456789)
    '0.0123456'
    >>> lower_bound_text(2.5e-7, 2)
    '2.4e-7'
    """
    return _directed_text(value, digits, ROUND_FLOOR)


def upper_bound_text(value: float, digits: int = 6) -> str:
    """``value`` to ``digits`` significant digits, rounded up: a printed upper bound stays one.

    Examples
    --------
    >>> upper_bound_text(0.01234561)
    '0.0123457'
    """
    return _directed_text(value, digits, ROUND_CEILING)


def inner_interval_text(
    lo: float, hi: float, digits: int = 10, *, accuracies: tuple[float | None, float | None] | None = None
) -> str:
    """``(lo, hi)`` printed inside itself: ``lo`` rounded up, ``hi`` rounded down, to ``digits`` digits.

    What is claimed of every point of ``(lo, hi)`` (a stability window, gains meeting a
    requirement) then holds for every printed point. With ``accuracies = (a_lo, a_hi)``, bounds
    of the errors of the computed ends, each end is first moved inward by its own, so that the
    printed interval lies inside the true one too; an end whose accuracy is None is only rounded
    inward, and the text says that its accuracy is not estimated. An interval narrower than its
    ends' accuracies is printed as computed, and said to be.

    Examples
    --------
    >>> inner_interval_text(0.60459978807807, 1.2345678901234, 6)
    '(0.604600, 1.23456)'
    >>> inner_interval_text(0.0, 0.22953913027614878, 12, accuracies=(0.0, 2e-12))
    '(0, 0.229539130274)'
    """
    if accuracies is None:
        # more digits where rounding inward would cross the ends (an interval narrower than the printed
        # resolution); two adjacent doubles are printed as they are
        for places in range(digits, 18):
            low, high = upper_bound_text(lo, places), lower_bound_text(hi, places)
            if Decimal(low) < Decimal(high):
                return f"({low}, {high})"
        return f"({lo!r}, {hi!r})"
    a_lo, a_hi = accuracies
    inner_lo = math.nextafter(lo + a_lo, math.inf) if a_lo else lo
    inner_hi = math.nextafter(hi - a_hi, -math.inf) if a_hi else hi
    if not inner_lo < inner_hi:
        return f"{inner_interval_text(lo, hi, digits)} (narrower than its ends' accuracy)"
    text = inner_interval_text(inner_lo, inner_hi, digits)
    unknown = [name for name, a in (("lower", a_lo), ("upper", a_hi)) if a is None]
    if unknown:
        text += f" ({' and '.join(unknown)} end{'s' if len(unknown) == 2 else ''}: accuracy not estimated)"
    return text


def _directed_text(value: float, digits: int, rounding: str) -> str:
    """``value`` to ``digits`` significant digits in the direction ``rounding`` (on its exact binary value)."""
    if digits < 1:
        raise ValueError(f"digits must be at least 1, got {digits}")
    if not math.isfinite(value) or value == 0.0:
        return repr(float(value)).replace("0.0", "0")
    exact = Decimal(float(value))
    rounded = exact.quantize(Decimal(1).scaleb(exact.adjusted() - digits + 1), rounding=rounding)
    return f"{rounded:.{digits - 1}e}" if abs(value) >= 1e15 or abs(value) < 1e-4 else f"{rounded:f}"
