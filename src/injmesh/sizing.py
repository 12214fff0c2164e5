"""The target edge length h(p): validation of what the user gives.

``size`` is a positive float (uniform mesh) or a callable ``h(p)`` that takes an ``(n, 2)``
array of points and returns ``(n,)`` positive lengths, in the units of the domain.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
SizeLike = float | int | str | Callable[[FloatArray], FloatArray]


class SizeError(ValueError):
    """The size function is not a positive, finite length of the right shape."""


@dataclass(frozen=True)
class SizeFunction:
    """A validated h(p).

    Every evaluation checks the result's shape and that it is finite and positive, so a bad h
    fails with a message naming the offending point instead of producing a silently wrong mesh.
    The check is two vectorised reductions, cheap next to any mesher stage.
    """

    function: Callable[[FloatArray], FloatArray]
    constant: float | None = None

    def __call__(self, p: FloatArray) -> FloatArray:
        p = np.asarray(p, dtype=float).reshape(-1, 2)
        if self.constant is not None:
            return np.full(len(p), self.constant)
        try:
            h = np.asarray(self.function(p), dtype=float)
        except (TypeError, ValueError) as exc:
            raise SizeError(f"the size function failed on an (n, 2) array of points: {exc}") from exc
        if h.ndim == 0:
            h = np.full(len(p), float(h))
        if h.shape != (len(p),):
            raise SizeError(
                f"the size function must return shape ({len(p)},) for {len(p)} points, "
                f"got shape {h.shape}"
            )
        bad = ~(np.isfinite(h) & (h > 0))
        if bad.any():
            i = int(np.argmax(bad))
            raise SizeError(
                "the size function must be positive and finite; "
                f"h{tuple(p[i].round(6).tolist())} = {float(h[i])}"
            )
        return h


def as_size_function(size: SizeLike) -> SizeFunction:
    """Validate ``size`` and return it as a callable h(p).

    Parameters
    ----------
    size : float or callable or str
        A positive edge length, ``h(p) -> (n,)`` for ``p`` of shape ``(n, 2)``, or an expression
        in ``x`` and ``y`` (see :func:`injmesh.size_expression`).

    Raises
    ------
    SizeError
        If a number is not positive and finite.
    TypeError
        If ``size`` is neither a number nor a callable.

    Examples
    --------
    >>> import numpy as np
    >>> h = as_size_function(0.1)
    >>> h(np.zeros((3, 2)))
    array([0.1, 0.1, 0.1])
    """
    if isinstance(size, SizeFunction):
        return size
    if isinstance(size, str):  # the same safe expressions as the command line's --size
        from .expression import parse_size

        size = parse_size(size)
    if isinstance(size, (bool, np.bool_)):
        raise TypeError("size must be a positive number or a callable h(p), not a bool")
    if isinstance(size, (int, float, np.integer, np.floating)):
        value = float(size)
        if not (math.isfinite(value) and value > 0):
            raise SizeError(f"size must be a positive finite length, got {size!r}")
        return SizeFunction(lambda p: np.full(len(p), value), constant=value)
    if callable(size):
        return SizeFunction(size)
    raise TypeError(f"size must be a positive number or a callable h(p), got {type(size).__name__}")
