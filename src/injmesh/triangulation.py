"""Delaunay triangulation of the nodes and removal of the triangles outside the domain.

This module is the single place where SciPy's Qhull is called.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, QhullError

from .quality import signed_areas

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


#: Triangles with area below FLAT * (longest edge)^2 are degenerate (an equilateral one has 0.43).
FLAT = 1e-9


class TriangulationError(ValueError):
    """The nodes cannot be triangulated (too few, or all collinear)."""


def delaunay(points: FloatArray) -> IntArray:
    """Delaunay triangles of ``points`` ``(n, 2)``, as ``(m, 3)`` counter-clockwise indices."""
    if len(points) < 3:
        raise TriangulationError(f"cannot triangulate {len(points)} points; at least 3 are needed")
    try:
        # Centred, unit-size coordinates: far from the origin Qhull loses precision and drops
        # points, and a scaled domain must see the same triangulation.
        lo, hi = points.min(axis=0), points.max(axis=0)
        unit = (points - 0.5 * (lo + hi)) / max(float(np.max(hi - lo)), 1e-300)
        tri = Delaunay(unit, qhull_options="Qbb Qc Qz Q12").simplices
    except QhullError as exc:
        raise TriangulationError(f"Delaunay triangulation failed: {str(exc).splitlines()[0]}") from None
    tri = tri.astype(np.intp, copy=False)
    flip = signed_areas(points, tri) < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    return tri


def inside_triangles(
    points: FloatArray, triangles: IntArray, sdf: Callable[[FloatArray], FloatArray]
) -> IntArray:
    """Keep the triangles whose centroid lies inside the domain (``d < 0``).

    ``d <= 0`` counts as inside, as in boundary tracing: a d that vanishes along an interior line
    (the paper's L-shape) must not cut the mesh there.
    """
    centroids = points[triangles].mean(axis=1)
    keep = sdf(centroids) <= 0
    # Qhull may return flat triangles of collinear nodes on a concave straight boundary: their
    # centroid is on the boundary, so the sign test alone would keep them.
    e = points[triangles] - points[triangles][:, [1, 2, 0]]
    longest2 = np.max(np.einsum("mki,mki->mk", e, e), axis=1)
    keep &= np.abs(signed_areas(points, triangles)) > FLAT * longest2
    return triangles[keep]


def boundary_edges(triangles: IntArray) -> IntArray:
    """Edges used by exactly one triangle, oriented as in that triangle (domain on the left)."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[count[inv.reshape(-1)] == 1]
