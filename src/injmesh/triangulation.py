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


#: Edge flips need the in-circle determinant above INCIRCLE * (longest side^2)^2: cocircular
#: nodes (common in injected lattices) must not flip back and forth.
INCIRCLE = 1e-10


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
    points: FloatArray,
    triangles: IntArray,
    sdf: Callable[[FloatArray], FloatArray],
    walls: IntArray | None = None,
) -> IntArray:
    """Keep the triangles whose centroid lies inside the domain.

    ``d <= 0`` counts as inside, as in boundary tracing: a d that vanishes along an interior line
    (the paper's L-shape) must not cut the mesh there.  With ``walls``, the boundary segments
    ``(k, 2)`` actually meshed, a centroid within one edge length of the boundary is tested
    against that polygon instead (even-odd rule): next to a coarse curved boundary the centroid
    of a valid triangle can lie beyond the true curve (a hole carrying five nodes, say).
    """
    centroids = points[triangles].mean(axis=1)
    d = sdf(centroids)
    keep = d <= 0
    if walls is not None and len(walls):
        e = points[triangles] - points[triangles][:, [1, 2, 0]]
        reach = np.sqrt(np.max(np.einsum("mki,mki->mk", e, e), axis=1))
        near = np.flatnonzero(np.abs(d) < reach)
        if len(near):
            keep[near] = _inside_polygon(centroids[near], points[walls[:, 0]], points[walls[:, 1]])
    # Qhull may return flat triangles of collinear nodes on a concave straight boundary: their
    # centroid is on the boundary, so the sign test alone would keep them.
    e = points[triangles] - points[triangles][:, [1, 2, 0]]
    longest2 = np.max(np.einsum("mki,mki->mk", e, e), axis=1)
    keep &= np.abs(signed_areas(points, triangles)) > FLAT * longest2
    return triangles[keep]


def _inside_polygon(q: FloatArray, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
    """Even-odd test of points ``q`` against the segments ``a[i] -> b[i]`` (chunked)."""
    inside = np.zeros(len(q), dtype=bool)
    step = max(1, 2_000_000 // max(len(a), 1))
    for s in range(0, len(q), step):
        y = q[s : s + step, 1:2]
        x = q[s : s + step, 0:1]
        crosses = (a[:, 1] > y) != (b[:, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xint = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
        inside[s : s + step] = np.count_nonzero(crosses & (x < xint), axis=1) % 2 == 1
    return inside


def boundary_edges(triangles: IntArray) -> IntArray:
    """Edges used by exactly one triangle, oriented as in that triangle (domain on the left)."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[count[inv.reshape(-1)] == 1]


def flip_to_delaunay(points: FloatArray, triangles: IntArray, max_rounds: int = 100) -> IntArray | None:
    """Restore the Delaunay property of a valid triangulation by edge flips (Lawson).

    Used after nodes have moved a little: much cheaper than a new Qhull triangulation, and
    edges with one triangle (the boundary) are never flipped, so the mesh keeps its boundary.
    Each round flips, in parallel, the interior edges whose opposite node lies inside the
    circumcircle, at most one flip per triangle (worst violation first).

    Returns
    -------
    (m, 3) int array or None
        Counter-clockwise triangles, or None when the input has an inverted or flat triangle
        (flips cannot repair that: triangulate from scratch).
    """
    tri = np.array(triangles, dtype=np.intp, copy=True)
    if len(tri) == 0 or np.any(signed_areas(points, tri) <= 0):
        return None
    m = len(tri)
    n = len(points)
    for _ in range(max_rounds):
        # Edge opposite corner k of triangle t is (tri[t, k+1], tri[t, k+2]).
        u = tri[:, [1, 2, 0]].ravel()
        v = tri[:, [2, 0, 1]].ravel()
        key = np.minimum(u, v).astype(np.int64) * n + np.maximum(u, v)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        pair = np.flatnonzero(ks[1:] == ks[:-1])
        if len(pair) == 0:
            return tri
        h1, h2 = order[pair], order[pair + 1]  # half-edges: triangle * 3 + corner
        t1, k1 = np.divmod(h1, 3)
        t2, k2 = np.divmod(h2, 3)
        a = tri[t1, k1]
        b = tri[t2, k2]
        uu = tri[t1, (k1 + 1) % 3]
        vv = tri[t1, (k1 + 2) % 3]
        # In-circle test of b against the counter-clockwise triangle (a, uu, vv).
        pa, pu, pv = points[a] - points[b], points[uu] - points[b], points[vv] - points[b]
        la = np.einsum("ij,ij->i", pa, pa)
        lu = np.einsum("ij,ij->i", pu, pu)
        lv = np.einsum("ij,ij->i", pv, pv)
        det = (pa[:, 0] * (pu[:, 1] * lv - lu * pv[:, 1])
               - pa[:, 1] * (pu[:, 0] * lv - lu * pv[:, 0])
               + la * (pu[:, 0] * pv[:, 1] - pu[:, 1] * pv[:, 0]))
        scale = np.maximum(np.maximum(la, lu), lv) ** 2
        bad = np.flatnonzero(det > INCIRCLE * scale)
        if len(bad) == 0:
            return tri
        # At most one flip per triangle, worst first.
        bad = bad[np.argsort(-det[bad] / scale[bad], kind="stable")]
        first = np.full(m, len(bad))
        rank = np.arange(len(bad))
        np.minimum.at(first, t1[bad], rank)
        np.minimum.at(first, t2[bad], rank)
        ok = (first[t1[bad]] == rank) & (first[t2[bad]] == rank)
        f = bad[ok]
        # (a, uu, vv) + (b, vv, uu) -> (a, uu, b) + (a, b, vv): both counter-clockwise.
        tri[t1[f]] = np.stack([a[f], uu[f], b[f]], axis=1)
        tri[t2[f]] = np.stack([a[f], b[f], vv[f]], axis=1)
    return tri
