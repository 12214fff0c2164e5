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


def _pts(points: FloatArray) -> FloatArray:
    return np.ascontiguousarray(points, dtype=np.float64)


def _tri(triangles: IntArray, n: int | None = None) -> NDArray[np.int64]:
    """Triangles as C-contiguous int64 ``(m, 3)``: the one signature the kernels compile for.

    The kernels do not check bounds: an index outside ``0 .. n-1`` raises here instead, as
    NumPy's indexing would have (with ``n=None`` only negative indices are refused).
    """
    tri = np.ascontiguousarray(np.reshape(triangles, (-1, 3)), dtype=np.int64)
    if len(tri):
        lo, hi = int(tri.min()), int(tri.max())
        if lo < 0 or (n is not None and hi >= n):
            bad = lo if lo < 0 else hi
            raise IndexError(f"triangles refer to node {bad}, outside 0..{'' if n is None else n - 1}")
    return tri


def edge_lengths(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Side lengths of every triangle.

    Returns
    -------
    (m, 3) array
        Column k is the length of the side opposite vertex k.
    """
    from .kernels import mesh

    p = _pts(points)
    return mesh.edge_lengths(p, _tri(triangles, len(p)))  # type: ignore[no-any-return]


def triangle_quality(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Quality q of each triangle, Eq. (5.1): ``(b+c-a)(c+a-b)(a+b-c) / (abc)``.

    q is twice the ratio of inradius to circumradius: 1 for an equilateral triangle, 0 for a
    degenerate one (0 too where a side has length 0).

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
    >>> float(triangle_quality(p, np.array([[0, 1, 2]]))[0])  # doctest: +ELLIPSIS
    1.0...
    """
    from .kernels import mesh

    p = _pts(points)
    return mesh.triangle_quality(p, _tri(triangles, len(p)))  # type: ignore[no-any-return]


def signed_areas(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Signed area of each triangle, positive when counter-clockwise.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    >>> signed_areas(p, np.array([[0, 1, 2], [0, 2, 1]])).tolist()
    [0.5, -0.5]
    """
    from .kernels import mesh

    p = _pts(points)
    return mesh.signed_areas(p, _tri(triangles, len(p)))  # type: ignore[no-any-return]


def triangle_angles(points: FloatArray, triangles: IntArray) -> FloatArray:
    """Interior angles in degrees, ``(m, 3)``, column k at vertex k."""
    a, b, c = edge_lengths(points, triangles).T
    cos_a = (b * b + c * c - a * a) / (2 * b * c)
    cos_b = (c * c + a * a - b * b) / (2 * c * a)
    cos_c = (a * a + b * b - c * c) / (2 * a * b)
    return np.degrees(np.arccos(np.clip(np.stack([cos_a, cos_b, cos_c], axis=1), -1, 1)))


def unique_edges(triangles: IntArray) -> IntArray:
    """All distinct edges of a triangulation, ``(k, 2)`` with ``i < j``, sorted by ``(i, j)``.

    Linear time: each side is filed under its smaller node and each node's few sides are sorted
    (:func:`injmesh.kernels.mesh.edge_index`), no global sort.

    Examples
    --------
    >>> import numpy as np
    >>> unique_edges(np.array([[0, 1, 2], [2, 1, 3]])).tolist()
    [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    """
    from .kernels import mesh

    tri = _tri(triangles)
    if len(tri) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    return mesh.unique_edges(tri, int(tri.max()) + 1).astype(np.intp, copy=False)  # type: ignore[no-any-return]


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
