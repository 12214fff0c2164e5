"""Kernels over a triangle mesh given as plain arrays: edges, neighbours, measures, inside/outside.

These are the compiled bodies of :mod:`injmesh.quality` and :mod:`injmesh.triangulation`; call
those modules' functions, which validate and normalise their inputs (points ``(n, 2)`` float64
C-contiguous, triangles ``(m, 3)`` int64), so each kernel is compiled for one signature only.

Edges are found without a global sort: each half-edge is filed under its smaller vertex
(counting sort into compressed rows, as a CSR matrix stores its columns) and the few entries of
a row -- a vertex's degree -- are sorted by insertion.  The output is in the order a sort of
``(i, j)`` pairs gives, so it is the same as the ``np.unique`` formulation it replaces, and
linear in the mesh size.

Examples
--------
>>> import numpy as np
>>> from injmesh.kernels.mesh import unique_edges
>>> unique_edges(np.array([[0, 1, 2], [0, 2, 3]]), 4).tolist()
[[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# ---------------------------------------------------------------------------------------------
# Edges and neighbours


@njit(cache=True, inline="always")
def _file(start, fill, other, hid, u, v, h, count):  # type: ignore[no-untyped-def]
    lo = min(u, v)
    if count:
        start[lo + 1] += 1
    else:
        s = fill[lo]
        other[s] = max(u, v)
        hid[s] = h
        fill[lo] = s + 1


@njit(cache=True)
def _rows_by_low_vertex(tri, n):  # type: ignore[no-untyped-def]
    """Half-edges filed by their smaller vertex: (start (n+1,), other end, half-edge id).

    Half-edge ``3 t + k`` is the edge opposite corner k of t: ``tri[t, k+1] -> tri[t, k+2]``.
    Within a row the ids are increasing (counting sort is stable).  The corners are written
    out rather than looped over with ``% 3``: this loop is memory-bound and runs ~10x faster so.
    """
    m = tri.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    other = np.empty(3 * m, dtype=np.int64)
    hid = np.empty(3 * m, dtype=np.int64)
    fill = start
    for t in range(m):
        a = tri[t, 0]
        b = tri[t, 1]
        c = tri[t, 2]
        _file(start, fill, other, hid, b, c, 3 * t, True)
        _file(start, fill, other, hid, c, a, 3 * t + 1, True)
        _file(start, fill, other, hid, a, b, 3 * t + 2, True)
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:n].copy()
    for t in range(m):
        a = tri[t, 0]
        b = tri[t, 1]
        c = tri[t, 2]
        _file(start, fill, other, hid, b, c, 3 * t, False)
        _file(start, fill, other, hid, c, a, 3 * t + 1, False)
        _file(start, fill, other, hid, a, b, 3 * t + 2, False)
    return start, other, hid


@njit(cache=True)
def edge_index(tri, n):  # type: ignore[no-untyped-def]
    """Distinct edges ``(k, 2)`` (i < j, sorted) and the edge of each half-edge ``(3 m,)``.

    ``edge_of[3 t + k]`` is the row of ``edges`` holding the side opposite corner k of t.
    """
    start, other, hid = _rows_by_low_vertex(tri, n)
    # Insertion sort of each row by (other end, half-edge id): rows are a vertex's degree long.
    for v in range(n):
        for s in range(start[v] + 1, start[v + 1]):
            o = other[s]
            h = hid[s]
            r = s - 1
            while r >= start[v] and (other[r] > o or (other[r] == o and hid[r] > h)):
                other[r + 1] = other[r]
                hid[r + 1] = hid[r]
                r -= 1
            other[r + 1] = o
            hid[r + 1] = h
    count = 0
    for v in range(n):
        for s in range(start[v], start[v + 1]):
            if s == start[v] or other[s] != other[s - 1]:
                count += 1
    edges = np.empty((count, 2), dtype=np.int64)
    edge_of = np.empty(other.shape[0], dtype=np.int64)
    e = -1
    for v in range(n):
        for s in range(start[v], start[v + 1]):
            if s == start[v] or other[s] != other[s - 1]:
                e += 1
                edges[e, 0] = v
                edges[e, 1] = other[s]
            edge_of[hid[s]] = e
    return edges, edge_of


@njit(cache=True)
def unusual_edges(tri, n):  # type: ignore[no-untyped-def]
    """The edges that are not run along once each way: ``(k, 2)`` (i < j, sorted), and how many
    triangles run along each from i to j (``forward``) and from j to i (``backward``).

    In a valid mesh these are the boundary edges (``forward + backward == 1``); a count above 1
    in one direction is two triangles overlapping on that side.  The ordinary edges (one
    triangle each way: almost all of them) are counted in the short rows of half-edges filed
    under their smaller vertex and never listed, so no edge list of the whole mesh is built.
    """
    start, other, hid = _rows_by_low_vertex(tri, n)
    cap = 16
    out = np.empty((cap, 4), dtype=np.int64)
    k = 0
    for v in range(n):
        row0 = k
        for s in range(start[v], start[v + 1]):
            o = other[s]
            seen = False
            for r in range(start[v], s):
                if other[r] == o:
                    seen = True
                    break
            if seen:
                continue
            fwd = 0
            bwd = 0
            for r in range(s, start[v + 1]):
                if other[r] == o:
                    h = hid[r]
                    t = h // 3
                    if tri[t, (h - 3 * t + 1) % 3] == v:
                        fwd += 1
                    else:
                        bwd += 1
            if fwd == 1 and bwd == 1:
                continue
            if k == cap:
                cap *= 2
                grown = np.empty((cap, 4), dtype=np.int64)
                grown[:k] = out[:k]
                out = grown
            # Insertion into this vertex's run, kept sorted by the other end.
            r = k
            while r > row0 and out[r - 1, 1] > o:
                out[r] = out[r - 1]
                r -= 1
            out[r, 0] = v
            out[r, 1] = o
            out[r, 2] = fwd
            out[r, 3] = bwd
            k += 1
    return out[:k, :2].copy(), out[:k, 2].copy(), out[:k, 3].copy()


@njit(cache=True, inline="always")
def push_pair(out_a, out_b, count, i, j):  # type: ignore[no-untyped-def]
    """Append the pair (i, j) at ``count``, doubling the arrays when full; the arrays and the
    new count."""
    if count == out_a.shape[0]:
        out_a = np.concatenate((out_a, np.empty(max(count, 1), dtype=np.int64)))
        out_b = np.concatenate((out_b, np.empty(max(count, 1), dtype=np.int64)))
    out_a[count] = i
    out_b[count] = j
    return out_a, out_b, count + 1


@njit(cache=True)
def close_pairs(pts, cell, order, eps):  # type: ignore[no-untyped-def]
    """Pairs of points closer than ``eps`` in both coordinates.

    ``cell[i]`` is ``floor(x_i / eps)`` (relative to any origin) and ``order`` sorts the points
    by (cell, y).  A point's partners lie in its own cell or the next one, within eps in y:
    a forward scan in its own cell and a binary search in the next, so the cost is about
    ``n log n`` even on lattices whose columns share (nearly) one x.
    """
    n = order.shape[0]
    out_a = np.empty(16, dtype=np.int64)
    out_b = np.empty(16, dtype=np.int64)
    count = 0
    # end[r]: one past the last rank of rank r's cell.
    end = np.empty(n, dtype=np.int64)
    last = n
    for r in range(n - 1, -1, -1):
        if r + 1 < n and cell[order[r + 1]] != cell[order[r]]:
            last = r + 1
        end[r] = last
    for r in range(n):
        i = order[r]
        xi = pts[i, 0]
        yi = pts[i, 1]
        c = cell[i]
        lo = r + 1
        hi = end[r]
        for step in range(2):
            s = lo
            while s < hi:
                j = order[s]
                if pts[j, 1] - yi > eps:
                    break
                if abs(pts[j, 0] - xi) <= eps and abs(pts[j, 1] - yi) <= eps:
                    out_a, out_b, count = push_pair(out_a, out_b, count, i, j)
                s += 1
            if step == 1 or end[r] >= n or cell[order[end[r]]] != c + 1:
                break
            # The next cell: its points from y_i - eps on (binary search over its y order).
            lo = end[r]
            hi = end[lo]
            a, b = lo, hi
            while a < b:
                mid = (a + b) // 2
                if pts[order[mid], 1] < yi - eps:
                    a = mid + 1
                else:
                    b = mid
            lo = a
    pairs = np.empty((count, 2), dtype=np.int64)
    pairs[:, 0] = out_a[:count]
    pairs[:, 1] = out_b[:count]
    return pairs


@njit(cache=True)
def close_pairs_binned(pts, eps, max_work):  # type: ignore[no-untyped-def]
    """Pairs ``(i, j)``, ``i < j``, of points closer than ``eps`` in both coordinates, found
    in square bins about one point wide (at least ``2 eps``): a point's partners lie in its
    own bin or, if it is that close to a side, in the bins beyond.  Linear in the number of
    points when they are spread out like mesh nodes, with no sort.

    Returns the pairs and True, or no pairs and False when the bins would cost more than
    ``max_work`` comparisons (points crowded into a few bins): :func:`close_pairs` then.
    """
    n = pts.shape[0]
    empty = np.empty((0, 2), dtype=np.int64)
    xmin, xmax, ymin, ymax = pts[0, 0], pts[0, 0], pts[0, 1], pts[0, 1]
    for i in range(n):
        xmin = min(xmin, pts[i, 0])
        xmax = max(xmax, pts[i, 0])
        ymin = min(ymin, pts[i, 1])
        ymax = max(ymax, pts[i, 1])
    w = max(math.sqrt(max((xmax - xmin) * (ymax - ymin), 0.0) / n), 2.0 * eps)
    if not (w > 0.0 and math.isfinite(w)):
        return empty, False
    nx = min(int((xmax - xmin) / w) + 1, 4 * n + 1)
    ny = min(int((ymax - ymin) / w) + 1, (4 * n) // nx + 1)
    # Bins capped in number stay at least w wide, so partners are still in adjacent bins.
    wx = max(w, (xmax - xmin) / nx * (1.0 + 1e-12))
    wy = max(w, (ymax - ymin) / ny * (1.0 + 1e-12))
    bx = np.empty(n, dtype=np.int64)
    by = np.empty(n, dtype=np.int64)
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    for i in range(n):
        bx[i] = min(int((pts[i, 0] - xmin) / wx), nx - 1)
        by[i] = min(int((pts[i, 1] - ymin) / wy), ny - 1)
        start[by[i] * nx + bx[i] + 1] += 1
    work = 0
    for b in range(nx * ny):
        work += start[b + 1] * start[b + 1]
        start[b + 1] += start[b]
    if work > max_work:
        return empty, False
    fill = start[:-1].copy()
    member = np.empty(n, dtype=np.int64)
    for i in range(n):
        b = by[i] * nx + bx[i]
        member[fill[b]] = i
        fill[b] += 1
    out_a = np.empty(16, dtype=np.int64)
    out_b = np.empty(16, dtype=np.int64)
    count = 0
    # A point more than 2 eps (rounding to spare) from a side of its bin has no partner beyond
    # it: most points look in their own bin only.
    mx = 2.0 * eps / wx
    my = 2.0 * eps / wy
    for i in range(n):
        xi = pts[i, 0]
        yi = pts[i, 1]
        fx = (xi - xmin) / wx - bx[i]
        fy = (yi - ymin) / wy - by[i]
        j_lo = by[i] - 1 if fy < my else by[i]
        j_hi = by[i] + 1 if fy > 1.0 - my else by[i]
        i_lo = bx[i] - 1 if fx < mx else bx[i]
        i_hi = bx[i] + 1 if fx > 1.0 - mx else bx[i]
        for j_bin in range(max(j_lo, 0), min(j_hi, ny - 1) + 1):
            for i_bin in range(max(i_lo, 0), min(i_hi, nx - 1) + 1):
                b = j_bin * nx + i_bin
                for s in range(start[b], start[b + 1]):
                    j = member[s]
                    if j <= i:
                        continue
                    if abs(pts[j, 0] - xi) <= eps and abs(pts[j, 1] - yi) <= eps:
                        out_a, out_b, count = push_pair(out_a, out_b, count, i, j)
    pairs = np.empty((count, 2), dtype=np.int64)
    pairs[:, 0] = out_a[:count]
    pairs[:, 1] = out_b[:count]
    return pairs, True


@njit(cache=True)
def edges_present(tri, pairs, n):  # type: ignore[no-untyped-def]
    """Whether each row (i, j) of ``pairs`` is a side of some triangle of ``tri``.

    The pairs are filed under their smaller node (few rows: boundary segments), then every
    triangle side whose smaller node has a row is looked up there: one pass over the
    triangles, no adjacency of the whole mesh.
    """
    k = pairs.shape[0]
    start, row = _filed_pairs(pairs, n)
    found = np.zeros(k, dtype=np.bool_)
    for t in range(tri.shape[0]):
        for c in range(3):
            u = tri[t, c]
            v = tri[t, (c + 1) % 3]
            lo = min(u, v)
            hi = max(u, v)
            for s in range(start[lo], start[lo + 1]):
                r = row[s]
                if max(pairs[r, 0], pairs[r, 1]) == hi:
                    found[r] = True
    return found


@njit(cache=True)
def unique_edges(tri, n):  # type: ignore[no-untyped-def]
    """Distinct edges ``(k, 2)`` with i < j, sorted by (i, j)."""
    return edge_index(tri, n)[0]


@njit(cache=True)
def rows_with(tri, mark):  # type: ignore[no-untyped-def]
    """The rows of ``tri`` (in order) that hold a node flagged in ``mark``: one pass, where
    ``mark[tri].any(axis=1)`` gathers a flag per corner into a temporary first."""
    m = tri.shape[0]
    out = np.empty(m, dtype=np.int64)
    k = 0
    for t in range(m):
        if mark[tri[t, 0]] or mark[tri[t, 1]] or mark[tri[t, 2]]:
            out[k] = t
            k += 1
    return out[:k].copy()


@njit(cache=True)
def neighbours(tri, n):  # type: ignore[no-untyped-def]
    """Triangle across the edge opposite each corner, ``(m, 3)``, -1 where there is none.

    The twin of half-edge u -> v is a half-edge v -> u.  Both are filed under the smaller of
    u and v, so twins meet in one short row (memory is touched once per half-edge at random,
    then row by row).  In an invalid mesh with several copies of a directed edge, each twin is
    paired once, in triangle order; the copies left over keep -1.
    """
    m = tri.shape[0]
    start, other, hid = _rows_by_low_vertex(tri, n)
    nbr = np.full((m, 3), -1, dtype=np.int64)
    for v in range(n):
        for s in range(start[v], start[v + 1]):
            h = hid[s]
            th = h // 3
            kh = h - 3 * th
            if nbr[th, kh] >= 0:
                continue
            forward = tri[th, (kh + 1) % 3] == v  # h runs v -> other
            for r in range(s + 1, start[v + 1]):
                if other[r] != other[s]:
                    continue
                g = hid[r]
                tg = g // 3
                kg = g - 3 * tg
                if nbr[tg, kg] >= 0 or (tri[tg, (kg + 1) % 3] == v) == forward:
                    continue
                nbr[th, kh] = tg
                nbr[tg, kg] = th
                break
    return nbr


@njit(cache=True)
def by_least_vertex(tri, n):  # type: ignore[no-untyped-def]
    """The rows of ``tri`` ordered by their least vertex, ties in row order: what
    ``np.argsort(tri.min(axis=1), kind="stable")`` gives, by a counting sort (linear in the
    rows; vertices ``0 .. n-1``)."""
    m = tri.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for t in range(m):
        start[min(tri[t, 0], tri[t, 1], tri[t, 2]) + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    order = np.empty(m, dtype=np.int64)
    for t in range(m):
        v = min(tri[t, 0], tri[t, 1], tri[t, 2])
        order[start[v]] = t
        start[v] += 1
    return order


@njit(cache=True)
def kept_neighbours(nbr, rows):  # type: ignore[no-untyped-def]
    """The neighbour table (int32) of the triangles ``rows`` of a triangulation, in that order,
    from the whole triangulation's table ``nbr``: across each edge the other triangle's place
    in ``rows``, -1 where it is not among them (or where there is none).

    Each edge of a triangulation has at most two triangles, so this is :func:`neighbours` of
    the triangles kept, without finding the twins again."""
    pos = np.full(nbr.shape[0], -1, dtype=np.int32)
    for a in range(rows.shape[0]):
        pos[rows[a]] = a
    out = np.empty((rows.shape[0], 3), dtype=np.int32)
    for a in range(rows.shape[0]):
        t = rows[a]
        for k in range(3):
            u = nbr[t, k]
            out[a, k] = pos[u] if u >= 0 else -1
    return out


@njit(cache=True)
def boundary_edges(tri, n):  # type: ignore[no-untyped-def]
    """Edges in exactly one triangle, oriented as there; in the order sides (0,1), (1,2),
    (2,0) of all triangles (the order of the concatenation it replaces)."""
    m = tri.shape[0]
    _, edge_of = edge_index(tri, n)
    count = np.zeros(edge_of.shape[0], dtype=np.int64)
    for h in range(edge_of.shape[0]):
        count[edge_of[h]] += 1
    # Side (0,1) is opposite corner 2, (1,2) opposite 0, (2,0) opposite 1.
    total = 0
    for h in range(edge_of.shape[0]):
        if count[edge_of[h]] == 1:
            total += 1
    out = np.empty((total, 2), dtype=np.int64)
    r = 0
    for c in (2, 0, 1):
        for t in range(m):
            if count[edge_of[3 * t + c]] == 1:
                out[r, 0] = tri[t, (c + 1) % 3]
                out[r, 1] = tri[t, (c + 2) % 3]
                r += 1
    return out


# ---------------------------------------------------------------------------------------------
# Measures


@njit(cache=True)
def signed_areas(pts, tri):  # type: ignore[no-untyped-def]
    m = tri.shape[0]
    out = np.empty(m, dtype=np.float64)
    for t in range(m):
        a = tri[t, 0]
        b = tri[t, 1]
        c = tri[t, 2]
        ux = pts[b, 0] - pts[a, 0]
        uy = pts[b, 1] - pts[a, 1]
        vx = pts[c, 0] - pts[a, 0]
        vy = pts[c, 1] - pts[a, 1]
        out[t] = 0.5 * (ux * vy - uy * vx)
    return out


@njit(cache=True, inline="always")
def _length(pts, i, j):  # type: ignore[no-untyped-def]
    # sqrt of the sum of squares, not math.hypot: numba's hypot is ~40x slower, and mesh
    # coordinates are far from overflow.
    dx = pts[j, 0] - pts[i, 0]
    dy = pts[j, 1] - pts[i, 1]
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def edge_lengths(pts, tri):  # type: ignore[no-untyped-def]
    """Column k: length of the side opposite vertex k."""
    m = tri.shape[0]
    out = np.empty((m, 3), dtype=np.float64)
    for t in range(m):
        for k in range(3):
            out[t, k] = _length(pts, tri[t, (k + 1) % 3], tri[t, (k + 2) % 3])
    return out


@njit(cache=True)
def triangle_quality(pts, tri):  # type: ignore[no-untyped-def]
    """Eq. (5.1), 0 where a side has length 0."""
    m = tri.shape[0]
    out = np.empty(m, dtype=np.float64)
    for t in range(m):
        p0 = tri[t, 0]
        p1 = tri[t, 1]
        p2 = tri[t, 2]
        a = _length(pts, p1, p2)
        b = _length(pts, p2, p0)
        c = _length(pts, p0, p1)
        den = a * b * c
        if den == 0.0 or not math.isfinite(den):
            out[t] = 0.0
        else:
            out[t] = (b + c - a) * (c + a - b) * (a + b - c) / den
    return out


@njit(cache=True)
def centroids_and_flatness(pts, tri, flat):  # type: ignore[no-untyped-def]
    """Centroids ``(m, 2)``, longest side squared ``(m,)`` and whether each triangle is flat:
    ``|area| <= flat * longest^2``."""
    m = tri.shape[0]
    cen = np.empty((m, 2), dtype=np.float64)
    longest2 = np.empty(m, dtype=np.float64)
    is_flat = np.empty(m, dtype=np.bool_)
    for t in range(m):
        a = tri[t, 0]
        b = tri[t, 1]
        c = tri[t, 2]
        cen[t, 0] = (pts[a, 0] + pts[b, 0] + pts[c, 0]) / 3.0
        cen[t, 1] = (pts[a, 1] + pts[b, 1] + pts[c, 1]) / 3.0
        best = 0.0
        for k in range(3):
            i = tri[t, k]
            j = tri[t, (k + 1) % 3]
            dx = pts[i, 0] - pts[j, 0]
            dy = pts[i, 1] - pts[j, 1]
            best = max(best, dx * dx + dy * dy)
        longest2[t] = best
        ux = pts[b, 0] - pts[a, 0]
        uy = pts[b, 1] - pts[a, 1]
        vx = pts[c, 0] - pts[a, 0]
        vy = pts[c, 1] - pts[a, 1]
        is_flat[t] = abs(0.5 * (ux * vy - uy * vx)) <= flat * best
    return cen, longest2, is_flat


# ---------------------------------------------------------------------------------------------
# Inside / outside


@njit(cache=True)
def classify_by_walls(tri, nbr, walls, n):  # type: ignore[no-untyped-def]
    """Flood fill of triangles across non-wall edges; see ``triangulation.classify_by_walls``.

    Returns (inside, open) boolean arrays.
    """
    m = tri.shape[0]
    # Per half-edge: is it a wall, and is the triangle on a wall's left (+1) or right (-1)?
    is_wall, left, right, _, _ = _on_pairs(tri, walls, n)
    # Connected regions across non-wall edges, labelled in order of their lowest triangle.
    label, n_lab = _flood(nbr, is_wall)
    seen_in = np.zeros(n_lab, dtype=np.bool_)
    seen_out = np.zeros(n_lab, dtype=np.bool_)
    for t in range(m):
        if left[t]:
            seen_in[label[t]] = True
        if right[t]:
            seen_out[label[t]] = True
    any_in = False
    for r in range(n_lab):
        any_in = any_in or seen_in[r]
    inside = np.empty(m, dtype=np.bool_)
    open_ = np.empty(m, dtype=np.bool_)
    for t in range(m):
        r = label[t]
        inside[t] = seen_in[r] and not seen_out[r]
        op = seen_in[r] == seen_out[r]
        # A region touching no wall lies beyond the walls (outside), unless no region touches
        # a wall from inside at all.
        if any_in and not seen_in[r] and not seen_out[r]:
            op = False
        open_[t] = op
    return inside, open_


@njit(cache=True)
def inside_polygon(q, a, b):  # type: ignore[no-untyped-def]
    """Even-odd test of points q against the segments a[i] -> b[i].

    A segment changes the parity of a point at height y only when y lies in its y-range, so the
    segments are listed in horizontal strips (each in every strip its closed y-range touches;
    about four entries per segment in all) and a point tests only those of its own strip, with
    the same crossing test as the plain loop over all segments: the same answers in
    O(segments in a strip) per point.  The strip of a height is a monotone function of it, so
    a segment is never missed at a strip border.
    """
    n, m = q.shape[0], a.shape[0]
    out = np.zeros(n, dtype=np.bool_)
    if m == 0 or n == 0:
        return out
    y0 = min(a[:, 1].min(), b[:, 1].min())
    y1 = max(a[:, 1].max(), b[:, 1].max())
    # About 4 m strip entries in all: a strip per segment, fewer when segments are tall.
    tall = 0.0
    for i in range(m):
        tall += abs(b[i, 1] - a[i, 1])
    n_strips = 1
    if y1 > y0 and tall > 0.0:
        n_strips = int(min(float(m), max(1.0, 4.0 * m * (y1 - y0) / tall)))
    inv = n_strips / (y1 - y0) if y1 > y0 else 0.0
    lo = np.empty(m, dtype=np.int64)
    hi = np.empty(m, dtype=np.int64)
    count = np.zeros(n_strips + 1, dtype=np.int64)
    for i in range(m):
        lo[i] = _strip(min(a[i, 1], b[i, 1]), y0, inv, n_strips)
        hi[i] = _strip(max(a[i, 1], b[i, 1]), y0, inv, n_strips)
        for k in range(lo[i], hi[i] + 1):
            count[k + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    seg = np.empty(start[-1], dtype=np.int64)
    for i in range(m):  # increasing i within each strip: the plain loop's order
        for k in range(lo[i], hi[i] + 1):
            seg[fill[k]] = i
            fill[k] += 1
    for s in range(n):
        x = q[s, 0]
        y = q[s, 1]
        k = _strip(y, y0, inv, n_strips)
        odd = False
        for j in range(start[k], start[k + 1]):
            i = seg[j]
            if (a[i, 1] > y) != (b[i, 1] > y):
                xint = a[i, 0] + (y - a[i, 1]) * (b[i, 0] - a[i, 0]) / (b[i, 1] - a[i, 1])
                if x < xint:
                    odd = not odd
        out[s] = odd
    return out


@njit(cache=True, inline="always")
def _strip(y, y0, inv, n_strips):  # type: ignore[no-untyped-def]
    """The strip of height y: floor((y - y0) * inv) clamped to 0 .. n_strips - 1 (monotone)."""
    t = (y - y0) * inv
    if not t > 0.0:  # below, at y0, or NaN
        return 0
    if t >= n_strips:
        return n_strips - 1
    return int(t)


@njit(cache=True)
def renew_neighbours(tri, nbr, rows):  # type: ignore[no-untyped-def]
    """Update :func:`neighbours`' table ``nbr`` in place after the triangles of ``rows`` were
    replaced by others covering the same region (flips inside a patch whose outline stayed).

    ``nbr`` still holds the old entries: the triangles outside ``rows`` that touched them are
    found there.  Each side of a triangle of ``rows`` is paired with its twin among those
    triangles and ``rows``; the outside triangles' entries that pointed into ``rows`` are
    paired again.  The cost follows ``len(rows)``, not the mesh.
    """
    m = tri.shape[0]
    inr = np.zeros(m, dtype=np.bool_)
    for r in rows:
        inr[r] = True
    seen = np.zeros(m, dtype=np.bool_)
    outs = np.empty(3 * rows.shape[0], dtype=np.int64)
    no = 0
    for r in rows:
        for k in range(3):
            u = nbr[r, k]
            if u >= 0 and not inr[u] and not seen[u]:
                seen[u] = True
                outs[no] = u
                no += 1
    s = np.concatenate((rows.astype(np.int64), outs[:no]))
    top = 0
    for t in s:
        for k in range(3):
            top = max(top, tri[t, k])
    base = np.int64(top) + 1
    keys = np.empty(3 * s.shape[0], dtype=np.int64)
    for a in range(s.shape[0]):
        t = s[a]
        for k in range(3):
            keys[3 * a + k] = np.int64(tri[t, (k + 1) % 3]) * base + tri[t, (k + 2) % 3]
    order = np.argsort(keys)
    sk = keys[order]
    for a in range(s.shape[0]):
        t = s[a]
        for k in range(3):
            if not inr[t] and (nbr[t, k] < 0 or not inr[nbr[t, k]]):
                continue  # an outside triangle's side that never touched the patch
            twin = np.int64(tri[t, (k + 2) % 3]) * base + tri[t, (k + 1) % 3]
            j = np.searchsorted(sk, twin)
            nbr[t, k] = s[order[j] // 3] if j < sk.shape[0] and sk[j] == twin else -1


@njit(cache=True)
def curve_groups(tri, nbr, seg, n):  # type: ignore[no-untyped-def]
    """Triangles grouped by flood fill across every edge that is not a segment of ``seg``,
    and the triangle on each segment's left (holding a -> b) and right (b -> a), -1 if none.

    Returns (label (m,), number of groups, left (k,), right (k,)); groups are numbered in
    order of their lowest triangle.
    """
    barrier, _, _, left, right = _on_pairs(tri, seg, n)
    label, n_lab = _flood(nbr, barrier)
    return label, n_lab, left, right


@njit(cache=True)
def _filed_pairs(pairs, n):  # type: ignore[no-untyped-def]
    """Rows of ``pairs (k, 2)`` filed under their smaller vertex: (start (n+1,), row ids)."""
    w = pairs.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(w):
        start[min(pairs[i, 0], pairs[i, 1]) + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:n].copy()
    ids = np.empty(w, dtype=np.int64)
    for i in range(w):
        lo = min(pairs[i, 0], pairs[i, 1])
        ids[fill[lo]] = i
        fill[lo] += 1
    return start, ids


@njit(cache=True)
def _on_pairs(tri, pairs, n):  # type: ignore[no-untyped-def]
    """Which half-edges of ``tri`` are rows of ``pairs (k, 2)`` (either way): (flags (m, 3),
    triangles holding a pair a -> b (m,), holding b -> a (m,), the last triangle holding each
    row a -> b (k,), b -> a (k,), -1 if none)."""
    m = tri.shape[0]
    start, ids = _filed_pairs(pairs, n)
    on = np.zeros((m, 3), dtype=np.bool_)
    left = np.zeros(m, dtype=np.bool_)
    right = np.zeros(m, dtype=np.bool_)
    left_of = np.full(pairs.shape[0], -1, dtype=np.int64)
    right_of = np.full(pairs.shape[0], -1, dtype=np.int64)
    for t in range(m):
        for k in range(3):
            u = tri[t, (k + 1) % 3]
            v = tri[t, (k + 2) % 3]
            lo = min(u, v)
            for s in range(start[lo], start[lo + 1]):
                i = ids[s]
                if pairs[i, 0] == u and pairs[i, 1] == v:
                    on[t, k] = True
                    left[t] = True
                    left_of[i] = t
                elif pairs[i, 0] == v and pairs[i, 1] == u:
                    on[t, k] = True
                    right[t] = True
                    right_of[i] = t
    return on, left, right, left_of, right_of


@njit(cache=True)
def _flood(nbr, barrier):  # type: ignore[no-untyped-def]
    """Triangles labelled by flood fill across the edges not flagged in ``barrier (m, 3)``, in
    order of their lowest triangle: (label (m,), number of labels)."""
    m = nbr.shape[0]
    label = np.full(m, -1, dtype=np.int64)
    stack = np.empty(m, dtype=np.int64)
    n_lab = 0
    for seed in range(m):
        if label[seed] >= 0:
            continue
        label[seed] = n_lab
        sp = 1
        stack[0] = seed
        while sp > 0:
            sp -= 1
            t = stack[sp]
            for k in range(3):
                u = nbr[t, k]
                if u >= 0 and not barrier[t, k] and label[u] < 0:
                    label[u] = n_lab
                    stack[sp] = u
                    sp += 1
        n_lab += 1
    return label, n_lab
