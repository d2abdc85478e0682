"""Named errors of nrobust.

Every check of user input raises a subclass of :class:`ValueError` whose message
names the offending parameter and the admissible range, so that
``except ValueError`` keeps working for callers who do not care which one.
"""

from __future__ import annotations

__all__ = [
    "NrobustError",
    "ParameterError",
    "RegionError",
    "ConvergenceError",
    "CertificationError",
    "SweepError",
    "SpuriousPoleWarning",
]


class NrobustError(Exception):
    """Base class of every error raised on purpose by nrobust."""


class ParameterError(NrobustError, ValueError):
    """A parameter is outside its admissible range.

    Parameters
    ----------
    name : str
        Name of the parameter as the user passed it.
    requirement : str
        The admissible range, in words (``"> 0"``, ``"finite"``, ...).
    value : object, optional
        The value received, echoed in the message.
    """

    def __init__(self, name: str, requirement: str, value: object = None) -> None:
        self.name = name
        self.requirement = requirement
        self.value = value
        got = "" if value is None else f" (got {value!r})"
        super().__init__(f"{name} must be {requirement}{got}")


class RegionError(ParameterError):
    """A rectangular region ``(re_min, re_max, im_min, im_max)`` is empty or not finite."""


class ConvergenceError(NrobustError, RuntimeError):
    """An iterative method reached its work bound without meeting its tolerance."""


class CertificationError(NrobustError, RuntimeError):
    """A certified computation could not be completed within its work bound.

    Raised instead of returning an uncertified answer silently; the message says
    what could not be certified and which bound was hit.
    """


class SweepError(NrobustError, RuntimeError):
    """A point of a parallel grid computation raised; the message names the point and the error."""


class SpuriousPoleWarning(UserWarning):
    """A rational model had poles in ``Re s > 0`` that the modelled function does not have.

    Issued by :func:`nrobust.lti.transfer.pade_approximation` when it replaces such poles (the
    message names them); filter it with ``warnings.simplefilter("ignore", SpuriousPoleWarning)``.
    """
