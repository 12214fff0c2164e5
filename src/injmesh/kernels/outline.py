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
builds once: a k-d tree of the corners whose nodes know their least spacing (a branch and
bound search prunes a node whose ``least spacing + rate * distance`` cannot beat the value so
far), and a grid of per-cell lower bounds and seed corners that dismisses at once the points no
cone can reach and gives the others a near-final first value.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

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
    rate-Lipschitz), sorted by that bound, at most ``_MAX_LEAVES`` of them.

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
    lo, hi = np.empty(nodes, dtype=np.int64), np.empty(nodes, dtype=np.int64)
    box = np.empty((nodes, 4))
    least = np.empty(nodes)
    lo[0], hi[0] = 0, n
    for k in range(nodes):
        if k > 0:
            up = (k - 1) // 2
            mid = (lo[up] + hi[up]) // 2
            lo[k], hi[k] = (lo[up], mid) if k == 2 * up + 1 else (mid, hi[up])
        x0 = y0 = s0 = np.inf
        x1 = y1 = -np.inf
        for t in range(lo[k], hi[k]):
            j = perm[t]
            x0, x1 = min(x0, corners[j, 0]), max(x1, corners[j, 0])
            y0, y1 = min(y0, corners[j, 1]), max(y1, corners[j, 1])
            s0 = min(s0, spacing[j])
        box[k, 0], box[k, 1], box[k, 2], box[k, 3] = x0, y0, x1, y1
        least[k] = s0
        if 2 * k + 1 < nodes:
            run = perm[lo[k]:hi[k]]
            perm[lo[k]:hi[k]] = run[np.argsort(corners[run, 0 if x1 - x0 >= y1 - y0 else 1],
                                                kind="mergesort")]
    xs, ys, ss = corners[perm, 0].copy(), corners[perm, 1].copy(), spacing[perm].copy()
    slack = _ROUNDING * (ss.max() + rate * (abs(box[0, 0]) + abs(box[0, 1]) + abs(box[0, 2])
                                            + abs(box[0, 3]) + 2.0 * margin))
    first_leaf = (1 << depth) - 1
    tree = (rate, slack, first_leaf, lo, hi, box, least, xs, ys, ss)
    # The grid of cells, at most `cells` along the longer side (a row of collinear corners).
    gx0, gy0 = box[0, 0] - margin, box[0, 1] - margin
    ex, ey = box[0, 2] - box[0, 0] + 2.0 * margin, box[0, 3] - box[0, 1] + 2.0 * margin
    cells = max(cells, 1.0)
    size = max(math.sqrt(ex * ey / cells), max(ex, ey) / cells)
    if not size > 0.0:  # corners at one place and no margin
        size = 1.0
    nx, ny = int(ex / size) + 1, int(ey / size) + 1
    lower = np.empty(nx * ny)
    seed = np.empty(nx * ny, dtype=np.int64)
    start = np.zeros(nx * ny + 1, dtype=np.int64)
    leaves = np.empty(max(4 * n, 16), dtype=np.int64)
    bounds = np.empty(max(4 * n, 16))
    stack = np.empty(depth + 2, dtype=np.int64)
    found = np.empty(_MAX_LEAVES + 1, dtype=np.int64)
    found_b = np.empty(_MAX_LEAVES + 1)
    m = 0
    for c in range(nx * ny):
        ax, ay = gx0 + (c % nx) * size, gy0 + (c // nx) * size
        low, _ = _least(ax, ay, ax + size, ay + size, np.inf, tree, stack)
        # Lowered by the rounding allowance: no point of the cell has a cone below it.
        lower[c] = low - _ROUNDING * low - slack
        mx, my = ax + 0.5 * size, ay + 0.5 * size
        centre, seed[c] = _least(mx, my, mx, my, np.inf, tree, stack)
        if low < h_max:
            # 0.7072 > sqrt(2) / 2: the farthest point of the cell from its centre.
            k = _leaves_below(ax, ay, ax + size, ay + size, centre + rate * 0.7072 * size, tree,
                              stack, found, found_b)
            if k > 0:
                by_bound = np.argsort(found_b[:k], kind="mergesort")
                if m + k > len(leaves):
                    leaves = np.concatenate((leaves, np.empty(m + k, dtype=np.int64)))
                    bounds = np.concatenate((bounds, np.empty(m + k)))
                for t in range(k):
                    leaves[m + t] = found[by_bound[t]]
                    b = found_b[by_bound[t]]
                    bounds[m + t] = b - _ROUNDING * b - slack
                m += k
        start[c + 1] = m
    return tree, (gx0, gy0, size, nx, ny, lower, seed, start, leaves[:m].copy(), bounds[:m].copy())


@nb.njit(cache=True)
def _leaves_below(x0, y0, x1, y1, u, tree, stack, found, found_b):  # type: ignore[no-untyped-def]
    """The leaves whose bound over the box [x0, x1] x [y0, y1] (``least spacing + rate *
    distance``) is not beyond u, and their bounds, in ``found``, ``found_b``: how many, or 0
    when more than ``len(found) - 1``."""
    rate, slack, first_leaf, lo, hi, box, least, xs, ys, ss = tree
    r2 = rate * rate
    m = 0
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        dx = max(box[k, 0] - x1, 0.0, x0 - box[k, 2])
        dy = max(box[k, 1] - y1, 0.0, y0 - box[k, 3])
        e = u + _ROUNDING * u + slack - least[k]
        if e < 0.0 or r2 * (dx * dx + dy * dy) > e * e:
            continue
        if k < first_leaf:
            stack[top] = 2 * k + 2
            stack[top + 1] = 2 * k + 1
            top += 2
            continue
        if m == len(found) - 1:
            return 0
        found[m] = k
        found_b[m] = least[k] + rate * math.sqrt(dx * dx + dy * dy)
        m += 1
    return m


@nb.njit(cache=True)
def _least(x0, y0, x1, y1, v, tree, stack):  # type: ignore[no-untyped-def]
    """``min(v, min_c (spacing[c] + rate * distance from c to the box [x0, x1] x [y0, y1]))``
    (a point when ``x0 == x1`` and ``y0 == y1``) and the corner (its place in the tree's
    order) that gave it, -1 for v itself.

    Depth first through the k-d tree, the child nearer the box first; a node is skipped when
    ``least spacing + rate * distance`` is beyond v by more than the rounding allowance,
    compared squared (``(rate * distance)**2 > (v' - least)**2``, no square root).
    """
    rate, slack, first_leaf, lo, hi, box, least, xs, ys, ss = tree
    r2 = rate * rate
    arg = -1
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        k = stack[top]
        dx = max(box[k, 0] - x1, 0.0, x0 - box[k, 2])
        dy = max(box[k, 1] - y1, 0.0, y0 - box[k, 3])
        e = v + _ROUNDING * v + slack - least[k]
        if e < 0.0 or r2 * (dx * dx + dy * dy) > e * e:
            continue
        if k < first_leaf:
            a, b = 2 * k + 1, 2 * k + 2
            # The nearer child is pushed last, so searched first (ties: the first child).
            da = max(box[a, 0] - x1, 0.0, x0 - box[a, 2]) ** 2 + max(box[a, 1] - y1, 0.0, y0 - box[a, 3]) ** 2
            db = max(box[b, 0] - x1, 0.0, x0 - box[b, 2]) ** 2 + max(box[b, 1] - y1, 0.0, y0 - box[b, 3]) ** 2
            if da <= db:
                a, b = b, a
            stack[top] = a
            stack[top + 1] = b
            top += 2
            continue
        for t in range(lo[k], hi[k]):
            dx = max(x0 - xs[t], 0.0, xs[t] - x1)
            dy = max(y0 - ys[t], 0.0, ys[t] - y1)
            d2 = dx * dx + dy * dy
            e = v + _ROUNDING * v + slack - ss[t]
            if e < 0.0 or r2 * d2 > e * e:
                continue
            cone = ss[t] + rate * math.sqrt(d2)
            if cone < v:
                v = cone
                arg = t
    return v, arg


@nb.njit(cache=True)
def corner_cones(p, hp, index):  # type: ignore[no-untyped-def]
    """``min(hp, min_c (spacing[c] + rate * sqrt(dx * dx + dy * dy)))`` over all corners c, for
    each point of ``p (n, 2)``: the brute-force minimum bit for bit.

    ``index`` is :func:`cone_index` of the corners.  A point whose h is below its grid cell's
    lower bound (farther from every corner than a cone could reach: most of a big domain) keeps
    it at once; any other starts from the cone of its cell's seed corner and searches the k-d
    tree for lower ones (a few nodes and corners near it).  A point with a NaN or infinite
    coordinate, or with ``hp <= min(spacing)`` or NaN, keeps hp.
    """
    tree, grid = index
    rate, slack, first_leaf, lo, hi, box, least, xs, ys, ss = tree
    x0, y0, size, nx, ny, lower, seed, start, leaves, bounds = grid
    r2 = rate * rate
    s_min = least[0]
    n = p.shape[0]
    out = np.empty(n)
    stack = np.empty(64, dtype=np.int64)
    for i in range(n):
        x, y = p[i, 0], p[i, 1]
        v = hp[i]
        out[i] = v
        if not (math.isfinite(x) and math.isfinite(y)) or not v > s_min:
            continue
        fx, fy = (x - x0) / size, (y - y0) / size
        if 0.0 <= fx < nx and 0.0 <= fy < ny:
            c = int(fy) * nx + int(fx)
            if v <= lower[c]:
                continue
            t = seed[c]
            dx, dy = x - xs[t], y - ys[t]
            v = min(v, ss[t] + rate * math.sqrt(dx * dx + dy * dy))
            if start[c] < start[c + 1]:
                for q in range(start[c], start[c + 1]):
                    if bounds[q] >= v:  # and so are the rest: sorted
                        break
                    k = leaves[q]
                    dx = max(box[k, 0] - x, 0.0, x - box[k, 2])
                    dy = max(box[k, 1] - y, 0.0, y - box[k, 3])
                    e = v + _ROUNDING * v + slack - least[k]
                    if e < 0.0 or r2 * (dx * dx + dy * dy) > e * e:
                        continue
                    for t in range(lo[k], hi[k]):
                        dx, dy = x - xs[t], y - ys[t]
                        d2 = dx * dx + dy * dy
                        e = v + _ROUNDING * v + slack - ss[t]
                        if e < 0.0 or r2 * d2 > e * e:
                            continue
                        v = min(v, ss[t] + rate * math.sqrt(d2))
                out[i] = v
                continue
        out[i], _ = _least(x, y, x, y, v, tree, stack)
    return out
