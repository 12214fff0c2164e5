"""Loops over boundary polylines: merging close vertices, and walls that face each other.

:func:`merge_close` is the sequential pass of polygon cleaning
(:meth:`injmesh.geometry.Polygon.cleaned`).

:func:`facing_walls` is the kernel behind :func:`injmesh.sizing.thick_everywhere`.  A
boundary given as closed polylines (vertex ``k`` starts segment ``k``, which ends at vertex
``nxt[k]``) is searched for a vertex v and a segment s, with an end point of s within
``radius`` of v, whose foot f (the nearest point of s to v) is closer than a width and lies in
a given cone about v's normal.
Candidate pairs come from a uniform grid of cells ``radius`` wide (each vertex looks at its own
and the eight surrounding cells), so the cost is the number of vertex pairs within ``radius``,
with nothing stored per pair (a detailed outline has hundreds per vertex).

:func:`corner_cones` is the cap of :func:`injmesh.boundary.corner_size`:
``min(h(p), min_c (s_c + rate |p - c|))`` over *every* corner c, equal bit for bit to the
brute-force minimum (so rate-Lipschitz wherever h is), on the structure :func:`cone_index`
builds once: a k-d tree of the corners whose nodes know their least spacing (a node whose
``least spacing + rate * distance`` cannot beat the value so far is skipped), and a grid whose
cells keep a lower bound of the cones over them (a point no cone can reach is done at once), a
seed corner (a near-final first value) and the list of the tree's leaves that can hold the
minimum somewhere in the cell, so that a point walks a few leaves instead of the tree.  A leaf
is read whole, without a branch per corner (its corners are packed in padded rows the compiler
vectorizes), and a point starts from the leaf that held its predecessor's minimum: the points
of a batch come in mesh order, so that leaf is nearly always the answer and the walk stops at
the first few list entries.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from . import threads
from .mesh import push_pair

_TINY = np.finfo(np.float64).tiny


@nb.njit(cache=True)
def merge_close(v, tolerance):  # type: ignore[no-untyped-def]
    """Indices of the vertices of ring ``v (n, 2)`` kept when runs of close vertices merge.

    Walking the ring from vertex 0, a vertex closer than ``tolerance`` to the last kept one
    joins it (the first of a run is kept); then kept vertices at the end of the ring closer
    than ``tolerance`` to vertex 0 are dropped (at least one vertex stays).
    """
    n = v.shape[0]
    keep = np.empty(max(n, 1), dtype=np.int64)
    keep[0] = 0
    m = 1
    for i in range(1, n):
        k = keep[m - 1]
        if math.hypot(v[i, 0] - v[k, 0], v[i, 1] - v[k, 1]) >= tolerance:
            keep[m] = i
            m += 1
    while m > 1 and math.hypot(v[keep[m - 1], 0] - v[0, 0], v[keep[m - 1], 1] - v[0, 1]) < tolerance:
        m -= 1
    return keep[:m].copy()


@nb.njit(cache=True)
def _cells(v, size):  # type: ignore[no-untyped-def]
    """A uniform grid of cells ``size`` wide over points ``v (n, 2)``: the cell of each point,
    the points in cell order and where each cell's run starts (``nx * ny + 1`` entries)."""
    n = v.shape[0]
    x0, y0 = v[:, 0].min(), v[:, 1].min()
    nx = int((v[:, 0].max() - x0) / size) + 1
    ny = int((v[:, 1].max() - y0) / size) + 1
    cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        cell[i] = int((v[i, 1] - y0) / size) * nx + int((v[i, 0] - x0) / size)
    order = np.argsort(cell, kind="mergesort")
    first = np.full(nx * ny + 1, n, dtype=np.int64)
    for k in range(n - 1, -1, -1):
        first[cell[order[k]]] = k
    for c in range(nx * ny - 1, -1, -1):
        if first[c] == n:
            first[c] = first[c + 1]
    return cell, order, first, nx, ny


@nb.njit(cache=True)
def facing_walls(v, prv, seg, seg_len, v_n, seg_n, radius, width, back_to_back, cos,
                 first_only):  # type: ignore[no-untyped-def]
    """Vertices and segments facing each other closer than ``width``.

    For every pair of vertices i < j with ``|v_i - v_j| <= radius`` (squared distances
    compared with ``radius**2``), both ways round (vertex a, partner b), and both segments at
    the partner (s = b and s = ``prv[b]``, segment k running from ``v[k]`` along ``seg[k]``),
    unless s is one of a's own segments: the foot f of ``v[a]`` on s, the distance
    ``dist = |f - v[a]|`` and the unit direction ``e`` from a to f.

    * *back to back*: ``0 < dist < back_to_back``, ``e . v_n[a] < -cos`` and
      ``e . seg_n[s] > cos`` (s behind a's wall, facing away from it);
    * *facing*: ``0 < dist < width``, ``e . v_n[a] > cos`` and ``-e . seg_n[s] > cos``.

    Returns
    -------
    behind : bool
        Some vertex and segment are back to back (the search stops there).
    a : (k,) int array, foot : (k, 2) array, dist : (k,) array
        The facing vertex-segment pairs: the vertex, the foot on the segment, the distance
        (empty when ``behind``), in no particular order.  With ``first_only`` the search stops
        at the first facing pair (a back-to-back pair later in the search is then not looked
        for).
    """
    out_a = np.empty(64, dtype=np.int64)
    out_f = np.empty((64, 2))
    out_d = np.empty(64)
    m = 0
    n = v.shape[0]
    if n < 2 or not radius > 0.0:
        return False, out_a[:0].copy(), out_f[:0].copy(), out_d[:0].copy()
    cell, order, first, nx, ny = _cells(v, radius)
    r2 = radius * radius
    for i in range(n):
        cx, cy = cell[i] % nx, cell[i] // nx
        for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
            for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
                c = gy * nx + gx
                for kk in range(first[c], first[c + 1]):
                    j = order[kk]
                    dx, dy = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1]
                    if j <= i or not dx * dx + dy * dy <= r2:
                        continue
                    for q in range(4):  # a and b both ways round, both segments at b
                        a, b = (i, j) if q < 2 else (j, i)
                        s = b if q % 2 == 0 else prv[b]
                        if s == a or s == prv[a]:
                            continue
                        kind, fx, fy, dist = _judge(a, s, v, seg, seg_len, v_n, seg_n, width,
                                                    back_to_back, cos)
                        if kind == 1:
                            return True, out_a[:0].copy(), out_f[:0].copy(), out_d[:0].copy()
                        if kind == 2:
                            if m == len(out_a):
                                out_a = np.concatenate((out_a, np.empty(m, dtype=np.int64)))
                                out_f = np.concatenate((out_f, np.empty((m, 2))))
                                out_d = np.concatenate((out_d, np.empty(m)))
                            out_a[m] = a
                            out_f[m, 0], out_f[m, 1] = fx, fy
                            out_d[m] = dist
                            m += 1
                            if first_only:
                                return False, out_a[:m].copy(), out_f[:m].copy(), out_d[:m].copy()
    return False, out_a[:m].copy(), out_f[:m].copy(), out_d[:m].copy()


@nb.njit(cache=True, inline="always")
def segment_foot(px, py, ax, ay, bx, by):  # type: ignore[no-untyped-def]
    """The foot ``a + t (b - a)`` (t clamped to [0, 1]) of the point on segment ab and its
    distance (a hypot): the numbers of :func:`nearest_of_segments`, one segment."""
    abx, aby = bx - ax, by - ay
    l2 = max(abx * abx + aby * aby, _TINY)
    t = min(max(((px - ax) * abx + (py - ay) * aby) / l2, 0.0), 1.0)
    qx, qy = ax + t * abx, ay + t * aby
    return math.hypot(px - qx, py - qy), qx, qy


@nb.njit(cache=True)
def nearest_of_segments(p, cand, seg_a, seg_b):  # type: ignore[no-untyped-def]
    """The distance from each point of ``p (n, 2)`` to the nearest of its candidate segments
    ``cand (n, c)`` (rows of ``seg_a``, ``seg_b``), and the foot on it (the first candidate on
    ties).  The foot is ``a + t (b - a)``, t clamped to [0, 1], and the distance a hypot: the
    numbers of the NumPy form (tests/test_feature_size.py), without its (n, c, 2) temporaries
    (the feature grid's nearest boundary points)."""
    n, c = cand.shape
    dist = np.empty(n)
    foot = np.empty((n, 2))
    for i in range(n):
        px, py = p[i, 0], p[i, 1]
        best = np.inf
        fx, fy = 0.0, 0.0
        for j in range(c):
            k = cand[i, j]
            d, qx, qy = segment_foot(px, py, seg_a[k, 0], seg_a[k, 1], seg_b[k, 0], seg_b[k, 1])
            if d < best:
                best, fx, fy = d, qx, qy
        dist[i] = best
        foot[i, 0] = fx
        foot[i, 1] = fy
    return dist, foot


@nb.njit(cache=True)
def points_in_balls(q, radius, v, size):  # type: ignore[no-untyped-def]
    """Pairs (i, j) with ``|v_j - q_i| <= radius_i``, for points ``q (m, 2)``, radii
    ``radius (m,)`` and points ``v (n, 2)``, from a uniform grid of cells ``size`` wide over v
    (each ball looks at the cells its box overlaps): the rows i and the columns j, grouped by
    i, in no particular order within a row.  A NaN radius finds nothing; squared distances are
    compared with ``radius**2``.
    """
    m = q.shape[0]
    rows = np.empty(max(4 * m, 16), dtype=np.int64)
    cols = np.empty(max(4 * m, 16), dtype=np.int64)
    k = 0
    if v.shape[0] == 0 or not size > 0.0:
        return rows[:0].copy(), cols[:0].copy()
    cell, order, first, nx, ny = _cells(v, size)
    x0, y0 = v[:, 0].min(), v[:, 1].min()
    for i in range(m):
        r = radius[i]
        if not r >= 0.0:
            continue
        r2 = r * r
        x, y = q[i, 0], q[i, 1]
        # Cells overlapped by the ball's box, clipped to the grid as floats (an infinite or
        # huge radius must not overflow an int).
        gx0 = int(min(max(np.floor((x - r - x0) / size), 0.0), nx - 1.0))
        gx1 = int(min(max(np.floor((x + r - x0) / size), -1.0), nx - 1.0))
        gy0 = int(min(max(np.floor((y - r - y0) / size), 0.0), ny - 1.0))
        gy1 = int(min(max(np.floor((y + r - y0) / size), -1.0), ny - 1.0))
        for gy in range(gy0, gy1 + 1):
            for gx in range(gx0, gx1 + 1):
                c = gy * nx + gx
                for t in range(first[c], first[c + 1]):
                    j = order[t]
                    dx, dy = v[j, 0] - x, v[j, 1] - y
                    if dx * dx + dy * dy <= r2:
                        rows, cols, k = push_pair(rows, cols, k, i, j)
    return rows[:k].copy(), cols[:k].copy()


@nb.njit(cache=True, inline="always")
def _judge(a, s, v, seg, seg_len, v_n, seg_n, width, back_to_back, cos):  # type: ignore[no-untyped-def]
    """Vertex a against segment s: 1 back to back, 2 facing, 0 neither; the foot, the distance."""
    abx, aby = seg[s, 0], seg[s, 1]
    t = ((v[a, 0] - v[s, 0]) * abx + (v[a, 1] - v[s, 1]) * aby) / max(seg_len[s] * seg_len[s], _TINY)
    t = min(max(t, 0.0), 1.0)
    fx, fy = v[s, 0] + t * abx, v[s, 1] + t * aby
    gx, gy = fx - v[a, 0], fy - v[a, 1]
    dist = math.hypot(gx, gy)
    if not dist > 0.0:
        return 0, fx, fy, dist
    ex, ey = gx / dist, gy / dist
    own = ex * v_n[a, 0] + ey * v_n[a, 1]
    other = ex * seg_n[s, 0] + ey * seg_n[s, 1]
    if dist < back_to_back and own < -cos and other > cos:
        return 1, fx, fy, dist
    if dist < width and own > cos and -other > cos:
        return 2, fx, fy, dist
    return 0, fx, fy, dist


#: Rounding allowance of the cone bounds, relative to the cone values and to the coordinates'
#: magnitude (thousands of ulps): a bound prunes a corner only when it beats the best cone by
#: more than this, so no corner the formula's rounding could have made the minimum is ever left
#: out, and the result is the brute-force minimum bit for bit.
_ROUNDING = 1e-12


#: Longest list of candidate leaves a grid cell keeps (beyond it, its points search the tree).
_MAX_LEAVES = 64


@nb.njit(cache=True)
def cone_index(corners, spacing, rate, leaf, margin, cells, h_max):  # type: ignore[no-untyped-def]
    """The search structure of :func:`corner_cones` over ``corners (n, 2)`` with ``spacing (n,)``.

    A k-d tree of the corners (each node splits its run of corners at the middle, across the
    longer side of its bounding box, down to ``leaf`` corners or fewer; node k's children are
    2k + 1 and 2k + 2), each node with its bounding box and its least spacing, so that
    ``least spacing + rate * distance to the box`` bounds its corners' cones from below.

    Over it, a grid of about ``cells`` square cells covering the corners' box grown by
    ``margin``.  Each cell C keeps a lower bound of every cone over C (a point whose h is below
    it keeps h at once), the corner whose cone is the lowest at C's centre (a point's first
    value) and, when that lower bound is below ``h_max`` (the largest h expected near the
    corners), the tree's leaves that can hold the minimum somewhere in C: those whose bound over
    C is at most ``U_C = cone at the centre + rate * half the diagonal`` (the cones' minimum is
    rate-Lipschitz), sorted by that bound, at most ``_MAX_LEAVES`` of them.  What a point reads
    is packed in rows (a node's box, least spacing and run of corners; a corner's x, y and
    spacing; a cell's bound and seed corner; a list entry's bound and leaf; a leaf's corners' x,
    y and spacing, padded to a multiple of four corners with infinite spacing): a point touches
    few cache lines.

    Returns
    -------
    index : tuple
        What :func:`corner_cones` reads: ``(tree, grid)``.
    """
    n = corners.shape[0]
    depth = 0
    while (n >> depth) > leaf:
        depth += 1
    nodes = (1 << (depth + 1)) - 1
    perm = np.arange(n)
    # node rows: x0, y0, x1, y1, least spacing, first corner, end of its corners
    node = np.empty((nodes, 7))
    node[0, 5], node[0, 6] = 0.0, float(n)
    for k in range(nodes):
        if k > 0:
            up = (k - 1) // 2
            mid = float((int(node[up, 5]) + int(node[up, 6])) // 2)
            node[k, 5], node[k, 6] = (node[up, 5], mid) if k == 2 * up + 1 else (mid, node[up, 6])
        lo, hi = int(node[k, 5]), int(node[k, 6])
        x0 = y0 = s0 = np.inf
        x1 = y1 = -np.inf
        for t in range(lo, hi):
            j = perm[t]
            x0, x1 = min(x0, corners[j, 0]), max(x1, corners[j, 0])
            y0, y1 = min(y0, corners[j, 1]), max(y1, corners[j, 1])
            s0 = min(s0, spacing[j])
        node[k, 0], node[k, 1], node[k, 2], node[k, 3], node[k, 4] = x0, y0, x1, y1, s0
        if 2 * k + 1 < nodes:
            run = perm[lo:hi]
            perm[lo:hi] = run[np.argsort(corners[run, 0 if x1 - x0 >= y1 - y0 else 1],
                                         kind="mergesort")]
    # corner rows, in the tree's order: x, y, spacing
    pts = np.empty((n, 3))
    pts[:, 0], pts[:, 1], pts[:, 2] = corners[perm, 0], corners[perm, 1], spacing[perm]
    slack = _ROUNDING * (spacing.max() + rate * (abs(node[0, 0]) + abs(node[0, 1])
                                                 + abs(node[0, 2]) + abs(node[0, 3]) + 2.0 * margin))
    first_leaf = (1 << depth) - 1
    tree = (rate, slack, first_leaf, node, pts)
    # The grid of cells, at most `cells` along the longer side (a row of collinear corners).
    gx0, gy0 = node[0, 0] - margin, node[0, 1] - margin
    ex, ey = node[0, 2] - node[0, 0] + 2.0 * margin, node[0, 3] - node[0, 1] + 2.0 * margin
    cells = max(cells, 1.0)
    size = max(math.sqrt(ex * ey / cells), max(ex, ey) / cells)
    if not size > 0.0:  # corners at one place and no margin
        size = 1.0
    nx, ny = int(ex / size) + 1, int(ey / size) + 1
    # cell rows: lower bound, seed corner's x, y and spacing
    cell = np.empty((nx * ny, 4))
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    entries = np.empty((max(4 * n, 16), 2))  # list rows: bound over the cell, leaf
    stack = np.empty(depth + 2, dtype=np.int64)
    found = np.empty((_MAX_LEAVES + 1, 2))
    m = 0
    for c in range(nx * ny):
        ax, ay = gx0 + (c % nx) * size, gy0 + (c // nx) * size
        low, _ = _least(ax, ay, ax + size, ay + size, np.inf, tree, stack)
        # Lowered by the rounding allowance: no point of the cell has a cone below it.
        cell[c, 0] = low - _ROUNDING * low - slack
        mx, my = ax + 0.5 * size, ay + 0.5 * size
        centre, t = _least(mx, my, mx, my, np.inf, tree, stack)
        cell[c, 1], cell[c, 2], cell[c, 3] = pts[t, 0], pts[t, 1], pts[t, 2]
        if low < h_max:
            # 0.7072 > sqrt(2) / 2: the farthest point of the cell from its centre.
            k = _leaves_below(ax, ay, ax + size, ay + size, centre + rate * 0.7072 * size, tree,
                              stack, found)
            if k > 0:
                by_bound = np.argsort(found[:k, 0], kind="mergesort")
                if m + k > len(entries):
                    entries = np.concatenate((entries, np.empty((m + k, 2))))
                for t in range(k):
                    b = found[by_bound[t], 0]
                    entries[m + t, 0] = b - _ROUNDING * b - slack
                    entries[m + t, 1] = found[by_bound[t], 1]
                m += k
        start[c + 1] = m
    # leaf rows: the x's, y's and spacings of a leaf's corners (three rows of `width`), padded
    # with corners at the origin whose cone is infinite: a leaf's cones are computed all at
    # once, four lanes at a time, with no branch per corner (one per corner mispredicted half
    # the time and cost more than the cones it skipped).
    width = 1
    for k in range(first_leaf, nodes):
        width = max(width, int(node[k, 6]) - int(node[k, 5]))
    width = (width + 3) // 4 * 4
    lv = np.zeros((nodes - first_leaf, 3, width))
    lv[:, 2, :] = np.inf
    for k in range(first_leaf, nodes):
        for t in range(int(node[k, 5]), int(node[k, 6])):
            j = t - int(node[k, 5])
            lv[k - first_leaf, 0, j] = pts[t, 0]
            lv[k - first_leaf, 1, j] = pts[t, 1]
            lv[k - first_leaf, 2, j] = pts[t, 2]
    return tree, (gx0, gy0, size, nx, ny, cell, start, entries[:m].copy(), lv)


@nb.njit(cache=True, inline="always")
def _beyond(bound2, v, slack, least):  # type: ignore[no-untyped-def]
    """``least + rate * distance`` is beyond v by more than the rounding allowance, given
    ``bound2 = (rate * distance)**2``: compared squared, no square root."""
    e = v + _ROUNDING * v + slack - least
    return e < 0.0 or bound2 > e * e


@nb.njit(cache=True, inline="always")
def _gap(node, k, x0, y0, x1, y1):  # type: ignore[no-untyped-def]
    """The x and y gaps between node k's box (row ``node[k, 0:4]``) and the box [x0, x1] x
    [y0, y1] (0 where they overlap)."""
    return (max(node[k, 0] - x1, 0.0, x0 - node[k, 2]),
            max(node[k, 1] - y1, 0.0, y0 - node[k, 3]))


@nb.njit(cache=True)
def _leaves_below(x0, y0, x1, y1, u, tree, stack, found):  # type: ignore[no-untyped-def]
    """The leaves whose bound over the box [x0, x1] x [y0, y1] (``least spacing + rate *
    distance``) is not beyond u: their bounds and numbers in the rows of ``found``; how many,
    or 0 when more than ``len(found) - 1``."""
    rate, slack, first_leaf, node, pts = tree
    r2 = rate * rate
    m = 0
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        dx, dy = _gap(node, k, x0, y0, x1, y1)
        if _beyond(r2 * (dx * dx + dy * dy), u, slack, node[k, 4]):
            continue
        if k < first_leaf:
            stack[top] = 2 * k + 2
            stack[top + 1] = 2 * k + 1
            top += 2
            continue
        if m == len(found) - 1:
            return 0
        found[m, 0] = node[k, 4] + rate * math.sqrt(dx * dx + dy * dy)
        found[m, 1] = k
        m += 1
    return m


@nb.njit(cache=True)
def _least(x0, y0, x1, y1, v, tree, stack):  # type: ignore[no-untyped-def]
    """``min(v, min_c (spacing[c] + rate * distance from c to the box [x0, x1] x [y0, y1]))``
    (a point when ``x0 == x1`` and ``y0 == y1``) and the corner (its row in the tree's
    order) that gave it, -1 for v itself.

    Depth first through the k-d tree, the child nearer the box first, skipping a node whose
    ``least spacing + rate * distance`` is beyond v by more than the rounding allowance.
    """
    rate, slack, first_leaf, node, pts = tree
    r2 = rate * rate
    arg = -1
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        dx, dy = _gap(node, k, x0, y0, x1, y1)
        if _beyond(r2 * (dx * dx + dy * dy), v, slack, node[k, 4]):
            continue
        if k < first_leaf:
            a, b = 2 * k + 1, 2 * k + 2
            # The nearer child is pushed last, so searched first (ties: the first child).
            ax, ay = _gap(node, a, x0, y0, x1, y1)
            bx, by = _gap(node, b, x0, y0, x1, y1)
            if ax * ax + ay * ay <= bx * bx + by * by:
                a, b = b, a
            stack[top] = a
            stack[top + 1] = b
            top += 2
            continue
        for t in range(int(node[k, 5]), int(node[k, 6])):
            dx = max(x0 - pts[t, 0], 0.0, pts[t, 0] - x1)
            dy = max(y0 - pts[t, 1], 0.0, pts[t, 1] - y1)
            d2 = dx * dx + dy * dy
            if _beyond(r2 * d2, v, slack, pts[t, 2]):
                continue
            cone = pts[t, 2] + rate * math.sqrt(d2)
            if cone < v:
                v = cone
                arg = t
    return v, arg


@nb.njit(cache=True, inline="always")
def _leaf_min(lv, j, x, y, rate, tmp):  # type: ignore[no-untyped-def]
    """The least cone at (x, y) of the corners of leaf row j of ``lv``, every cone computed the
    same way as by brute force (so the minimum is bit for bit); ``tmp`` is scratch of
    ``lv.shape[2]`` entries (a loop that stores, which the compiler vectorizes, then the
    minimum)."""
    for t in range(tmp.shape[0]):
        dx, dy = x - lv[j, 0, t], y - lv[j, 1, t]
        tmp[t] = lv[j, 2, t] + rate * math.sqrt(dx * dx + dy * dy)
    m = tmp[0]
    for t in range(1, tmp.shape[0]):
        m = min(m, tmp[t])
    return m


@nb.njit(cache=True, nogil=True)
def corner_cones(p, hp, index):  # type: ignore[no-untyped-def]
    """``min(hp, min_c (spacing[c] + rate * sqrt(dx * dx + dy * dy)))`` over all corners c, for
    each point of ``p (n, 2)``: the brute-force minimum bit for bit.

    ``index`` is :func:`cone_index` of the corners.  A point whose h is below its grid cell's
    lower bound (farther from every corner than a cone could reach: most of a big domain) keeps
    it at once.  Any other starts from the cone of its cell's seed corner and walks its cell's
    leaves in order of their bounds over the cell until one is no lower than the value so far,
    skipping a leaf whose bound at the point is not lower either (a few leaves and corners); a
    point outside the grid, or in a cell without a list, searches the whole tree instead.  The
    leaf that held the last minimum found is read first (a point's neighbour in the batch
    mostly has the same nearest corners): pruning starts from a near-final value.  Extra cones
    never change a minimum, so the order of the points changes nothing but the time.  A
    point with a NaN or infinite coordinate, or with ``hp <= min(spacing)`` or NaN, keeps hp.
    """
    tree, grid = index
    rate, slack, first_leaf, node, pts = tree
    x0, y0, size, nx, ny, cell, start, entries, lv = grid
    r2 = rate * rate
    s_min = node[0, 4]
    n = p.shape[0]
    out = np.empty(n)
    stack = np.empty(64, dtype=np.int64)
    best = -1
    tmp = np.empty(lv.shape[2])
    for i in range(n):
        x, y = p[i, 0], p[i, 1]
        v = hp[i]
        out[i] = v
        if not (math.isfinite(x) and math.isfinite(y)) or not v > s_min:
            continue
        fx, fy = (x - x0) / size, (y - y0) / size
        if 0.0 <= fx < nx and 0.0 <= fy < ny:
            c = int(fy) * nx + int(fx)
            if v <= cell[c, 0]:
                continue
            dx, dy = x - cell[c, 1], y - cell[c, 2]
            v = min(v, cell[c, 3] + rate * math.sqrt(dx * dx + dy * dy))
            if start[c] < start[c + 1]:
                if best >= 0:  # the leaf of the last minimum found
                    v = min(v, _leaf_min(lv, best - first_leaf, x, y, rate, tmp))
                prev = best
                for q in range(start[c], start[c + 1]):
                    if entries[q, 0] >= v:  # and so are the rest: sorted
                        break
                    k = int(entries[q, 1])
                    if k == prev:  # read already
                        continue
                    dx, dy = _gap(node, k, x, y, x, y)
                    if _beyond(r2 * (dx * dx + dy * dy), v, slack, node[k, 4]):
                        continue
                    w = _leaf_min(lv, k - first_leaf, x, y, rate, tmp)
                    if w < v:
                        v = w
                        best = k
                out[i] = v
                continue
        out[i], _ = _least(x, y, x, y, v, tree, stack)
    return out


def threaded_corner_cones(p, hp, index):  # type: ignore[no-untyped-def]
    """:func:`corner_cones` over chunks of the points on several threads: each point's value is
    the brute-force minimum whatever the order, so the chunks give the serial answer."""
    n = p.shape[0]
    if not threads.worth(n):
        return corner_cones(p, hp, index)
    out = np.empty(n)

    def run(lo: int, hi: int) -> None:
        out[lo:hi] = corner_cones(p[lo:hi], hp[lo:hi], index)

    threads.each(n, run)
    return out


@nb.njit(cache=True)
def nearest_segments_brute(q, a, ab, ab2):  # type: ignore[no-untyped-def]
    """The nearest segment ``a[i] -> a[i] + ab[i]`` of each point of ``q (m, 2)``, trying every
    segment (for few points and segments): its index (the lowest on a tie), the foot's
    parameter t (clamped to [0, 1]) and the distance.  The numbers of ``boundary
    ._nearest_segments``'s NumPy form: ``t = clip(((q - a) . ab) / ab2, 0, 1)``, the foot
    ``a + t ab``, a hypot."""
    m, n = q.shape[0], a.shape[0]
    seg = np.zeros(m, dtype=np.int64)
    out_t = np.zeros(m)
    out_d = np.full(m, np.inf)
    for i in range(m):
        qx, qy = q[i, 0], q[i, 1]
        for j in range(n):
            t = ((qx - a[j, 0]) * ab[j, 0] + (qy - a[j, 1]) * ab[j, 1]) / ab2[j]
            # As np.clip clamps: -0.0 becomes 0.0, a NaN stays.
            t = 0.0 if t <= 0.0 else (1.0 if t >= 1.0 else t)
            d = math.hypot(qx - (a[j, 0] + t * ab[j, 0]), qy - (a[j, 1] + t * ab[j, 1]))
            if d < out_d[i]:
                seg[i], out_t[i], out_d[i] = j, t, d
    return seg, out_t, out_d
