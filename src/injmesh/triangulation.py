"""Delaunay triangulation of the nodes and removal of the triangles outside the domain.

This module is the single place where SciPy's Qhull is called.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, QhullError

from .quality import signed_areas, unique_edges

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
    """Keep the triangles that lie inside the domain.

    With ``walls``, the boundary segments ``(k, 2)`` actually meshed (domain on their left), the
    triangles are classified topologically (:func:`classify_by_walls`): those reached from the
    left side of a segment without crossing another are inside.  This is exact wherever the
    segments are edges of the triangulation, however thin the domain.  Triangles of a region
    that a missing segment leaves open are judged by their centroid instead: against the
    segments' polygon (even-odd rule) within one edge length of the boundary, by the sign of d
    further away.

    Without ``walls`` a triangle is inside when its centroid is (``d <= 0``: a d that vanishes
    along an interior line, as the paper's L-shape does, must not cut the mesh there).
    """
    centroids = points[triangles].mean(axis=1)
    e = points[triangles] - points[triangles][:, [1, 2, 0]]
    longest2 = np.max(np.einsum("mki,mki->mk", e, e), axis=1)
    if walls is not None and len(walls):
        keep, open_ = classify_by_walls(triangles, walls)
        judge = np.flatnonzero(open_)
    else:
        keep = np.zeros(len(triangles), dtype=bool)
        judge = np.arange(len(triangles))
    if len(judge):
        d = sdf(centroids[judge])
        keep[judge] = d <= 0
        if walls is not None and len(walls):
            near = judge[np.abs(d) < np.sqrt(longest2[judge])]
            if len(near):
                keep[near] = inside_polygon(centroids[near], points[walls[:, 0]], points[walls[:, 1]])
    # Qhull may return flat triangles of collinear nodes on a concave straight boundary: their
    # centroid is on the boundary, so the sign test alone would keep them.
    keep &= np.abs(signed_areas(points, triangles)) > FLAT * longest2
    return triangles[keep]


def classify_by_walls(triangles: IntArray, walls: IntArray) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
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
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    m = len(triangles)
    n = int(max(triangles.max(initial=0), walls.max(initial=0))) + 1
    u = triangles.ravel()
    v = triangles[:, [1, 2, 0]].ravel()
    owner = np.repeat(np.arange(m), 3)
    directed = u.astype(np.int64) * n + v
    undirected = np.minimum(u, v).astype(np.int64) * n + np.maximum(u, v)
    wall_undirected = np.minimum(walls[:, 0], walls[:, 1]).astype(np.int64) * n + np.maximum(
        walls[:, 0], walls[:, 1])
    is_wall = np.isin(undirected, wall_undirected)
    # Pairs of triangles sharing a non-wall edge.
    order = np.argsort(undirected, kind="stable")
    k = undirected[order]
    same = np.flatnonzero((k[1:] == k[:-1]) & ~is_wall[order[1:]])
    a, b = owner[order[same]], owner[order[same + 1]]
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(m, m))
    _, label = connected_components(graph, directed=False)
    # Seeds: the triangle holding a -> b is on the wall's left (inside); b -> a, its right.
    wkey = walls[:, 0].astype(np.int64) * n + walls[:, 1]
    rkey = walls[:, 1].astype(np.int64) * n + walls[:, 0]
    left = owner[np.isin(directed, wkey)]
    right = owner[np.isin(directed, rkey)]
    n_lab = int(label.max(initial=-1)) + 1
    seen_in = np.zeros(n_lab, dtype=bool)
    seen_out = np.zeros(n_lab, dtype=bool)
    seen_in[label[left]] = True
    seen_out[label[right]] = True
    inside = (seen_in & ~seen_out)[label]
    open_ = (seen_in == seen_out)[label]
    # A region touching no wall at all lies beyond the walls: outside, not open, unless no
    # region touches a wall from inside (no wall is an edge).
    untouched = ~seen_in & ~seen_out
    if seen_in.any():
        open_ &= ~untouched[label]
    return inside, open_


def inside_polygon(q: FloatArray, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
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


def constrained_triangles(
    points: FloatArray, sdf: Callable[[FloatArray], FloatArray], walls: IntArray
) -> IntArray:
    """The triangles inside the boundary segments ``walls``, each segment an edge.

    Delaunay triangulation of all the nodes, then every segment Delaunay dropped is recovered by
    flips (:func:`recover_segments`), then the inside is found by flood fill from the segments
    (:func:`classify_by_walls`).  Where a node lies exactly on a segment, recovery fails and
    that region is judged by its centroids; the mesh's own check then reports the segment.
    """
    full, _ = recover_segments(points, delaunay(points), walls)
    return inside_triangles(points, full, sdf, walls)


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


def neighbours(triangles: IntArray) -> IntArray:
    """Triangle across the edge opposite each corner, ``(m, 3)``, -1 on the hull.

    Edge k of triangle t joins ``triangles[t, (k + 1) % 3]`` and ``triangles[t, (k + 2) % 3]``.
    """
    m = len(triangles)
    u = triangles[:, [1, 2, 0]].ravel()
    v = triangles[:, [2, 0, 1]].ravel()
    n = int(triangles.max(initial=0)) + 1
    key = u.astype(np.int64) * n + v
    rev = v.astype(np.int64) * n + u
    order = np.argsort(key, kind="stable")
    pos = np.searchsorted(key[order], rev)
    pos = np.minimum(pos, len(key) - 1)
    hit = key[order[pos]] == rev
    nbr = np.full(3 * m, -1, dtype=np.intp)
    nbr[hit] = order[pos[hit]] // 3
    return nbr.reshape(m, 3)


def recover_segments(
    points: FloatArray, triangles: IntArray, segments: IntArray
) -> tuple[IntArray, IntArray]:
    """Make every segment an edge of the triangulation by edge flips (Sloan's algorithm).

    ``triangles`` must triangulate the convex hull of ``points`` (as :func:`delaunay` does).
    For each segment a-b that is not an edge, the edges it crosses are collected by walking
    from a to b; each is flipped when its two triangles form a strictly convex quadrilateral
    and revisited otherwise, until a-b appears.  Flipping never leaves the hull, so the result
    is still a valid triangulation; it is constrained, not Delaunay, next to the recovered
    segments.  A segment through another node (collinear) cannot be recovered.

    Returns
    -------
    triangles : (m, 3) int array
        The triangulation with the segments as edges.
    failed : (f,) int array
        Indices of the segments that could not be recovered.
    """
    tri = np.array(triangles, dtype=np.intp, copy=True)
    seg = np.asarray(segments, dtype=np.intp).reshape(-1, 2)
    if len(seg) == 0 or len(tri) == 0:
        return tri, np.zeros(0, dtype=np.intp)
    n = int(max(tri.max(), seg.max())) + 1
    have = unique_edges(tri)
    s = np.sort(seg, axis=1)
    missing = np.flatnonzero(~np.isin(s[:, 0].astype(np.int64) * n + s[:, 1],
                                      have[:, 0].astype(np.int64) * n + have[:, 1]))
    if len(missing) == 0:
        return tri, np.zeros(0, dtype=np.intp)
    nbr = neighbours(tri)
    pts = np.asarray(points, dtype=float)
    star: dict[int, int] = {}
    for t, row in enumerate(tri.tolist()):
        for v in row:
            star[v] = t
    failed = []
    for k in missing.tolist():
        a, b = int(seg[k, 0]), int(seg[k, 1])
        if a == b or a not in star or b not in star or not _recover_one(pts, tri, nbr, star, a, b):
            failed.append(k)
    return tri, np.asarray(failed, dtype=np.intp)


def _orient(p: FloatArray, a: int, b: int, c: int) -> float:
    return float((p[b, 0] - p[a, 0]) * (p[c, 1] - p[a, 1]) - (p[b, 1] - p[a, 1]) * (p[c, 0] - p[a, 0]))


def _crossed(p: FloatArray, tri: IntArray, nbr: IntArray, star: dict[int, int], a: int, b: int
             ) -> list[tuple[int, int]] | None:
    """Edges (as (triangle, corner)) crossed by segment a-b, walking from a; None if a node lies
    on the segment or the walk fails."""
    # Rotate around a to the triangle whose opposite edge the segment crosses.
    t0 = star[a]
    t = t0
    found = -1
    for _ in range(len(tri)):
        row = tri[t]
        i = int(np.flatnonzero(row == a)[0])
        u, v = int(row[(i + 1) % 3]), int(row[(i + 2) % 3])
        if u == b or v == b:
            return []
        ou, ov = _orient(p, a, b, u), _orient(p, a, b, v)
        if ou < 0 < ov:  # u right of a->b, v left: the segment leaves through u-v
            found = t
            break
        # Next triangle clockwise around a: across edge (a, u), opposite corner v.
        nt = int(nbr[t, (i + 2) % 3])
        if nt < 0:
            # Hit the hull: go the other way round.
            nt = -1
            break
        t = nt
        if t == t0:
            break
    if found < 0:
        # Counter-clockwise sweep from t0 (needed when a is on the hull).
        t = t0
        for _ in range(len(tri)):
            row = tri[t]
            i = int(np.flatnonzero(row == a)[0])
            u, v = int(row[(i + 1) % 3]), int(row[(i + 2) % 3])
            ou, ov = _orient(p, a, b, u), _orient(p, a, b, v)
            if ou < 0 < ov:
                found = t
                break
            nt = int(nbr[t, (i + 1) % 3])
            if nt < 0 or nt == t0:
                return None
            t = nt
        if found < 0:
            return None
    out = []
    t = found
    row = tri[t]
    i = int(np.flatnonzero(row == a)[0])
    k = i  # the crossed edge of t is opposite corner k
    for _ in range(len(tri)):
        out.append((t, k))
        u, v = int(tri[t, (k + 1) % 3]), int(tri[t, (k + 2) % 3])
        nt = int(nbr[t, k])
        if nt < 0:
            return None
        row = tri[nt]
        w = int(row[~np.isin(row, (u, v))][0])
        if w == b:
            return out
        ow = _orient(p, a, b, w)
        if ow == 0:
            return None  # a node on the segment
        # In nt (counter-clockwise v, u, w), the next crossed edge is (v, w) or (w, u).
        if ow > 0:  # w left of a->b: the segment leaves through u-w, the edge opposite v
            k = int(np.flatnonzero(row == v)[0])
        else:
            k = int(np.flatnonzero(row == u)[0])
        t = nt
    return None


def _flip(tri: IntArray, nbr: IntArray, star: dict[int, int], t: int, k: int) -> tuple[int, int]:
    """Flip the edge opposite corner k of t; return the two triangles (new edge in both)."""
    s = int(nbr[t, k])
    a = int(tri[t, k])
    u, v = int(tri[t, (k + 1) % 3]), int(tri[t, (k + 2) % 3])
    j = int(np.flatnonzero(nbr[s] == t)[0])
    b = int(tri[s, j])
    # Outer neighbours: t across (a,u) is opposite v; across (v,a) is opposite u.
    t_au = int(nbr[t, (k + 2) % 3])
    t_va = int(nbr[t, (k + 1) % 3])
    # s is (b, v, u) counter-clockwise: across (b,v) opposite u; across (u,b) opposite v.
    ju = int(np.flatnonzero(tri[s] == u)[0])
    jv = int(np.flatnonzero(tri[s] == v)[0])
    s_bv = int(nbr[s, ju])
    s_ub = int(nbr[s, jv])
    # New: t = (a, u, b), s = (a, b, v).
    tri[t] = (a, u, b)
    tri[s] = (a, b, v)
    nbr[t] = (s_ub, s, t_au)   # opposite a: (u,b); opposite u: (b,a)=s; opposite b: (a,u)
    nbr[s] = (s_bv, t_va, t)   # opposite a: (b,v); opposite b: (v,a); opposite v: (a,b)=t
    for outer, old, new in ((s_ub, s, t), (t_va, t, s)):
        if outer >= 0:
            nbr[outer][nbr[outer] == old] = new
    for v_, t_ in ((a, t), (u, t), (b, s), (v, s)):
        star[v_] = t_
    return t, s


def _recover_one(p: FloatArray, tri: IntArray, nbr: IntArray, star: dict[int, int], a: int, b: int) -> bool:
    crossed = _crossed(p, tri, nbr, star, a, b)
    if crossed is None:
        return False
    # Edges by their end nodes: (t, k) pairs go stale as flips rewrite triangles.
    queue = [(int(tri[t, (k + 1) % 3]), int(tri[t, (k + 2) % 3])) for t, k in crossed]
    budget = 50 * (len(queue) + 1) ** 2
    while queue and budget > 0:
        budget -= 1
        u, v = queue.pop(0)
        t, k = _find_edge(tri, star, nbr, u, v)
        if t < 0:
            continue
        s = int(nbr[t, k])
        w = int(tri[t, k])
        x = int(tri[s][~np.isin(tri[s], (u, v))][0])
        # Convex quadrilateral w, u, x, v: both diagonals separate the other two nodes.
        if _orient(p, w, x, u) * _orient(p, w, x, v) < 0 and _orient(p, u, v, w) * _orient(p, u, v, x) < 0:
            t, s = _flip(tri, nbr, star, t, k)
            # The new edge is (w, x); it still crosses a-b unless it shares an end with it.
            if w not in (a, b) and x not in (a, b) and _orient(p, a, b, w) * _orient(p, a, b, x) < 0:
                queue.append((w, x))
        else:
            queue.append((u, v))
    return not queue


def _find_edge(tri: IntArray, star: dict[int, int], nbr: IntArray, u: int, v: int) -> tuple[int, int]:
    """A triangle with edge u-v and the corner opposite it, by rotating around u."""
    t0 = star[u]
    for direction in (0, 1):
        t = t0
        for _ in range(len(tri)):
            row = tri[t]
            i = int(np.flatnonzero(row == u)[0])
            if v in (int(row[(i + 1) % 3]), int(row[(i + 2) % 3])):
                k = int(np.flatnonzero(~np.isin(row, (u, v)))[0])
                return t, k
            nt = int(nbr[t, (i + 2) % 3] if direction == 0 else nbr[t, (i + 1) % 3])
            if nt < 0 or nt == t0:
                break
            t = nt
    return -1, -1
