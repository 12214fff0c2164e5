"""Queries on a flat boundary representation: nearest point, signed distance, box overlaps,
curve intersections and the simplicity sweep.

A boundary is a set of *pieces*, each a line segment or a circular arc, stored in flat arrays
(coordinates local to the geometry):

``p0, p1 (m, 2)``
    Start and end points; the domain lies on the left of the direction of travel.
``c (m, 2), r (m,)``
    Centre and radius of an arc (unused for a segment).
``a0 (m,), sw (m,)``
    Start angle and signed sweep of an arc (``sw > 0`` counter-clockwise); ``sw == 0`` marks a
    segment.
``prv, nxt (m,)``
    The pieces before and after each one along its loop.

A bounding-volume hierarchy over the pieces' boxes (median splits, at most ``QUERY_LEAF``
pieces per leaf) answers nearest-piece queries in O(log m) for points anywhere in the plane.
A search starts at the leaf that answered a nearby point and climbs to the root; it reads the
pieces from tables in leaf order with what each test needs precomputed (:func:`leaf_table`,
:func:`side_table`) and tests arcs without trigonometry.  The sign of
the distance comes from the nearest feature alone (the side of a segment or arc, or the wedge at
a vertex), which is exact wherever the distance is not itself at rounding level; where several
loops pass through the nearest vertex (two operands touching at a point) the point is inside if
it is inside any of the wedges there.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from . import threads

LEAF = 4  # build_bvh's default, for box_pairs (overlap queries want small leaves)
QUERY_LEAF = 8  # for nearest-point searches: a shallower tree, contiguous leaves
TWO_PI = 2.0 * math.pi
_STACK = 256
_TIES = 16


# --- one piece -------------------------------------------------------------------------------


@nb.njit(cache=True, inline="always")
def _sweep_param(phi: float, a0: float, sw: float) -> float:
    """Angle travelled from the start of an arc to direction ``phi``, in [0, 2 pi)."""
    if sw > 0.0:
        return (phi - a0) % TWO_PI
    return (a0 - phi) % TWO_PI


@nb.njit(cache=True)
def piece_foot(k, x, y, p0, p1, c, r, a0, sw):  # type: ignore[no-untyped-def]
    """Squared distance from ``(x, y)`` to piece ``k``, its foot, and where the foot lies:
    0 the start point, 1 inside the piece, 2 the end point."""
    if sw[k] == 0.0:
        ax, ay = p0[k, 0], p0[k, 1]
        ex, ey = p1[k, 0] - ax, p1[k, 1] - ay
        l2 = ex * ex + ey * ey
        t = ((x - ax) * ex + (y - ay) * ey) / l2 if l2 > 0.0 else 0.0
        if t <= 0.0:
            dx, dy = x - ax, y - ay
            return dx * dx + dy * dy, ax, ay, 0
        if t >= 1.0:
            dx, dy = x - p1[k, 0], y - p1[k, 1]
            return dx * dx + dy * dy, p1[k, 0], p1[k, 1], 2
        fx, fy = ax + t * ex, ay + t * ey
        dx, dy = x - fx, y - fy
        return dx * dx + dy * dy, fx, fy, 1
    vx, vy = x - c[k, 0], y - c[k, 1]
    rho = math.hypot(vx, vy)
    if rho > 0.0:
        s = _sweep_param(math.atan2(vy, vx), a0[k], sw[k])
        if s <= abs(sw[k]):
            fx = c[k, 0] + r[k] * vx / rho
            fy = c[k, 1] + r[k] * vy / rho
            g = rho - r[k]
            return g * g, fx, fy, 1
    dx0, dy0 = x - p0[k, 0], y - p0[k, 1]
    dx1, dy1 = x - p1[k, 0], y - p1[k, 1]
    d0 = dx0 * dx0 + dy0 * dy0
    d1 = dx1 * dx1 + dy1 * dy1
    if d1 < d0:
        return d1, p1[k, 0], p1[k, 1], 2
    return d0, p0[k, 0], p0[k, 1], 0


@nb.njit(cache=True, inline="always")
def tangent(k, at_end, p0, p1, c, sw):  # type: ignore[no-untyped-def]
    """Direction of travel of piece ``k`` at its start (``at_end`` False) or end."""
    if sw[k] == 0.0:
        return p1[k, 0] - p0[k, 0], p1[k, 1] - p0[k, 1]
    if at_end:
        vx, vy = p1[k, 0] - c[k, 0], p1[k, 1] - c[k, 1]
    else:
        vx, vy = p0[k, 0] - c[k, 0], p0[k, 1] - c[k, 1]
    if sw[k] > 0.0:
        return -vy, vx
    return vy, -vx


@nb.njit(cache=True, inline="always")
def _inside(lt, st, j, where, x, y):  # type: ignore[no-untyped-def]
    """Whether ``(x, y)`` is inside, judged from its foot on the piece in leaf slot ``j``
    (``where`` as piece_foot's), from the leaf table ``lt`` and the side table ``st``."""
    if where == 1:
        if lt[j, _KIND] == _SEG:
            ex, ey = lt[j, 5], lt[j, 6]
            return ex * (y - lt[j, _AY]) - ey * (x - lt[j, _AX]) > 0.0
        rho = math.hypot(x - lt[j, 5], y - lt[j, 6])
        return rho < lt[j, 7] if st[j, 0] > 0.0 else rho > lt[j, 7]
    if where == 0:
        vx, vy = lt[j, _AX], lt[j, _AY]
        ux, uy, wx, wy = st[j, 1], st[j, 2], st[j, 3], st[j, 4]
    else:
        vx, vy = lt[j, _BX], lt[j, _BY]
        ux, uy, wx, wy = st[j, 5], st[j, 6], st[j, 7], st[j, 8]
    ex, ey = x - vx, y - vy
    cu = ux * ey - uy * ex
    cw = wx * ey - wy * ex
    turn = ux * wy - uy * wx
    # The domain is the wedge swept counter-clockwise from the outgoing direction w to the
    # reversed incoming direction -u: convex (a left turn) means left of both, reflex of either.
    if turn > 0.0 or (turn == 0.0 and ux * wx + uy * wy < 0.0):
        return cu > 0.0 and cw > 0.0
    return cu > 0.0 or cw > 0.0


@nb.njit(cache=True)
def side_table(p0, p1, c, sw, prv, nxt, order):  # type: ignore[no-untyped-def]
    """What the inside test needs of each piece, one row per leaf slot (piece ``order[j]``):
    the sweep's sign (0 for a segment) and the directions of travel into and out of its start
    (the previous piece's at its end, its own at its start) and of its end (its own, the next
    piece's at its start).  In leaf order, so a search reads the pieces' neighbours from the
    rows it just searched instead of from anywhere in the boundary."""
    m = order.shape[0]
    st = np.empty((m, 9))
    for j in range(m):
        k = order[j]
        st[j, 0] = 0.0 if sw[k] == 0.0 else (1.0 if sw[k] > 0.0 else -1.0)
        st[j, 1], st[j, 2] = tangent(prv[k], True, p0, p1, c, sw)
        st[j, 3], st[j, 4] = tangent(k, False, p0, p1, c, sw)
        st[j, 5], st[j, 6] = tangent(k, True, p0, p1, c, sw)
        st[j, 7], st[j, 8] = tangent(nxt[k], False, p0, p1, c, sw)
    return st


# --- the hierarchy ---------------------------------------------------------------------------


@nb.njit(cache=True)
def piece_boxes(p0, p1, c, r, a0, sw):  # type: ignore[no-untyped-def]
    """Tight axis-aligned boxes of the pieces, ``lo, hi (m, 2)``."""
    m = p0.shape[0]
    lo = np.empty((m, 2))
    hi = np.empty((m, 2))
    for k in range(m):
        lo[k, 0] = min(p0[k, 0], p1[k, 0])
        lo[k, 1] = min(p0[k, 1], p1[k, 1])
        hi[k, 0] = max(p0[k, 0], p1[k, 0])
        hi[k, 1] = max(p0[k, 1], p1[k, 1])
        if sw[k] != 0.0:
            for q in range(4):  # the extreme points at angles 0, pi/2, pi, 3 pi/2
                phi = 0.5 * math.pi * q
                if _sweep_param(phi, a0[k], sw[k]) <= abs(sw[k]):
                    x = c[k, 0] + r[k] * math.cos(phi)
                    y = c[k, 1] + r[k] * math.sin(phi)
                    lo[k, 0] = min(lo[k, 0], x)
                    lo[k, 1] = min(lo[k, 1], y)
                    hi[k, 0] = max(hi[k, 0], x)
                    hi[k, 1] = max(hi[k, 1], y)
    return lo, hi


@nb.njit(cache=True)
def build_bvh(lo, hi, leaf):  # type: ignore[no-untyped-def]
    """A bounding-volume hierarchy over boxes ``lo, hi (m, 2)``, at most ``leaf`` boxes per leaf.

    Returns ``node_lo, node_hi (k, 2)``, ``child (k,)`` (index of the first of two consecutive
    children, -1 for a leaf), ``start, count (k,)`` (a leaf's range in ``order``) and ``order``
    (box indices).  Splits at the median of the box centres along the longer axis (stable sort:
    deterministic).
    """
    m = lo.shape[0]
    order = np.arange(m)
    cap = max(1, 2 * m)
    node_lo = np.empty((cap, 2))
    node_hi = np.empty((cap, 2))
    child = np.full(cap, -1, dtype=np.int64)
    start = np.zeros(cap, dtype=np.int64)
    count = np.zeros(cap, dtype=np.int64)
    cx = 0.5 * (lo[:, 0] + hi[:, 0])
    cy = 0.5 * (lo[:, 1] + hi[:, 1])
    st_node = np.empty(_STACK, dtype=np.int64)
    st_s = np.empty(_STACK, dtype=np.int64)
    st_e = np.empty(_STACK, dtype=np.int64)
    st_node[0], st_s[0], st_e[0] = 0, 0, m
    sp = 1
    n_nodes = 1
    while sp > 0:
        sp -= 1
        node, s, e = st_node[sp], st_s[sp], st_e[sp]
        bx0 = by0 = np.inf
        bx1 = by1 = -np.inf
        mx0 = my0 = np.inf
        mx1 = my1 = -np.inf
        for j in range(s, e):
            k = order[j]
            bx0 = min(bx0, lo[k, 0])
            by0 = min(by0, lo[k, 1])
            bx1 = max(bx1, hi[k, 0])
            by1 = max(by1, hi[k, 1])
            mx0 = min(mx0, cx[k])
            my0 = min(my0, cy[k])
            mx1 = max(mx1, cx[k])
            my1 = max(my1, cy[k])
        node_lo[node, 0], node_lo[node, 1] = bx0, by0
        node_hi[node, 0], node_hi[node, 1] = bx1, by1
        start[node] = s
        count[node] = e - s
        if e - s <= leaf:
            continue
        sub = order[s:e].copy()
        key = cx[sub] if mx1 - mx0 >= my1 - my0 else cy[sub]
        idx = np.argsort(key, kind="mergesort")
        for j in range(e - s):
            order[s + j] = sub[idx[j]]
        mid = (s + e) // 2
        child[node] = n_nodes
        st_node[sp], st_s[sp], st_e[sp] = n_nodes, s, mid
        st_node[sp + 1], st_s[sp + 1], st_e[sp + 1] = n_nodes + 1, mid, e
        sp += 2
        n_nodes += 2
    return node_lo[:n_nodes].copy(), node_hi[:n_nodes].copy(), child[:n_nodes].copy(), start[
        :n_nodes
    ].copy(), count[:n_nodes].copy(), order


# --- queries ---------------------------------------------------------------------------------


@nb.njit(cache=True, inline="always")
def _spread16(v):  # type: ignore[no-untyped-def]
    """The 16 low bits of ``v`` moved to the even bit positions."""
    v &= 0xFFFF
    v = (v | (v << 8)) & 0x00FF00FF
    v = (v | (v << 4)) & 0x0F0F0F0F
    v = (v | (v << 2)) & 0x33333333
    return (v | (v << 1)) & 0x55555555


@nb.njit(cache=True)
def _morton_order(q):  # type: ignore[no-untyped-def]
    """An order of the points along a Z-curve over their box: neighbours in the order are
    neighbours in the plane, so consecutive queries reuse the cache and the last answer.

    The 32-bit keys are sorted by a stable radix sort (four byte-wide passes): the order a
    stable comparison sort gives, in linear time (a comparison sort cost as much as the
    queries it orders)."""
    n = q.shape[0]
    if n == 0:
        return np.arange(0)
    x0, y0 = q[:, 0].min(), q[:, 1].min()
    span = max(q[:, 0].max() - x0, q[:, 1].max() - y0)
    scale = 65535.0 / span if span > 0.0 else 0.0
    key = np.empty(n, dtype=np.int64)
    for i in range(n):
        key[i] = _spread16(int((q[i, 0] - x0) * scale)) | (_spread16(int((q[i, 1] - y0) * scale)) << 1)
    idx = np.arange(n)
    tmp = np.empty(n, dtype=np.int64)
    hist = np.empty(256, dtype=np.int64)
    for shift in range(0, 32, 8):
        hist[:] = 0
        for i in range(n):
            hist[(key[idx[i]] >> shift) & 255] += 1
        total = 0
        for b in range(256):
            h = hist[b]
            hist[b] = total
            total += h
        for i in range(n):
            b = (key[idx[i]] >> shift) & 255
            tmp[hist[b]] = idx[i]
            hist[b] += 1
        idx, tmp = tmp, idx
    return idx


# Columns of the packed leaf table (one row per leaf slot, see leaf_table).
_KIND, _AX, _AY, _BX, _BY = 0, 1, 2, 3, 4
_SEG = 0.0  # a segment: columns 5, 6 its direction, 7 its squared length
_ARC = 1.0  # an arc sweeping at most pi: 5, 6 centre, 7 radius, 8-11 the sweep's end rays
_WIDE = 2.0  # an arc sweeping more than pi (same columns)
_ROW = 12


@nb.njit(cache=True)
def leaf_table(p0, p1, c, r, sw):  # type: ignore[no-untyped-def]
    """The pieces (already in leaf order) packed one row each, with what every nearest-point
    test needs precomputed, so a leaf's pieces are one contiguous block of memory.

    A row holds the kind (segment, arc sweeping at most pi, arc sweeping more), the start and
    end point, then for a segment its direction and squared length, for an arc its centre,
    radius and the two rays from the centre that bound its sweep counter-clockwise (start then
    end: a clockwise arc sweeps counter-clockwise from its end point to its start point).
    """
    m = p0.shape[0]
    t = np.zeros((m, _ROW))
    for k in range(m):
        t[k, _AX], t[k, _AY], t[k, _BX], t[k, _BY] = p0[k, 0], p0[k, 1], p1[k, 0], p1[k, 1]
        if sw[k] == 0.0:
            t[k, _KIND] = _SEG
            ex, ey = p1[k, 0] - p0[k, 0], p1[k, 1] - p0[k, 1]
            t[k, 5], t[k, 6], t[k, 7] = ex, ey, ex * ex + ey * ey
            continue
        t[k, _KIND] = _ARC if abs(sw[k]) <= math.pi else _WIDE
        t[k, 5], t[k, 6], t[k, 7] = c[k, 0], c[k, 1], r[k]
        ux, uy = p0[k, 0] - c[k, 0], p0[k, 1] - c[k, 1]
        vx, vy = p1[k, 0] - c[k, 0], p1[k, 1] - c[k, 1]
        if abs(sw[k]) >= TWO_PI:  # a full turn: every direction is in the sweep
            t[k, _KIND] = _WIDE
            vx, vy = ux, uy
        if sw[k] < 0.0:
            ux, uy, vx, vy = vx, vy, ux, uy
        t[k, 8], t[k, 9], t[k, 10], t[k, 11] = ux, uy, vx, vy
    return t


@nb.njit(cache=True, inline="always")
def _foot(t, j, x, y):  # type: ignore[no-untyped-def]
    """piece_foot on row ``j`` of a leaf table, without trigonometry: a direction lies in an
    arc's sweep by its turns from the sweep's two end rays (both left turns for a sweep up to
    pi; either one for a wider sweep, so a full turn, whose rays coincide, holds every
    direction)."""
    ax, ay = t[j, _AX], t[j, _AY]
    if t[j, _KIND] == _SEG:
        ex, ey, l2 = t[j, 5], t[j, 6], t[j, 7]
        s = (x - ax) * ex + (y - ay) * ey
        if s <= 0.0 or l2 == 0.0:
            dx, dy = x - ax, y - ay
            return dx * dx + dy * dy, ax, ay, 0
        if s >= l2:
            bx, by = t[j, _BX], t[j, _BY]
            dx, dy = x - bx, y - by
            return dx * dx + dy * dy, bx, by, 2
        u = s / l2
        fx, fy = ax + u * ex, ay + u * ey
        dx, dy = x - fx, y - fy
        return dx * dx + dy * dy, fx, fy, 1
    cx, cy, r = t[j, 5], t[j, 6], t[j, 7]
    vx, vy = x - cx, y - cy
    left0 = t[j, 8] * vy - t[j, 9] * vx >= 0.0
    left1 = vx * t[j, 11] - vy * t[j, 10] >= 0.0
    within = (left0 or left1) if t[j, _KIND] == _WIDE else (left0 and left1)
    rho = math.sqrt(vx * vx + vy * vy)
    if within and rho > 0.0:
        g = rho - r
        return g * g, cx + r * vx / rho, cy + r * vy / rho, 1
    dx0, dy0 = x - ax, y - ay
    bx, by = t[j, _BX], t[j, _BY]
    dx1, dy1 = x - bx, y - by
    d0 = dx0 * dx0 + dy0 * dy0
    d1 = dx1 * dx1 + dy1 * dy1
    if d1 < d0:
        return d1, bx, by, 2
    return d0, ax, ay, 0


@nb.njit(cache=True, inline="always")
def _box_gap(box, node, x, y):  # type: ignore[no-untyped-def]
    """Squared distance from ``(x, y)`` to row ``node`` of a packed box table (lo x, lo y,
    hi x, hi y)."""
    dx = max(box[node, 0] - x, 0.0, x - box[node, 2])
    dy = max(box[node, 1] - y, 0.0, y - box[node, 3])
    return dx * dx + dy * dy


@nb.njit(cache=True)
def tree_links(child, start, count, m):  # type: ignore[no-untyped-def]
    """``up (k, 2)``, every node's parent and the parent's other child (-1 for the root), and
    ``leaf_of (m,)``, the leaf holding every leaf slot: the links a search needs to start at
    a leaf (both of a level's links in one row, so climbing waits for one load per level)."""
    k = child.shape[0]
    parent = np.full((k, 2), -1, dtype=np.int64)
    leaf_of = np.zeros(m, dtype=np.int64)
    for node in range(k):
        ch = child[node]
        if ch >= 0:
            parent[ch, 0], parent[ch, 1] = node, ch + 1
            parent[ch + 1, 0], parent[ch + 1, 1] = node, ch
        else:
            for j in range(start[node], start[node] + count[node]):
                leaf_of[j] = node
    return parent, leaf_of


@nb.njit(cache=True, inline="always")
def nearest_point(x, y, hint, g, stack, tie_j, tie_w):  # type: ignore[no-untyped-def]
    """Nearest boundary point of ``(x, y)`` (local coordinates) for compiled callers.

    ``g`` is :meth:`BRep.kernel_data`'s tuple; ``hint`` a leaf slot to start from (the answer
    for a nearby point, or -1); ``stack`` a float work array of size ``2 * _STACK`` (node and
    box distance), ``tie_j``, ``tie_w`` int work arrays of size ``_TIES``.  Returns the signed
    distance (negative inside), the foot, the piece and the leaf slot (the hint for the next
    point).

    Inlined into its callers: a call would reference-count each of ``g``'s arrays per point,
    which costs as much as the search on a small boundary.
    """
    return _nearest_point(x, y, hint, g[10], g[11], g[12], g[13], g[20], g[21], g[22], g[23],
                          g[24], stack, tie_j, tie_w)


@nb.njit(cache=True, inline="always")
def _nearest_point(x, y, hint, child, start, count, order, lt, box, parent, leaf_of, st, stack,
                   tie_j, tie_w):  # type: ignore[no-untyped-def]
    # With a hint the search starts at the hint's leaf and climbs to the root, searching each
    # ancestor's other child only if its box is nearer than the best piece so far: for a
    # nearby point, one box test per level instead of a descent from the root that tests
    # both children at every level and pushes and pops the path.
    best = np.inf
    bj = -1
    fx = fy = 0.0
    nties = 0
    up = leaf_of[hint] if hint >= 0 else 0
    stack[0] = up
    stack[1] = 0.0
    sp = 1
    while True:
        while sp > 0:
            sp -= 1
            if stack[2 * sp + 1] > best:
                continue  # best has improved since this node was pushed
            node = int(stack[2 * sp])
            ch = child[node]
            if ch < 0:
                for j in range(start[node], start[node] + count[node]):
                    d2, gx, gy, where = _foot(lt, j, x, y)
                    if d2 < best:
                        best, bj, fx, fy = d2, j, gx, gy
                        tie_j[0], tie_w[0] = j, where
                        nties = 1
                    elif d2 == best and nties < _TIES:
                        tie_j[nties], tie_w[nties] = j, where
                        nties += 1
                continue
            dl = _box_gap(box, ch, x, y)
            dr = _box_gap(box, ch + 1, x, y)
            # Push the farther child first so the nearer one is searched first.
            if dl <= dr:
                if dr <= best:
                    stack[2 * sp], stack[2 * sp + 1] = ch + 1, dr
                    sp += 1
                if dl <= best:
                    stack[2 * sp], stack[2 * sp + 1] = ch, dl
                    sp += 1
            else:
                if dl <= best:
                    stack[2 * sp], stack[2 * sp + 1] = ch, dl
                    sp += 1
                if dr <= best:
                    stack[2 * sp], stack[2 * sp + 1] = ch + 1, dr
                    sp += 1
        if up <= 0:
            break  # the root's subtree is done
        other = parent[up, 1]
        up = parent[up, 0]
        gap = _box_gap(box, other, x, y)
        if gap <= best:
            stack[0], stack[1] = other, gap
            sp = 1
    # Ties at the nearest distance: the same vertex reached from two pieces, or several loops
    # through one point (operands touching there): inside any wedge is inside.
    inside = False
    for t in range(nties):
        if _inside(lt, st, tie_j[t], tie_w[t], x, y):
            inside = True
            break
    d = math.sqrt(best)
    return (-d if inside else d), fx, fy, (order[bj] if bj >= 0 else -1), bj


@nb.njit(cache=True, nogil=True)
def _query_z(qz, lo, hi, g, dz, fz, kz):  # type: ignore[no-untyped-def]
    """Signed distance, foot and piece of the Z-ordered points ``qz[lo:hi]`` into ``dz``,
    ``fz``, ``kz`` at the same rows; each search starts from the previous answer's leaf, the
    first from the root."""
    stack = np.empty(2 * _STACK)
    tie_j = np.empty(_TIES, dtype=np.int64)
    tie_w = np.empty(_TIES, dtype=np.int64)
    child, start, count, order, lt, box = g[10], g[11], g[12], g[13], g[20], g[21]
    parent, leaf_of, st = g[22], g[23], g[24]
    last = -1
    for s in range(lo, hi):
        d, fx, fy, k, last = _nearest_point(qz[s, 0], qz[s, 1], last, child, start, count, order,
                                            lt, box, parent, leaf_of, st, stack, tie_j, tie_w)
        dz[s] = d
        fz[s, 0], fz[s, 1] = fx, fy
        kz[s] = k


@nb.njit(cache=True)
def nearest(q, g):  # type: ignore[no-untyped-def]
    """Signed distance (negative inside), foot point and piece of each point of ``q (n, 2)``.

    Points are visited along a Z-curve and each search starts from the leaf of the previous
    point's nearest piece, which bounds the search from the first step (the tables store the
    pieces in leaf order, so a leaf's pieces are contiguous in memory).
    """
    n = q.shape[0]
    zorder = _morton_order(q)
    # Gather the points into Z-order and scatter the answers back in loops of their own: the
    # query loop then reads and writes memory in sequence, and the random accesses, being
    # independent of one another, overlap (interleaved with the queries, they cost as much).
    qz = np.empty((n, 2))
    for s in range(n):
        qz[s, 0], qz[s, 1] = q[zorder[s], 0], q[zorder[s], 1]
    dz = np.empty(n)
    fz = np.empty((n, 2))
    kz = np.empty(n, dtype=np.int64)
    _query_z(qz, 0, n, g, dz, fz, kz)
    dist = np.empty(n)
    foot = np.empty((n, 2))
    piece = np.empty(n, dtype=np.int64)
    for s in range(n):
        i = zorder[s]
        dist[i] = dz[s]
        foot[i, 0], foot[i, 1] = fz[s, 0], fz[s, 1]
        piece[i] = kz[s]
    return dist, foot, piece




def signed_distance(q, g):  # type: ignore[no-untyped-def]
    """The signed distances of :func:`nearest`, over chunks of the Z-ordered points on several
    threads.

    The distance is the least over every piece and its sign comes from every piece at that
    distance (up to ``_TIES`` of them), whichever the search meets first, so a chunk that
    starts its search from the root instead of its predecessor's leaf gives the same number.
    (The foot and piece of an exact tie are the first met: :func:`nearest` keeps its one
    order for those.)
    """
    n = q.shape[0]
    if not threads.worth(n):
        return nearest(q, g)[0]
    zorder = _morton_order(q)
    qz = np.ascontiguousarray(q[zorder])
    dz = np.empty(n)
    fz = np.empty((n, 2))
    kz = np.empty(n, dtype=np.int64)
    threads.each(n, lambda lo, hi: _query_z(qz, lo, hi, g, dz, fz, kz))
    out = np.empty(n)
    out[zorder] = dz
    return out


@nb.njit(cache=True)
def box_pairs(lo, hi, node_lo, node_hi, child, start, count, order, pad):  # type: ignore[no-untyped-def]
    """Pairs ``(i, k)``: box ``i`` of ``lo, hi`` overlaps box ``k`` of the hierarchy (within
    ``pad``).  Returns an ``(p, 2)`` array."""
    n = lo.shape[0]
    cap = 16 * n + 16
    out = np.empty((cap, 2), dtype=np.int64)
    npairs = 0
    stack = np.empty(_STACK, dtype=np.int64)
    for i in range(n):
        x0, y0, x1, y1 = lo[i, 0] - pad, lo[i, 1] - pad, hi[i, 0] + pad, hi[i, 1] + pad
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            node = stack[sp]
            if node_lo[node, 0] > x1 or node_hi[node, 0] < x0 or node_lo[node, 1] > y1 or node_hi[
                node, 1
            ] < y0:
                continue
            ch = child[node]
            if ch >= 0:
                stack[sp] = ch
                stack[sp + 1] = ch + 1
                sp += 2
                continue
            for j in range(start[node], start[node] + count[node]):
                if npairs == cap:
                    grown = np.empty((2 * cap, 2), dtype=np.int64)
                    grown[:cap] = out
                    out = grown
                    cap *= 2
                out[npairs, 0] = i
                out[npairs, 1] = order[j]
                npairs += 1
    return out[:npairs].copy()


# --- intersections of pieces (CSG) -----------------------------------------------------------


@nb.njit(cache=True)
def _on_piece(k, x, y, p0, p1, c, r, a0, sw, tol):  # type: ignore[no-untyped-def]
    d2, _, _, _ = piece_foot(k, x, y, p0, p1, c, r, a0, sw)
    return d2 <= tol * tol


#: Crossings of a circle with a line or circle that is nearly tangent to it are one tangent
#: point when the squared half-chord is below ``_TANGENT * r * (r + distance)``: it is a
#: difference of squares of lengths near r, so its rounding error is a few ulps of r^2, and
#: its square root, the half-chord, is uncertain by ~1e-8 r.  Taken as two crossings, a circle
#: tangent to a rectangle's side at its corner split the side 5e-9 from the corner, a vertex
#: the corner could not snap to (found by fuzzing), and the boundary did not close.  One point
#: at the foot of the centre is well conditioned; it moves a true pair of crossings ~1e-7 r
#: apart onto their midpoint.
_TANGENT = 64 * 2.220446049250313e-16


@nb.njit(cache=True)
def split_points(pairs, p0, p1, c, r, a0, sw, tol):  # type: ignore[no-untyped-def]
    """Points where the pieces of each pair meet, as records ``(piece, x, y)``.

    For each pair: the crossings of the two curves (segment-segment, segment-arc, arc-arc,
    tangent points counted once), and every end point of one piece that lies within ``tol`` of
    the other (T-junctions, touching at a point, collinear and co-circular overlaps).
    """
    npairs = pairs.shape[0]
    rec_k = np.empty(8 * npairs, dtype=np.int64)
    rec_xy = np.empty((8 * npairs, 2))
    nrec = 0
    px = np.empty(2)
    py = np.empty(2)
    for q in range(npairs):
        i, j = pairs[q, 0], pairs[q, 1]
        npts = 0
        if sw[i] == 0.0 and sw[j] == 0.0:
            ax, ay = p0[i, 0], p0[i, 1]
            rx, ry = p1[i, 0] - ax, p1[i, 1] - ay
            bx, by = p0[j, 0], p0[j, 1]
            sx, sy = p1[j, 0] - bx, p1[j, 1] - by
            den = rx * sy - ry * sx
            if abs(den) > 1e-12 * math.hypot(rx, ry) * math.hypot(sx, sy):
                t = ((bx - ax) * sy - (by - ay) * sx) / den
                t = min(max(t, 0.0), 1.0)
                px[0], py[0] = ax + t * rx, ay + t * ry
                npts = 1
        elif sw[i] != 0.0 and sw[j] != 0.0:
            dx, dy = c[j, 0] - c[i, 0], c[j, 1] - c[i, 1]
            d = math.hypot(dx, dy)
            r1, r2 = r[i], r[j]
            if d > tol and d <= r1 + r2 + tol and d >= abs(r1 - r2) - tol:
                a = (d * d + r1 * r1 - r2 * r2) / (2.0 * d)
                h2 = r1 * r1 - a * a
                ex, ey = dx / d, dy / d
                if h2 <= max(tol * tol, _TANGENT * r1 * (r1 + d)):  # tangent: one point
                    px[0], py[0] = c[i, 0] + a * ex, c[i, 1] + a * ey
                    npts = 1
                else:
                    h = math.sqrt(h2)
                    px[0], py[0] = c[i, 0] + a * ex - h * ey, c[i, 1] + a * ey + h * ex
                    px[1], py[1] = c[i, 0] + a * ex + h * ey, c[i, 1] + a * ey - h * ex
                    npts = 2
        else:
            s, a = (i, j) if sw[i] == 0.0 else (j, i)
            ax, ay = p0[s, 0], p0[s, 1]
            rx, ry = p1[s, 0] - ax, p1[s, 1] - ay
            l2 = rx * rx + ry * ry
            if l2 > 0.0:
                t0 = ((c[a, 0] - ax) * rx + (c[a, 1] - ay) * ry) / l2
                fx, fy = ax + t0 * rx, ay + t0 * ry
                hh = math.hypot(c[a, 0] - fx, c[a, 1] - fy)
                if hh <= r[a] + tol:
                    g2 = r[a] * r[a] - hh * hh
                    if g2 <= max(tol * tol, _TANGENT * r[a] * (r[a] + hh)):  # tangent: one point
                        px[0], py[0] = fx, fy
                        npts = 1
                    else:
                        g = math.sqrt(g2 / l2)
                        px[0], py[0] = fx - g * rx, fy - g * ry
                        px[1], py[1] = fx + g * rx, fy + g * ry
                        npts = 2
        for u in range(npts):
            if _on_piece(i, px[u], py[u], p0, p1, c, r, a0, sw, tol) and _on_piece(
                j, px[u], py[u], p0, p1, c, r, a0, sw, tol
            ):
                rec_k[nrec], rec_xy[nrec, 0], rec_xy[nrec, 1] = i, px[u], py[u]
                rec_k[nrec + 1], rec_xy[nrec + 1, 0], rec_xy[nrec + 1, 1] = j, px[u], py[u]
                nrec += 2
        for a, b in ((i, j), (j, i)):
            for e in range(2):
                ex = p0[b, 0] if e == 0 else p1[b, 0]
                ey = p0[b, 1] if e == 0 else p1[b, 1]
                if _on_piece(a, ex, ey, p0, p1, c, r, a0, sw, tol):
                    rec_k[nrec], rec_xy[nrec, 0], rec_xy[nrec, 1] = a, ex, ey
                    nrec += 1
    return rec_k[:nrec].copy(), rec_xy[:nrec].copy()


# --- exact orientation and the simplicity sweep ------------------------------------------------

_SPLITTER = 134217729.0  # 2^27 + 1
_ORIENT_BOUND = 3.3306690738754716e-16  # (3 + 16 eps) eps, Shewchuk's ccwerrboundA


@nb.njit(cache=True, inline="always")
def _two_sum(a, b):  # type: ignore[no-untyped-def]
    s = a + b
    bv = s - a
    av = s - bv
    return s, (a - av) + (b - bv)


@nb.njit(cache=True, inline="always")
def _two_prod(a, b):  # type: ignore[no-untyped-def]
    p = a * b
    c = _SPLITTER * a
    ah = c - (c - a)
    al = a - ah
    c = _SPLITTER * b
    bh = c - (c - b)
    bl = b - bh
    return p, al * bl - (((p - ah * bh) - al * bh) - ah * bl)


@nb.njit(cache=True)
def _orient_exact(ax, ay, bx, by, cx, cy):  # type: ignore[no-untyped-def]
    """Exact sign of the orientation determinant, by expansion arithmetic (Shewchuk)."""
    terms = np.empty(16)
    acx, acx_e = _two_sum(ax, -cx)
    acy, acy_e = _two_sum(ay, -cy)
    bcx, bcx_e = _two_sum(bx, -cx)
    bcy, bcy_e = _two_sum(by, -cy)
    n = 0
    for u, v, s in (
        (acx, bcy, 1.0), (acx, bcy_e, 1.0), (acx_e, bcy, 1.0), (acx_e, bcy_e, 1.0),
        (acy, bcx, -1.0), (acy, bcx_e, -1.0), (acy_e, bcx, -1.0), (acy_e, bcx_e, -1.0),
    ):
        p, e = _two_prod(u, v)
        terms[n] = s * p
        terms[n + 1] = s * e
        n += 2
    # Grow an expansion term by term (components stay non-overlapping, increasing).
    exp = np.zeros(17)
    m = 0
    for t in range(16):
        q = terms[t]
        for k in range(m):
            q, h = _two_sum(q, exp[k])
            exp[k] = h
        exp[m] = q
        m += 1
    for k in range(m - 1, -1, -1):
        if exp[k] != 0.0:
            return 1 if exp[k] > 0.0 else -1
    return 0


@nb.njit(cache=True)
def orient(ax, ay, bx, by, cx, cy):  # type: ignore[no-untyped-def]
    """Sign of the turn a -> b -> c (+1 left, -1 right, 0 collinear), exact."""
    l = (ax - cx) * (by - cy)
    r = (ay - cy) * (bx - cx)
    det = l - r
    if abs(det) > _ORIENT_BOUND * (abs(l) + abs(r)):
        return 1 if det > 0.0 else -1
    return _orient_exact(ax, ay, bx, by, cx, cy)


@nb.njit(cache=True)
def _between(ax, ay, bx, by, px, py):  # type: ignore[no-untyped-def]
    """For p collinear with a-b: whether p lies on the closed segment."""
    return min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by)


@nb.njit(cache=True)
def segments_meet(a, b, i, j):  # type: ignore[no-untyped-def]
    """Whether closed segments i and j share a point (exact)."""
    o1 = orient(a[i, 0], a[i, 1], b[i, 0], b[i, 1], a[j, 0], a[j, 1])
    o2 = orient(a[i, 0], a[i, 1], b[i, 0], b[i, 1], b[j, 0], b[j, 1])
    o3 = orient(a[j, 0], a[j, 1], b[j, 0], b[j, 1], a[i, 0], a[i, 1])
    o4 = orient(a[j, 0], a[j, 1], b[j, 0], b[j, 1], b[i, 0], b[i, 1])
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    if o1 == 0 and _between(a[i, 0], a[i, 1], b[i, 0], b[i, 1], a[j, 0], a[j, 1]):
        return True
    if o2 == 0 and _between(a[i, 0], a[i, 1], b[i, 0], b[i, 1], b[j, 0], b[j, 1]):
        return True
    if o3 == 0 and _between(a[j, 0], a[j, 1], b[j, 0], b[j, 1], a[i, 0], a[i, 1]):
        return True
    if o4 == 0 and _between(a[j, 0], a[j, 1], b[j, 0], b[j, 1], b[i, 0], b[i, 1]):
        return True
    return False


@nb.njit(cache=True)
def _bad_pair(a, b, nxt, i, j):  # type: ignore[no-untyped-def]
    """Whether segments i and j of closed rings meet other than as consecutive edges joined
    at their common vertex (which may not fold back onto each other)."""
    if i == j:
        return False
    if nxt[i] == j or nxt[j] == i:
        if nxt[i] == j and nxt[j] == i:  # a two-edge ring: degenerate
            return True
        first, second = (i, j) if nxt[i] == j else (j, i)
        # shared vertex v = b[first] = a[second]; p before it, q after it
        vx, vy = b[first, 0], b[first, 1]
        px, py = a[first, 0], a[first, 1]
        qx, qy = b[second, 0], b[second, 1]
        if orient(px, py, vx, vy, qx, qy) != 0:
            return False
        return (px - vx) * (qx - vx) + (py - vy) * (qy - vy) > 0.0  # folds back
    return segments_meet(a, b, i, j)


@nb.njit(cache=True)
def _above(a, b, lft, rgt, s, u):  # type: ignore[no-untyped-def]
    """Whether segment u (being inserted at its left end) goes above segment s."""
    ls, rs, lu, ru = lft[s], rgt[s], lft[u], rgt[u]
    sx0, sy0 = (a[s, 0], a[s, 1]) if ls == 0 else (b[s, 0], b[s, 1])
    sx1, sy1 = (b[s, 0], b[s, 1]) if rs == 1 else (a[s, 0], a[s, 1])
    ux0, uy0 = (a[u, 0], a[u, 1]) if lu == 0 else (b[u, 0], b[u, 1])
    ux1, uy1 = (b[u, 0], b[u, 1]) if ru == 1 else (a[u, 0], a[u, 1])
    o = orient(sx0, sy0, sx1, sy1, ux0, uy0)
    if o == 0:
        o = orient(sx0, sy0, sx1, sy1, ux1, uy1)
    return o > 0


def first_crossing(a, b, nxt):  # type: ignore[no-untyped-def]
    """A pair of segments of closed rings that cross, touch or overlap, or (-1, -1).

    A Shamos-Hoey sweep in lexicographic (x, y) order with exact orientation tests: every pair
    of segments that become neighbours on the sweep line is tested; the first bad pair ends the
    sweep.  Segment k runs from ``a[k]`` to ``b[k]``; ``nxt[k]`` is the segment after it on its
    ring (consecutive segments may share their common vertex).  The sweep-line status is a
    sorted array (binary search, shifted on insert and delete).
    """
    m = a.shape[0]
    # Which end of each segment comes first in (x, y) order: 0 = a, 1 = b.
    lft = ((b[:, 0] < a[:, 0]) | ((b[:, 0] == a[:, 0]) & (b[:, 1] < a[:, 1]))).astype(np.int64)
    first = np.where(lft[:, None] == 0, a, b)
    last = np.where(lft[:, None] == 0, b, a)
    ex = np.concatenate([first[:, 0], last[:, 0]])
    ey = np.concatenate([first[:, 1], last[:, 1]])
    etype = np.repeat(np.array([0, 1]), m)  # inserts before deletes at equal points
    order = np.lexsort((etype, ey, ex)).astype(np.int64)
    i, j = _sweep(a, b, nxt, lft, order)
    return int(i), int(j)


@nb.njit(cache=True)
def _sweep(a, b, nxt, lft, order):  # type: ignore[no-untyped-def]
    m = a.shape[0]
    rgt = 1 - lft
    status = np.empty(m, dtype=np.int64)
    pos = np.full(m, -1, dtype=np.int64)
    ns = 0
    for e in order:
        k = e % m
        if e < m:
            lo, hi = 0, ns
            while lo < hi:
                mid = (lo + hi) // 2
                if _above(a, b, lft, rgt, status[mid], k):
                    lo = mid + 1
                else:
                    hi = mid
            for t in range(ns, lo, -1):
                status[t] = status[t - 1]
                pos[status[t]] = t
            status[lo] = k
            pos[k] = lo
            ns += 1
            if lo > 0 and _bad_pair(a, b, nxt, status[lo - 1], k):
                return status[lo - 1], k
            if lo + 1 < ns and _bad_pair(a, b, nxt, k, status[lo + 1]):
                return k, status[lo + 1]
        else:
            at = pos[k]
            for t in range(at, ns - 1):
                status[t] = status[t + 1]
                pos[status[t]] = t
            ns -= 1
            pos[k] = -1
            if 0 < at < ns and _bad_pair(a, b, nxt, status[at - 1], status[at]):
                return status[at - 1], status[at]
    return -1, -1


@nb.njit(cache=True)
def containment(points, a, b, ring, n_rings):  # type: ignore[no-untyped-def]
    """``inside[i, j]``: point i lies inside ring j (even-odd rule over ring j's segments).

    Used for rings already known not to meet, so no point lies on another ring."""
    n = points.shape[0]
    inside = np.zeros((n, n_rings), dtype=np.bool_)
    for k in range(a.shape[0]):
        ay, by = a[k, 1], b[k, 1]
        j = ring[k]
        for i in range(n):
            y = points[i, 1]
            if (ay > y) != (by > y):
                xint = a[k, 0] + (y - ay) * (b[k, 0] - a[k, 0]) / (by - ay)
                if points[i, 0] < xint:
                    inside[i, j] = not inside[i, j]
    return inside
