"""Parameter grids: the cartesian product of parameter values, generated point by point."""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Iterator, Mapping, Sequence
from typing import Any, overload

import numpy as np

from ..errors import ParameterError

__all__ = ["Grid", "grid"]


class Grid(Sequence[dict[str, Any]]):
    """The cartesian product of parameter values (:func:`grid`), generated point by point.

    A grid stores its axes, never the product: ``len`` is the product of the axis
    lengths, ``grid[i]`` computes point ``i`` and iteration yields the points in
    ``itertools.product`` order (the last axis fastest). A grid equals any sequence of
    the same points in the same order.

    Attributes
    ----------
    axes : dict of str to sequence
        The values per parameter name (a ``range`` stays a ``range``).
    """

    def __init__(self, axes: Mapping[str, Sequence[Any]]) -> None:
        self.axes = dict(axes)
        self._size = math.prod(len(v) for v in self.axes.values())

    def __len__(self) -> int:
        return self._size

    @overload
    def __getitem__(self, index: int) -> dict[str, Any]: ...

    @overload
    def __getitem__(self, index: slice) -> list[dict[str, Any]]: ...

    def __getitem__(self, index: int | slice) -> dict[str, Any] | list[dict[str, Any]]:
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(self._size))]
        i = operator.index(index)
        if i < 0:
            i += self._size
        if not 0 <= i < self._size:
            raise IndexError(f"grid index {index} out of range for {self._size} points")
        point: dict[str, Any] = {}
        for name, values in reversed(self.axes.items()):
            i, k = divmod(i, len(values))
            point[name] = values[k]
        return {name: point[name] for name in self.axes}

    def __iter__(self) -> Iterator[dict[str, Any]]:
        names = list(self.axes)
        return (dict(zip(names, combo)) for combo in itertools.product(*self.axes.values()))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, Grid):
            return self.axes == other.axes
        if isinstance(other, Sequence) and not isinstance(other, (str, bytes)):
            return len(other) == self._size and all(a == b for a, b in zip(self, other))
        return NotImplemented

    __hash__ = None  # type: ignore[assignment]

    def describe(self) -> str:
        """``"a grid of 4 x 3 = 12 points over K, rho"``."""
        sizes = " x ".join(str(len(v)) for v in self.axes.values())
        return f"a grid of {sizes} = {self._size} points over {', '.join(self.axes)}"

    def __repr__(self) -> str:
        return f"Grid({', '.join(f'{k}: {len(v)} values' for k, v in self.axes.items())}; {self._size} points)"


def grid(**axes: Sequence[Any] | np.ndarray) -> Grid:
    """Cartesian product of parameter values, generated lazily.

    Parameters
    ----------
    **axes : sequence
        One non-empty sequence (list, tuple, range or 1-D array) of values per
        parameter name. numpy scalars are converted to Python scalars.

    Returns
    -------
    Grid
        A sequence of ``prod(len(values))`` dicts, computed on demand (nothing of the
        size of the product is allocated); the last axis varies fastest
        (``itertools.product`` order), so ``grid(K=[0, 1], delta=[0.1, 0.2])`` is
        ``[{K: 0, delta: 0.1}, {K: 0, delta: 0.2}, {K: 1, delta: 0.1}, {K: 1, delta: 0.2}]``.
        :func:`~nrobust.sweeps.engine.sweep` refuses a grid of more than ``max_points`` points before running any.

    Raises
    ------
    ParameterError
        If no axis is given or an axis is not a non-empty sequence.
    """
    if not axes:
        raise ParameterError("axes", "at least one keyword argument name=[values]")
    values: dict[str, Sequence[Any]] = {}
    for name, vals in axes.items():
        if isinstance(vals, (str, bytes, Mapping)) or not isinstance(vals, (Sequence, np.ndarray, range)):
            raise ParameterError(name, "a sequence of values (list, tuple, range or 1-D array)", vals)
        if isinstance(vals, np.ndarray) and vals.ndim != 1:
            raise ParameterError(name, "a 1-D array of values", vals)
        if len(vals) == 0:
            raise ParameterError(name, "a non-empty sequence of values", vals)
        values[name] = (
            vals if isinstance(vals, range) else tuple(v.item() if isinstance(v, np.generic) else v for v in vals)
        )
    return Grid(values)
