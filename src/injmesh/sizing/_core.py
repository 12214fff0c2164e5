"""The target edge length h(p): validation of what the user gives.

``size`` is a positive float (uniform mesh) or a callable ``h(p)`` that takes an ``(n, 2)``
array of points and returns ``(n,)`` positive lengths, in the units of the domain.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from ..geometry import Domain

FloatArray = NDArray[np.float64]
SizeLike = float | int | str | Callable[[FloatArray], FloatArray]


class SizeError(ValueError):
    """The size function is not a positive, finite length of the right shape."""


@dataclass(frozen=True)
class SizeFunction:
    """A validated h(p).

    Every evaluation checks the result's type, shape and that it is finite and positive, so a
    bad h fails with a message naming the offending point instead of producing a silently wrong
    mesh.  The check is a few vectorised reductions, cheap next to any mesher stage.

    ``domain`` and ``max_size`` are set by :meth:`restricted`: h is then evaluated only at
    points inside or on the boundary of the domain, and sizes above the domain's diameter are
    clamped to it.
    """

    function: Callable[[FloatArray], FloatArray]
    constant: float | None = None
    domain: Domain | None = None
    max_size: float | None = None

    def restricted(self, domain: Domain) -> SizeFunction:
        """This h, evaluated only inside ``domain`` and clamped to its diameter.

        DistMesh-style size functions are often meaningful only inside the domain
        (``0.05 + 0.3 * dcircle(p, 0, 0, 0.5)`` is negative inside the hole).  The returned
        function projects every point outside the domain (d > 0) onto the boundary (Eq. 3.2)
        before evaluating h there, so h is never asked for a value outside.  Cost: one call of
        ``domain.sdf`` per evaluation, plus a projection of the points that are outside (none,
        for the nodes of a mesh, which all lie inside or on the boundary).

        A size larger than the domain's diameter (``domain.diameter``, the diagonal of its
        bounding box) means "one element across everything"; it is clamped to the diameter, so a
        size such as 1e300 reaches the later stages as a sane length.

        Examples
        --------
        >>> import numpy as np
        >>> from injmesh import Circle
        >>> ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
        >>> h = as_size_function(lambda p: 0.05 + 0.3 * (np.hypot(p[:, 0], p[:, 1]) - 0.5))
        >>> h.restricted(ring)(np.array([[0.0, 0.0], [0.75, 0.0]])).round(3)
        array([0.05 , 0.125])
        """
        diameter = float(domain.diameter)
        if self.constant is not None:
            value = min(self.constant, diameter)
            return replace(self, function=_Constant(value), constant=value, domain=domain, max_size=diameter)
        return replace(self, domain=domain, max_size=diameter)

    def __call__(self, p: FloatArray) -> FloatArray:
        p = np.asarray(p, dtype=float).reshape(-1, 2)
        if self.constant is not None:
            return np.full(len(p), self.constant)
        q = p
        if self.domain is not None and len(p):
            outside = self.domain.sdf(p) > 0
            if outside.any():
                q = p.copy()
                q[outside] = self.domain.project(p[outside])
        try:
            raw = np.asarray(self.function(q))
        except (TypeError, ValueError) as exc:
            raise SizeError(f"the size function failed on an (n, 2) array of points: {exc}") from exc
        h = _as_lengths(raw)
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
            others = int(bad.sum()) - 1
            more = f" (and {others} other of the {len(p)} points)" if others else ""
            raise SizeError(
                "the size function must be positive and finite; "
                f"h{tuple(q[i].round(6).tolist())} = {float(h[i])}{more}"
            )
        if self.max_size is not None:
            h = np.minimum(h, self.max_size)
        return h


class _Constant:
    """A uniform size as a picklable callable."""

    def __init__(self, value: float) -> None:
        self.value = value

    def __call__(self, p: FloatArray) -> FloatArray:
        return np.full(len(p), self.value)


_KIND_NAMES = {"b": "booleans", "c": "complex numbers", "O": "Python objects (dtype=object)",
               "U": "strings", "S": "bytes", "M": "dates", "m": "time deltas", "V": "records"}


def _as_lengths(raw: np.ndarray) -> FloatArray:
    """The float64 lengths of a size function's result, refusing what is not a real number.

    ``np.asarray(..., dtype=float)`` would accept booleans (True = 1.0) and strings such as
    ``"0.1"``, and drop imaginary parts with only a warning: each is a bug in the user's h.
    """
    kind = raw.dtype.kind
    if kind not in "fiu":
        what = _KIND_NAMES.get(kind, f"dtype {raw.dtype}")
        raise SizeError(f"the size function must return real numbers, got {what} (dtype {raw.dtype})")
    return raw.astype(np.float64, copy=False)


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
        from ..expression import parse_size

        size = parse_size(size)
    if isinstance(size, (bool, np.bool_)):
        raise TypeError("size must be a positive number or a callable h(p), not a bool")
    if isinstance(size, (int, float, np.integer, np.floating)):
        value = float(size)
        if not (math.isfinite(value) and value > 0):
            raise SizeError(f"size must be a positive finite length, got {size!r}")
        return SizeFunction(_Constant(value), constant=value)
    if callable(size):
        return SizeFunction(size)
    raise TypeError(f"size must be a positive number or a callable h(p), got {type(size).__name__}")


def inside_only(size: SizeLike, domain: Domain) -> SizeFunction:
    """``size`` as a validated h(p) evaluated only inside ``domain``; see :meth:`SizeFunction.restricted`.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Circle
    >>> h = inside_only(lambda p: 1.0 - np.hypot(p[:, 0], p[:, 1]) + 0.1, Circle((0, 0), 1))
    >>> h(np.array([[3.0, 0.0]]))  # evaluated at the boundary point (1, 0)
    array([0.1])
    """
    return as_size_function(size).restricted(domain)
