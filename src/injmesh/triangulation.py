"""Delaunay triangulation of the nodes and removal of the triangles outside the domain.

The triangulation is our own incremental Delaunay kernel (:mod:`injmesh.kernels.delaunay`,
exact predicates: cocircular lattices, collinear rows and far offsets give a valid
triangulation); the other functions here run compiled kernels over plain arrays
(:mod:`injmesh.kernels.mesh`).  numba is imported on the first call, not with this module.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .quality import _pts, _tri

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


#: Triangles with area below FLAT * (longest edge)^2 are degenerate (an equilateral one has 0.43).
FLAT = 1e-9


class TriangulationError(ValueError):
    """The nodes cannot be triangulated (too few, not finite, or all collinear)."""


def delaunay(points: FloatArray) -> IntArray:
    """Delaunay triangles of ``points`` ``(n, 2)``, as ``(m, 3)`` counter-clockwise indices.

    The triangulation of the convex hull, decided by exact predicates: every triangle is
    strictly counter-clockwise and no point lies strictly inside a triangle's circumcircle.
    Ties between cocircular points are broken by a fixed insertion order, so the result is
    bit-identical from run to run.  A point that coincides exactly with an earlier one is left
    out: its index appears in no triangle (callers treat it as a node without triangles).

    Raises
    ------
    TriangulationError
        Fewer than three points, a non-finite coordinate, or all points collinear.

    Examples
    --------
    >>> import numpy as np
    >>> delaunay(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])).shape
    (2, 3)
    """
    return delaunay_with_neighbours(points)[0]


def delaunay_with_neighbours(points: FloatArray) -> tuple[IntArray, NDArray[np.int64]]:
    """:func:`delaunay`'s triangles and their neighbour table ``(m, 3)``: row t, column k is
    the triangle across the edge opposite corner k of triangle t, -1 on the hull.

    The kernel keeps the table as it triangulates; :func:`inside_triangles` and
    :func:`classify_by_walls` take it instead of finding it again (0.15 s at 1e6 nodes).
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise TriangulationError(f"points must be an (n, 2) array, got shape {p.shape}")
    if len(p) < 3:
        raise TriangulationError(f"cannot triangulate {len(p)} points; at least 3 are needed")
    from .kernels.delaunay import DelaunayError, LiveTriangulation

    try:
        live = LiveTriangulation(p)
    except DelaunayError as exc:
        raise TriangulationError(f"Delaunay triangulation failed: {exc}") from None
    tri32, nbr = live.compact()
    tri = tri32.astype(np.intp)
    dup = live.duplicates
    dropped = np.flatnonzero(dup >= 0)
    if len(dropped):
        # The kernel keeps the copy it inserted first; keep the lowest index instead, so a fixed
        # node (they come first) is never the one left out in favour of a free node on it.
        # (A renaming of the nodes in use: the neighbours stay as they are.)
        lowest = np.arange(len(p))
        np.minimum.at(lowest, dup[dropped], dropped)
        tri = lowest[tri]
    return tri, nbr.astype(np.int64)


def inside_triangles(
    points: FloatArray,
    triangles: IntArray,
    sdf: Callable[[FloatArray], FloatArray],
    walls: IntArray | None = None,
    neighbours: NDArray[np.int64] | None = None,
) -> IntArray:
    """Keep the triangles that lie inside the domain (those :func:`inside_mask` marks)."""
    return np.asarray(triangles)[inside_mask(points, triangles, sdf, walls, neighbours)]


def inside_mask(
    points: FloatArray,
    triangles: IntArray,
    sdf: Callable[[FloatArray], FloatArray],
    walls: IntArray | None = None,
    neighbours: NDArray[np.int64] | None = None,
) -> NDArray[np.bool_]:
    """Which triangles lie inside the domain.

    With ``walls``, the boundary segments ``(k, 2)`` actually meshed (domain on their left), the
    triangles are classified topologically (:func:`classify_by_walls`): those reached from the
    left side of a segment without crossing another are inside.  This is exact wherever the
    segments are edges of the triangulation, however thin the domain.  Triangles of a region
    that a missing segment leaves open are judged by their centroid instead: against the
    segments' polygon (even-odd rule) within one edge length of the boundary, by the sign of d
    further away.

    Without ``walls`` a triangle is inside when its centroid is (``d <= 0``: a d that vanishes
    along an interior line, as the paper's L-shape does, must not cut the mesh there).
    Flat triangles (area at most ``FLAT`` times the longest side squared) are never kept.
    ``neighbours``: the triangles' neighbour table, when the caller has it
    (:func:`delaunay_with_neighbours`).
    """
    from .kernels import mesh

    p = _pts(points)
    tri = _tri(triangles, len(p))
    centroids, longest2, flat = mesh.centroids_and_flatness(p, tri, FLAT)
    w = None if walls is None or len(walls) == 0 else _tri_pairs(walls, len(p))
    if w is not None:
        keep, open_ = classify_by_walls(tri, w, neighbours)
        judge = np.flatnonzero(open_)
    else:
        keep = np.zeros(len(tri), dtype=bool)
        judge = np.arange(len(tri))
    if len(judge):
        d = np.asarray(sdf(centroids[judge]), dtype=float).reshape(-1)
        keep[judge] = d <= 0
        if w is not None:
            near = judge[np.abs(d) < np.sqrt(longest2[judge])]
            if len(near):
                keep[near] = inside_polygon(centroids[near], p[w[:, 0]], p[w[:, 1]])
    # A flat triangle of collinear nodes on a straight boundary has its centroid on the
    # boundary: the sign test alone would keep it.
    keep &= ~flat
    return keep


def _tri_pairs(pairs: IntArray, n: int) -> NDArray[np.int64]:
    """``(k, 2)`` node pairs as C-contiguous int64, every index checked against ``0 .. n-1``."""
    e = np.ascontiguousarray(np.reshape(pairs, (-1, 2)), dtype=np.int64)
    if len(e) and (int(e.min()) < 0 or int(e.max()) >= n):
        bad = int(e.min()) if int(e.min()) < 0 else int(e.max())
        raise IndexError(f"segments refer to node {bad}, outside 0..{n - 1}")
    return e


def classify_by_walls(
    triangles: IntArray, walls: IntArray, neighbours: NDArray[np.int64] | None = None
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Inside/outside of every triangle from the oriented boundary segments, by flood fill.

    Triangles are joined across every edge that is not a wall; the triangle on the left of a
    wall is inside, the one on its right outside, and each connected region takes the side of
    the walls around it.  A region reached from both sides (a wall is not an edge, so the fill
    leaks through it) or from neither is *open*: the caller decides those another way.

    Parameters
    ----------
    triangles : (m, 3) int array
        Counter-clockwise triangles.
    walls : (k, 2) int array
        Boundary segments ``a -> b`` with the domain on their left.
    neighbours : (m, 3) int array, optional
        The triangles' neighbour table (:func:`delaunay_with_neighbours`), found here if not
        given.

    Returns
    -------
    inside, open : (m,) bool arrays

    Examples
    --------
    >>> import numpy as np
    >>> tri = np.array([[0, 1, 2], [0, 2, 3], [2, 4, 3]])  # a square 0-1-2-3 and a flap 2-4-3
    >>> walls = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])
    >>> [a.tolist() for a in classify_by_walls(tri, walls)]
    [[True, True, False], [False, False, False]]
    """
    from .kernels import mesh

    tri = _tri(triangles)
    w = np.ascontiguousarray(np.reshape(walls, (-1, 2)), dtype=np.int64)
    if len(w) and int(w.min()) < 0:
        raise IndexError(f"walls refer to node {int(w.min())}")
    n = int(max(tri.max(initial=0), w.max(initial=0))) + 1
    nbr = mesh.neighbours(tri, n) if neighbours is None else np.ascontiguousarray(neighbours, dtype=np.int64)
    return mesh.classify_by_walls(tri, nbr, w, n)  # type: ignore[no-any-return]


def inside_polygon(q: FloatArray, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
    """Even-odd test of points ``q`` against the segments ``a[i] -> b[i]``."""
    from .kernels import mesh

    return mesh.inside_polygon(_pts(q), _pts(a), _pts(b))  # type: ignore[no-any-return]


def constrained_triangles(
    points: FloatArray, sdf: Callable[[FloatArray], FloatArray], walls: IntArray,
    interior: IntArray | None = None,
) -> IntArray:
    """The triangles inside the boundary segments ``walls``, each segment an edge.

    Delaunay triangulation of all the nodes, then every segment Delaunay dropped is recovered by
    flips (:func:`recover_segments`), then the inside is found by flood fill from the segments
    (:func:`classify_by_walls`).  Where a node lies exactly on a segment, recovery fails and
    that region is judged by its centroids; the mesh's own check then reports the segment.
    ``interior`` segments (interior curves) become edges too but do not bound the inside.
    """
    tri, nbr = delaunay_with_neighbours(points)
    required = walls if interior is None else np.concatenate([walls, interior])
    full, _, nbr = _recover_segments(points, tri, required, nbr)
    return inside_triangles(points, full, sdf, walls, nbr)


def boundary_edges(triangles: IntArray) -> IntArray:
    """Edges used by exactly one triangle, oriented as in that triangle (domain on the left).

    In the order of the sides (0, 1) of all triangles, then (1, 2), then (2, 0).

    Examples
    --------
    >>> import numpy as np
    >>> boundary_edges(np.array([[0, 1, 2], [0, 2, 3]])).tolist()
    [[0, 1], [1, 2], [2, 3], [3, 0]]
    """
    from .kernels import mesh

    tri = _tri(triangles)
    if len(tri) == 0:
        return np.zeros((0, 2), dtype=np.asarray(triangles).dtype)
    out = mesh.boundary_edges(tri, int(tri.max()) + 1)
    return out.astype(np.asarray(triangles).dtype, copy=False)  # type: ignore[no-any-return]


def flip_to_delaunay(points: FloatArray, triangles: IntArray, max_rounds: int = 100) -> IntArray | None:
    """Restore the Delaunay property of a valid triangulation by edge flips (Lawson).

    Used after nodes have moved a little: much cheaper than a new triangulation, and edges with
    one triangle (the boundary) are never flipped, so the mesh keeps its boundary.  The flips
    are sequential (:func:`injmesh.kernels.delaunay.flip_to_delaunay`) and decided by the exact
    in-circle test, so they cannot cycle on cocircular nodes and end with every interior edge
    locally Delaunay.

    Parameters
    ----------
    points : (n, 2) float array
    triangles : (m, 3) int array
        A valid triangulation (counter-clockwise, each edge in one or two triangles).
    max_rounds : int
        Kept for compatibility with the former round-based version; unused (the kernel caps the
        flips at 50 per triangle instead, which a valid triangulation never reaches).

    Returns
    -------
    (m, 3) int array or None
        Counter-clockwise triangles, or None when the input has an inverted or flat triangle
        (flips cannot repair that: triangulate from scratch), or is not a valid triangulation.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> p[2] = [0.6, 0.6]  # now inside the circle through 0, 1, 3: diagonal 1-3 is illegal
    >>> flip_to_delaunay(p, np.array([[0, 1, 3], [1, 2, 3]])).tolist()
    [[0, 1, 2], [0, 2, 3]]
    """
    from .kernels import delaunay as kd
    from .kernels import mesh

    p = _pts(points)
    tri64 = _tri(triangles, len(p))
    if len(tri64) == 0:
        return None
    tri = tri64.astype(np.int32)
    nbr = mesh.neighbours(tri64, len(p)).astype(np.int32)
    con = np.zeros(tri.shape, dtype=np.uint8)
    vt = np.full(len(p), -1, dtype=np.int32)
    res = kd.flip_to_delaunay(p, tri, nbr, con, vt)
    if res < 0:
        return None
    return tri.astype(np.intp)


def neighbours(triangles: IntArray) -> IntArray:
    """Triangle across the edge opposite each corner, ``(m, 3)``, -1 on the hull.

    Edge k of triangle t joins ``triangles[t, (k + 1) % 3]`` and ``triangles[t, (k + 2) % 3]``.

    Examples
    --------
    >>> import numpy as np
    >>> neighbours(np.array([[0, 1, 2], [0, 2, 3]])).tolist()
    [[-1, 1, -1], [-1, -1, 0]]
    """
    from .kernels import mesh

    tri = _tri(triangles)
    if len(tri) == 0:
        return np.zeros((0, 3), dtype=np.intp)
    return mesh.neighbours(tri, int(tri.max()) + 1).astype(np.intp, copy=False)  # type: ignore[no-any-return]


def recover_segments(
    points: FloatArray, triangles: IntArray, segments: IntArray
) -> tuple[IntArray, IntArray]:
    """Make every segment an edge of the triangulation by edge flips (Sloan's algorithm).

    ``triangles`` must triangulate the convex hull of ``points`` (as :func:`delaunay` does).
    The segments that are already edges are fixed first; then for each missing segment a-b the
    edges it crosses are flipped while their quadrilateral is strictly convex, until a-b appears
    (:func:`injmesh.kernels.delaunay.recover_edge`), and the new edges are made Delaunay again
    except across the segments (a constrained Delaunay triangulation).  Flipping never leaves
    the hull, so the result is a valid triangulation.  A segment through another node
    (collinear), or crossing another segment, cannot be recovered.

    Returns
    -------
    triangles : (m, 3) int array
        The triangulation with the segments as edges.
    failed : (f,) int array
        Indices of the segments that could not be recovered.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [2.0, -1.0], [4.0, 0.0], [2.0, 1.0]])
    >>> tri, failed = recover_segments(p, delaunay(p), np.array([[0, 2]]))
    >>> sorted(sorted(t) for t in tri.tolist()), failed.tolist()
    ([[0, 1, 2], [0, 2, 3]], [])
    """
    tri, failed, _ = _recover_segments(points, triangles, segments)
    return tri, failed


def _recover_segments(
    points: FloatArray, triangles: IntArray, segments: IntArray,
    neighbours: NDArray[np.int64] | None = None,
) -> tuple[IntArray, IntArray, NDArray[np.int64]]:
    """:func:`recover_segments`, and the neighbour table of the result; ``neighbours``: that of
    ``triangles`` when the caller has it (the flips keep it up to date)."""
    from .kernels import delaunay as kd
    from .kernels import mesh

    p = _pts(points)
    tri64 = _tri(triangles, len(p))
    seg = np.ascontiguousarray(np.reshape(segments, (-1, 2)), dtype=np.int64)
    nbr = (mesh.neighbours(tri64, len(p)) if neighbours is None else neighbours).astype(np.int32)
    if len(seg) == 0 or len(tri64) == 0:
        return tri64.astype(np.intp), np.zeros(0, dtype=np.intp), nbr.astype(np.int64)
    tri = tri64.astype(np.int32)
    con = np.zeros(tri.shape, dtype=np.uint8)
    status = kd.recover_segments(p, tri, nbr, con, seg)
    return (tri.astype(np.intp), np.flatnonzero(status != kd.OK).astype(np.intp),
            nbr.astype(np.int64))
