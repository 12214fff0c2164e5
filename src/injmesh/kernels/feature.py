"""Loops of the feature size (:mod:`injmesh.sizing.features`) over boundary polylines.

* :func:`gap_pairs` -- the vertex pairs across a possible gap, :func:`thinnest_gap`'s quick
  first pass (:func:`injmesh.sizing.features.thinnest_gap`).
* :func:`nearest_vertices` -- the k nearest boundary vertices of many points, exactly, and
  :func:`nearest_feet` -- the nearest boundary point among their segments (the feature grid's
  nearest boundary points).
* :func:`gather_feet`, :func:`feature_values` -- the feature grid's per-node steps, the numbers
  of their NumPy form.

The searches bucket the vertices in a uniform grid of cells (:func:`injmesh.kernels.outline._cells`).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .mesh import push_pair
from .outline import _cells, segment_foot
from .raster import ring_cell


@nb.njit(cache=True)
def gap_pairs(v, normal, loop, along, total, width, cos, slack, detour):  # type: ignore[no-untyped-def]
    """Vertex pairs ``i < j`` that may bound a gap: the tests of ``sizing.features._gaps``,
    each loosened by ``slack``, in one pass over the vertices within the width of each other.

    Kept when ``0 < dist < width (1 + slack)`` (``dist = hypot(v_j - v_i)``), the unit
    direction e from i to j has ``e . normal_i > cos - slack`` and ``-e . normal_j > cos -
    slack``, and the boundary between them (along one loop, the shorter way round; infinite
    across loops) is longer than ``detour * dist * (1 - slack)``.  Returns the rows i and j.
    """
    n = v.shape[0]
    out_i = np.empty(16, dtype=np.int64)
    out_j = np.empty(16, dtype=np.int64)
    m = 0
    reach = width * (1.0 + slack)
    if n < 2 or not reach > 0.0:
        return out_i[:0].copy(), out_j[:0].copy()
    cell, order, first, nx, ny = _cells(v, reach)
    for i in range(n):
        cx, cy = cell[i] % nx, cell[i] // nx
        for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
            for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                c = gy * nx + gx
                for kk in range(first[c], first[c + 1]):
                    j = order[kk]
                    if j <= i:
                        continue
                    dx, dy = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1]
                    dist = math.hypot(dx, dy)
                    if not (dist > 0.0 and dist < reach):
                        continue
                    ex, ey = dx / dist, dy / dist
                    if not (ex * normal[i, 0] + ey * normal[i, 1] > cos - slack):
                        continue
                    if not (-(ex * normal[j, 0] + ey * normal[j, 1]) > cos - slack):
                        continue
                    arc = np.inf
                    if loop[i] == loop[j]:
                        arc = abs(along[j] - along[i])
                        arc = min(arc, total[i] - arc)
                    if not (arc > detour * dist * (1.0 - slack)):
                        continue
                    out_i, out_j, m = push_pair(out_i, out_j, m, i, j)
    return out_i[:m].copy(), out_j[:m].copy()


@nb.njit(cache=True, inline="always")
def _k_nearest(px, py, v, order, first, nx, ny, x0, y0, size, kq, max_rings, best_d, best_i):  # type: ignore[no-untyped-def]
    """The ``kq`` nearest of the points ``v`` to ``(px, py)``, nearest first, into ``best_d``
    (squared distances) and ``best_i``, by :func:`nearest_vertices`'s search in rings of cells;
    True when the answer is exact (False: beyond ``max_rings`` rings)."""
    cx = int(math.floor((px - x0) / size))
    cy = int(math.floor((py - y0) / size))
    # Rings beyond this one hold no cell of the grid.
    last = max(max(cx, nx - 1 - cx), max(cy, ny - 1 - cy))
    found = 0
    ring = 0
    while True:
        if ring > last:
            return found == kq  # every cell searched
        if ring > max_rings:
            return False
        for t in range(8 * ring if ring > 0 else 1):
            c = ring_cell(cx, cy, ring, t, nx, ny)
            if c < 0:
                continue
            for kk in range(first[c], first[c + 1]):
                j = order[kk]
                dx, dy = v[j, 0] - px, v[j, 1] - py
                d2 = dx * dx + dy * dy
                if found == kq and d2 >= best_d[kq - 1]:
                    continue
                # Insert in order (ties: the earlier found first).
                s = found if found < kq else kq - 1
                while s > 0 and best_d[s - 1] > d2:
                    best_d[s] = best_d[s - 1]
                    best_i[s] = best_i[s - 1]
                    s -= 1
                best_d[s] = d2
                best_i[s] = j
                if found < kq:
                    found += 1
        # Every cell of the next ring is at least ``ring * size`` from the point (less a
        # margin for the rounding of the cells' bounds).
        reach = ring * size * (1.0 - 1e-9)
        if found == kq and best_d[kq - 1] <= reach * reach:
            return True
        ring += 1


@nb.njit(cache=True)
def nearest_vertices(p, v, k, size, rel, max_rings):  # type: ignore[no-untyped-def]
    """The ``k`` nearest of the points ``v (n, 2)`` to each point of ``p (m, 2)``, nearest first.

    Cells ``size`` wide are searched in square rings round the point's cell until the k-th
    squared distance found is at most that of the ring's inner edge, so the answer is exact
    (``k <= n``).

    Returns ``near (m, k)`` int64 and ``status (m,)`` int8: 0 where ``near`` is the answer;
    1 where two of the k + 1 nearest squared distances are within ``rel`` (relative) of each
    other, so that their order may hinge on rounding; 2 where the point is farther than
    ``max_rings`` rings from its k + 1 nearest (it would cost more here than in a tree).  The
    caller asks a k-d tree for the last two.
    """
    m = p.shape[0]
    n = v.shape[0]
    kq = min(k + 1, n)
    near = np.zeros((m, k), dtype=np.int64)
    status = np.full(m, 2, dtype=np.int8)
    if m == 0 or n == 0 or k > n or not size > 0.0:
        return near, status
    cell, order, first, nx, ny = _cells(v, size)
    x0, y0 = v[:, 0].min(), v[:, 1].min()
    best_d = np.empty(kq)
    best_i = np.empty(kq, dtype=np.int64)
    for q in range(m):
        if not _k_nearest(p[q, 0], p[q, 1], v, order, first, nx, ny, x0, y0, size, kq, max_rings,
                          best_d, best_i):
            continue
        status[q] = 0
        for s in range(kq - 1):
            if best_d[s + 1] - best_d[s] <= rel * best_d[s + 1]:
                status[q] = 1
        for s in range(k):
            near[q, s] = best_i[s]
    return near, status


@nb.njit(cache=True)
def nearest_feet(p, seg_a, seg_b, prev, k, size, rel, max_rings):  # type: ignore[no-untyped-def]
    """The nearest point of the boundary polylines to each point of ``p (m, 2)`` and its
    distance, as :func:`~injmesh.kernels.outline.nearest_of_segments` finds it among the two
    segments at each of the ``k`` nearest vertices (``seg_a[j]`` to ``seg_b[j]`` and
    ``prev[j]``'s), those of :func:`nearest_vertices` in its order.

    Where :func:`nearest_vertices` leaves a point to a k-d tree because two of its k + 1
    nearest squared distances are within ``rel`` of each other (status 1), the answer is given
    here all the same when it cannot depend on how the tree orders them: the near ties are all
    among the k nearest (the (k+1)-th is clearly farther, so the k vertices are the same
    whatever the order, hence the candidate segments too), and every candidate at the least
    distance has the same foot, bit for bit (so whichever comes first is the same answer).

    Returns ``dist (m,)``, ``foot (m, 2)`` and ``status (m,)`` int8: 0 where they are the
    answer; else :func:`nearest_vertices`'s status (1: ties that may matter, 2: beyond its
    rings), the points the caller asks a k-d tree for.
    """
    m = p.shape[0]
    n = seg_a.shape[0]
    kq = min(k + 1, n)
    dist = np.zeros(m)
    foot = np.zeros((m, 2))
    status = np.full(m, 2, dtype=np.int8)
    if m == 0 or n == 0 or k > n or k < 1 or not size > 0.0:
        return dist, foot, status
    cell, order, first, nx, ny = _cells(seg_a, size)
    x0, y0 = seg_a[:, 0].min(), seg_a[:, 1].min()
    best_d = np.empty(kq)
    best_i = np.empty(kq, dtype=np.int64)
    cand = np.empty(2 * k, dtype=np.int64)
    cd = np.empty(2 * k)
    cx = np.empty(2 * k)
    cy = np.empty(2 * k)
    for q in range(m):
        px, py = p[q, 0], p[q, 1]
        if not _k_nearest(px, py, seg_a, order, first, nx, ny, x0, y0, size, kq, max_rings, best_d,
                          best_i):
            continue
        inner = False  # a near tie among the k nearest
        outer = False  # one between the k-th and the (k+1)-th
        for s in range(kq - 1):
            if best_d[s + 1] - best_d[s] <= rel * best_d[s + 1]:
                if s < k - 1:
                    inner = True
                else:
                    outer = True
        if outer:
            status[q] = 1
            continue
        for s in range(k):
            cand[s] = best_i[s]
            cand[k + s] = prev[best_i[s]]
        best = np.inf
        fx, fy = 0.0, 0.0
        for j in range(2 * k):
            c = cand[j]
            d, qx, qy = segment_foot(px, py, seg_a[c, 0], seg_a[c, 1], seg_b[c, 0], seg_b[c, 1])
            cd[j], cx[j], cy[j] = d, qx, qy
            if d < best:
                best, fx, fy = d, qx, qy
        if inner:
            # Every order of the tied vertices gives the first of the candidates at distance
            # ``best``: the same foot only if all of them have it (bits, sign of zero included).
            certain = True
            for j in range(2 * k):
                if cd[j] == best and not (_same_bits(cx[j], fx) and _same_bits(cy[j], fy)):
                    certain = False
            if not certain:
                status[q] = 1
                continue
        status[q] = 0
        dist[q] = best
        foot[q, 0] = fx
        foot[q, 1] = fy
    return dist, foot, status


@nb.njit(cache=True, inline="always")
def _same_bits(a, b):  # type: ignore[no-untyped-def]
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


#: The feature grid's neighbour pairs (a, b = a + (dj, di)): east, north, north-east, north-west.
_PAIRS = ((0, 1), (1, 0), (1, 1), (1, -1))


@nb.njit(cache=True, inline="always")
def _longer(dx, dy, length):  # type: ignore[no-untyped-def]
    """``math.hypot(dx, dy) > length``, from the squares where they decide it with a wide
    margin (relative 1e-9, far above their rounding; no overflow or underflow), else by the
    hypot itself: the same answer, mostly without a hypot."""
    g2 = dx * dx + dy * dy
    l2 = length * length
    if 1e-250 < l2 < 1e250 and g2 < 1e250:
        if g2 > l2 * (1.0 + 1e-9):
            return True
        if g2 < l2 * (1.0 - 1e-9):
            return False
    return math.hypot(dx, dy) > length


@nb.njit(cache=True)
def medial_candidates(x, y, feet, inside, exact, spacing, jump):  # type: ignore[no-untyped-def]
    """The nodes of the feature grid whose approximate nearest boundary points (``feet (ny, nx,
    2)``) jump between neighbours, grown by one node (3 x 3), inside and not ``exact``
    already: those ``sizing.features.feature_grid`` asks exact nearest points for.

    A pair of inside neighbours jumps when its feet are farther apart than
    ``max(jump * spacing, min(r_a, r_b) / 2)`` (r: distance from the node to its foot); the
    same numbers as the NumPy form, node by node.
    """
    ny, nx = inside.shape
    r = np.empty((ny, nx))
    for j in range(ny):
        for i in range(nx):
            r[j, i] = math.hypot(x[i] - feet[j, i, 0], y[j] - feet[j, i, 1])
    cand = np.zeros((ny, nx), dtype=np.bool_)
    floor = jump * spacing
    for dj, di in _PAIRS:
        for j in range(0, ny - dj):
            for i in range(max(0, -di), nx - max(0, di)):
                jb, ib = j + dj, i + di
                if not (inside[j, i] and inside[jb, ib]) or (cand[j, i] and cand[jb, ib]):
                    continue  # (a pair already marked both ways changes nothing)
                dx = feet[j, i, 0] - feet[jb, ib, 0]
                dy = feet[j, i, 1] - feet[jb, ib, 1]
                if _longer(dx, dy, max(floor, 0.5 * min(r[j, i], r[jb, ib]))):
                    cand[j, i] = True
                    cand[jb, ib] = True
    todo = np.zeros((ny, nx), dtype=np.bool_)
    for j in range(ny):
        for i in range(nx):
            if not inside[j, i] or exact[j, i]:
                continue
            hit = False
            for jj in range(max(j - 1, 0), min(j + 2, ny)):
                for ii in range(max(i - 1, 0), min(i + 2, nx)):
                    hit = hit or cand[jj, ii]
            todo[j, i] = hit
    return todo


@nb.njit(cache=True)
def medial_marks(x, y, feet, inside, spacing, limit):  # type: ignore[no-untyped-def]
    """The feature grid's medial-axis nodes, the distance r from each node to its foot, and
    the point where the medial axis crosses each marked node's pair.

    Two neighbours both farther than half a spacing from the boundary and inside mark each
    other when their unit directions from their feet make a dot product below ``limit``; the
    crossing of a marked pair is where the distances to the two walls (planes through the
    feet) are equal, clamped to the pair, and a node keeps the crossing of the last of its
    pairs in the NumPy form's order (direction by direction, the pairs' first nodes, then
    their second).  The same numbers as the NumPy form, node by node.
    """
    ny, nx = inside.shape
    r = np.empty((ny, nx))
    ux = np.zeros((ny, nx))
    uy = np.zeros((ny, nx))
    deep = np.zeros((ny, nx), dtype=np.bool_)
    half = 0.5 * spacing
    for j in range(ny):
        for i in range(nx):
            ex, ey = x[i] - feet[j, i, 0], y[j] - feet[j, i, 1]
            rr = math.hypot(ex, ey)
            r[j, i] = rr
            if rr > 0:
                ux[j, i], uy[j, i] = ex / rr, ey / rr
            deep[j, i] = inside[j, i] and rr > half
    marked = np.zeros((ny, nx), dtype=np.bool_)
    axis = np.zeros((ny, nx, 2))
    cross = np.zeros((ny, nx, 2))
    hit = np.zeros((ny, nx), dtype=np.bool_)
    for dj, di in _PAIRS:
        i0, i1 = max(0, -di), nx - max(0, di)
        for j in range(0, ny - dj):
            for i in range(i0, i1):
                jb, ib = j + dj, i + di
                hit[j, i] = False
                if not (deep[j, i] and deep[jb, ib]):
                    continue
                if not (ux[j, i] * ux[jb, ib] + uy[j, i] * uy[jb, ib] < limit):
                    continue
                hit[j, i] = True
                marked[j, i] = True
                marked[jb, ib] = True
                sx, sy = x[ib] - x[i], y[jb] - y[j]
                grow_a = sx * ux[j, i] + sy * uy[j, i]
                grow_b = -(sx * ux[jb, ib] + sy * uy[jb, ib])
                total = grow_a + grow_b
                t = (r[jb, ib] - r[j, i] + grow_b) / total if total > 0 else 0.5
                t = min(max(t, 0.0), 1.0)
                cross[j, i, 0] = x[i] + t * sx
                cross[j, i, 1] = y[j] + t * sy
        # The pairs' first nodes take their crossings, then the second nodes theirs.
        for j in range(0, ny - dj):
            for i in range(i0, i1):
                if hit[j, i]:
                    axis[j, i, 0], axis[j, i, 1] = cross[j, i, 0], cross[j, i, 1]
        for j in range(0, ny - dj):
            for i in range(i0, i1):
                if hit[j, i]:
                    axis[j + dj, i + di, 0], axis[j + dj, i + di, 1] = cross[j, i, 0], cross[j, i, 1]
    return marked, r, axis


@nb.njit(cache=True)
def gather_feet(feet, jj, ii):  # type: ignore[no-untyped-def]
    """``feet[jj, ii]`` for ``feet (ny, nx, 2)`` and the index grids ``jj, ii (ny, nx)`` of a
    distance transform: each node takes the foot of its nearest seed (a copy, C order)."""
    ny, nx = jj.shape
    out = np.empty((ny, nx, 2))
    for j in range(ny):
        for i in range(nx):
            out[j, i, 0] = feet[jj[j, i], ii[j, i], 0]
            out[j, i, 1] = feet[jj[j, i], ii[j, i], 1]
    return out


@nb.njit(cache=True)
def feature_values(x, y, r, axis, mj, mi, inside, near, min_size, max_size):  # type: ignore[no-untyped-def]
    """The feature size ``2 (r + d_MA)`` at the ``near`` nodes (r negative outside), ``d_MA``
    the distance to the crossing ``axis[mj, mi]`` of the nearest medial-axis node, clipped to
    ``[min_size, max_size]``; ``inf`` at the other nodes.  The numbers of the NumPy form
    (``np.hypot``, then ``np.clip``), node by node."""
    ny, nx = near.shape
    fs = np.full((ny, nx), np.inf)
    for j in range(ny):
        for i in range(nx):
            if not near[j, i]:
                continue
            a, b = mj[j, i], mi[j, i]
            d_ma = math.hypot(x[i] - axis[a, b, 0], y[j] - axis[a, b, 1])
            v = 2.0 * ((r[j, i] if inside[j, i] else -r[j, i]) + d_ma)
            fs[j, i] = min(max(v, min_size), max_size)
    return fs
