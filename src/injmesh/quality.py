"""Mesh metrics of the paper's Section 5: element quality (5.1) and size fidelity (Er).

Free functions over plain arrays: ``points`` is ``(n, 2)`` float64, ``triangles`` is ``(m, 3)``
int, ``edges`` is ``(k, 2)`` int with ``i < j``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def edge_lengths(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Side lengths of every triangle.

    Returns
    -------
    (m, 3) array
        Column k is the length of the side opposite vertex k.
    """
    p = points[triangles]
    return np.stack(
        [
            np.hypot(*(p[:, 2] - p[:, 1]).T),
            np.hypot(*(p[:, 0] - p[:, 2]).T),
            np.hypot(*(p[:, 1] - p[:, 0]).T),
        ],
        axis=1,
    )


def triangle_quality(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Quality q of each triangle, Eq. (5.1): ``(b+c-a)(c+a-b)(a+b-c) / (abc)``.

    q is twice the ratio of inradius to circumradius: 1 for an equilateral triangle, 0 for a
    degenerate one.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
    >>> float(triangle_quality(p, np.array([[0, 1, 2]]))[0])  # doctest: +ELLIPSIS
    1.0...
    """
    a, b, c = edge_lengths(points, triangles).T
    with np.errstate(invalid="ignore", divide="ignore"):
        q = (b + c - a) * (c + a - b) * (a + b - c) / (a * b * c)
    return np.nan_to_num(q, nan=0.0)


def signed_areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Signed area of each triangle, positive when counter-clockwise."""
    p = points[triangles]
    u = p[:, 1] - p[:, 0]
    v = p[:, 2] - p[:, 0]
    return 0.5 * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0])


def triangle_angles(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Interior angles in degrees, ``(m, 3)``, column k at vertex k."""
    a, b, c = edge_lengths(points, triangles).T
    cos_a = (b * b + c * c - a * a) / (2 * b * c)
    cos_b = (c * c + a * a - b * b) / (2 * c * a)
    cos_c = (a * a + b * b - c * c) / (2 * a * b)
    return np.degrees(np.arccos(np.clip(np.stack([cos_a, cos_b, cos_c], axis=1), -1, 1)))


def unique_edges(triangles: IntArray) -> IntArray:
    """All distinct edges of a triangulation, ``(k, 2)`` with ``i < j``, sorted."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    e.sort(axis=1)
    # One int64 key per edge: 1-D unique is much faster than unique over rows.
    n = int(triangles.max()) + 1 if len(triangles) else 1
    key = np.unique(e[:, 0].astype(np.int64) * n + e[:, 1])
    return np.stack([key // n, key % n], axis=1).astype(np.intp)


@dataclass(frozen=True)
class SizeReport:
    """How closely edge lengths follow the size function h.

    Attributes
    ----------
    er : float
        The paper's Er: mean over edges of ``|lc - h(midpoint)|`` (a length).
    relative : float
        Mean over edges of ``|lc / h(midpoint) - 1|`` (dimensionless).
    ratio_mean, ratio_min, ratio_max : float
        Statistics of ``lc / h(midpoint)``.
    edges : int
        Number of edges measured.
    """

    er: float
    relative: float
    ratio_mean: float
    ratio_min: float
    ratio_max: float
    edges: int


def size_report(
    points: FloatArray,
    triangles: IntArray,
    h: Callable[[FloatArray], FloatArray],
) -> SizeReport:
    """Compare every edge length lc with h at its midpoint (the paper's Er, Section 5)."""
    e = unique_edges(triangles)
    lc = np.hypot(*(points[e[:, 0]] - points[e[:, 1]]).T)
    ld = np.asarray(h(0.5 * (points[e[:, 0]] + points[e[:, 1]])), dtype=float).reshape(-1)
    ratio = lc / ld
    return SizeReport(
        er=float(np.mean(np.abs(lc - ld))),
        relative=float(np.mean(np.abs(ratio - 1.0))),
        ratio_mean=float(ratio.mean()),
        ratio_min=float(ratio.min()),
        ratio_max=float(ratio.max()),
        edges=int(len(e)),
    )
