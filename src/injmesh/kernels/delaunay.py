"""Incremental Delaunay triangulation with a live adjacency structure (numba kernels).

The structure
-------------
Triangles are rows of three arrays sized to a capacity:

* ``tri (cap, 3) int32`` -- vertices, counter-clockwise;
* ``nbr (cap, 3) int32`` -- ``nbr[t, k]`` is the triangle across the edge opposite corner k,
  i.e. the edge ``(tri[t, k+1], tri[t, k+2])`` (indices mod 3);
* ``con (cap, 3) uint8`` -- 1 where that edge is constrained (never flipped);
* ``vt (n,) int32`` -- one triangle incident to each vertex (-1: vertex not in the mesh);
* ``meta (4,) int64`` -- rows in use, free rows, the walk's start triangle, spare;
* ``free (cap,) int32`` -- a stack of freed rows (removal frees two rows, insertion takes two).

Internally the convex hull is closed by *ghost triangles*: each hull edge u -> v (interior on
its left) has a ghost ``(v, u, GHOST)`` whose third vertex is a virtual vertex at infinity
(``GHOST = -1``).  Every live triangle then has three neighbours, point location outside the hull
ends in a ghost, and insertion outside the hull is an ordinary split.  A ghost's "circumcircle"
is the open half-plane beyond its hull edge, which makes Lawson's flip rule hold unchanged on
the hull (a reflex hull vertex is filled by flipping the ghost-ghost edge at it).  Free rows
hold ``DEAD = -2``.  ``_compact`` turns the structure into the public convention: only the real
triangles, with ``-1`` for a neighbour beyond the hull.  :class:`LiveTriangulation` owns the
arrays and grows them; the kernels never allocate rows themselves.

Every decision -- walk steps, on-edge and duplicate tests, flips, ears -- uses the exact
predicates of :mod:`injmesh.kernels.predicates`, so collinear input, cocircular lattices and
far offsets (1e9) give a valid triangulation.  Ties are broken by the order of operations,
which is fixed: the output is bit-identical from run to run.  No kernel runs threads.

Insertion order is biased-randomized (BRIO rounds, each along a Hilbert curve); each point is
located by a visibility walk from the last triangle created, inserted by a 1-3 split (2-4 on
an edge) and made Delaunay by Lawson flips.  Removal re-triangulates the vertex's star by ear
clipping with Delaunay ears (O(degree^3): meant for mesh vertices of small degree); edge
recovery follows Sloan's flip algorithm (S. W. Sloan, "A fast algorithm for generating
constrained Delaunay triangulations", Computers & Structures 47, 1993).

Examples
--------
>>> import numpy as np
>>> from injmesh.kernels.delaunay import delaunay
>>> delaunay(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])).shape
(2, 3)
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from .predicates import incircle, orient2d

GHOST = -1
DEAD = -2

# Status codes returned by the kernels (negative: failure).
OK = 0
ERR_COLLINEAR = -1  # fewer than three distinct, non-collinear points
ERR_NOT_FOUND = -2  # the vertex or edge is not in the triangulation
ERR_CONSTRAINED = -3  # the operation would flip or remove a constrained edge
# recover_edge returns -(10 + w) when vertex w lies on the segment to recover;
# flip_to_delaunay returns -(10 + t) when triangle row t is inverted.
ERR_DEGENERATE = -5  # the operation would leave no triangle
ERR_LOOP = -6  # an iteration cap was reached (the structure is not a valid triangulation)
ERR_NOT_CONVEX = -7  # the quadrilateral around the edge is not strictly convex

IntArray = NDArray[np.int32]
FloatArray = NDArray[np.float64]


# ---------------------------------------------------------------------------------------------
# Small helpers


@njit(cache=True, inline="always")
def _orient(pts, i, j, k):  # type: ignore[no-untyped-def]
    return orient2d(pts[i, 0], pts[i, 1], pts[j, 0], pts[j, 1], pts[k, 0], pts[k, 1])


@njit(cache=True, inline="always")
def _is_ghost(tri, t):  # type: ignore[no-untyped-def]
    return tri[t, 0] == GHOST or tri[t, 1] == GHOST or tri[t, 2] == GHOST


@njit(cache=True, inline="always")
def _corner(arr, t, v):  # type: ignore[no-untyped-def]
    """Index 0..2 of value v in row t of arr (-1 when absent)."""
    if arr[t, 0] == v:
        return 0
    if arr[t, 1] == v:
        return 1
    if arr[t, 2] == v:
        return 2
    return -1


@njit(cache=True, inline="always")
def _push(stack, sp, val):  # type: ignore[no-untyped-def]
    if sp >= stack.shape[0]:
        grown = np.empty(2 * stack.shape[0] + 16, dtype=stack.dtype)
        grown[:sp] = stack[:sp]
        stack = grown
    stack[sp] = val
    return stack, sp + 1


@njit(cache=True)
def _alloc(meta, free):  # type: ignore[no-untyped-def]
    """A free triangle row: the last freed one, else the next unused one (meta[0])."""
    if meta[1] > 0:
        meta[1] -= 1
        return free[meta[1]]
    t = meta[0]
    meta[0] += 1
    return t


@njit(cache=True)
def _release(tri, nbr, con, meta, free, t):  # type: ignore[no-untyped-def]
    for k in range(3):
        tri[t, k] = DEAD
        nbr[t, k] = -1
        con[t, k] = 0
    free[meta[1]] = t
    meta[1] += 1


@njit(cache=True)
def _set_vt(tri, vt, t):  # type: ignore[no-untyped-def]
    for k in range(3):
        v = tri[t, k]
        if v >= 0:
            vt[v] = t


@njit(cache=True)
def _replace_nbr(nbr, t, old, new):  # type: ignore[no-untyped-def]
    if t < 0:
        return
    for k in range(3):
        if nbr[t, k] == old:
            nbr[t, k] = new
            return


@njit(cache=True)
def _conflict(pts, tri, t, d):  # type: ignore[no-untyped-def]
    """Is vertex d strictly inside the circumcircle of triangle t (generalised to ghosts)?

    A ghost (v, u, GHOST) stands for the half-plane beyond its hull edge u -> v: d conflicts
    with it when strictly beyond that edge.
    """
    if d < 0:
        return False
    a = tri[t, 0]
    b = tri[t, 1]
    c = tri[t, 2]
    if c == GHOST:
        return _orient(pts, a, b, d) > 0.0
    if a == GHOST:
        return _orient(pts, b, c, d) > 0.0
    if b == GHOST:
        return _orient(pts, c, a, d) > 0.0
    return (
        incircle(
            pts[a, 0], pts[a, 1], pts[b, 0], pts[b, 1], pts[c, 0], pts[c, 1], pts[d, 0], pts[d, 1]
        )
        > 0.0
    )


# ---------------------------------------------------------------------------------------------
# Flips


@njit(cache=True)
def _flip(tri, nbr, con, vt, t, k):  # type: ignore[no-untyped-def]
    """Flip the edge opposite corner k of t; returns the other triangle u.

    t = (a, b, c) and u = (d, c, b) become t = (a, b, d) and u = (a, d, c): corner 0 of both is
    a, the apex of t.  The caller has checked that the flip is legal.
    """
    k1 = (k + 1) % 3
    k2 = (k + 2) % 3
    a = tri[t, k]
    b = tri[t, k1]
    c = tri[t, k2]
    u = nbr[t, k]
    l = _corner(nbr, u, t)
    l1 = (l + 1) % 3
    l2 = (l + 2) % 3
    d = tri[u, l]
    n_ab = nbr[t, k2]
    n_ca = nbr[t, k1]
    n_bd = nbr[u, l1]
    n_dc = nbr[u, l2]
    c_ab = con[t, k2]
    c_ca = con[t, k1]
    c_bd = con[u, l1]
    c_dc = con[u, l2]
    tri[t, 0] = a
    tri[t, 1] = b
    tri[t, 2] = d
    nbr[t, 0] = n_bd
    nbr[t, 1] = u
    nbr[t, 2] = n_ab
    con[t, 0] = c_bd
    con[t, 1] = 0
    con[t, 2] = c_ab
    tri[u, 0] = a
    tri[u, 1] = d
    tri[u, 2] = c
    nbr[u, 0] = n_dc
    nbr[u, 1] = n_ca
    nbr[u, 2] = t
    con[u, 0] = c_dc
    con[u, 1] = c_ca
    con[u, 2] = 0
    _replace_nbr(nbr, n_bd, u, t)
    _replace_nbr(nbr, n_ca, t, u)
    if a >= 0:
        vt[a] = t
    if b >= 0:
        vt[b] = t
    if c >= 0:
        vt[c] = u
    if d >= 0:
        vt[d] = u
    return u


@njit(cache=True)
def _edge_illegal(pts, tri, nbr, con, t, k):  # type: ignore[no-untyped-def]
    """Should Lawson flip the edge opposite corner k of t?"""
    u = nbr[t, k]
    if u < 0 or con[t, k] != 0:
        return False
    gt = _is_ghost(tri, t)
    gu = _is_ghost(tri, u)
    if gt != gu:
        return False  # a hull edge: never flipped
    d = tri[u, _corner(nbr, u, t)]
    if gt:
        # Two ghosts share the edge (w, GHOST): flip when w is a reflex hull vertex, which
        # fills the notch with a real triangle (only where it is strictly counter-clockwise).
        if tri[t, k] == GHOST:
            return False
        return _conflict(pts, tri, t, d)
    return _conflict(pts, tri, t, d)


@njit(cache=True)
def _legalize(pts, tri, nbr, con, vt, stack, sp, cap, log=None):  # type: ignore[no-untyped-def]
    """Lawson flips from a stack of edges (t * 3 + k) until all are locally Delaunay.

    Returns (stack, number of flips); -1 flips when ``cap`` flips were exceeded.  ``log``
    (optional, a list) gets ``(t, u, b, c, a, d)`` for each flip: rows t and u changed, edge
    b-c gave way to a-d.
    """
    flips = 0
    while sp > 0:
        sp -= 1
        code = np.int64(stack[sp])  # int64 like the callers' row loops: one compile of the callees
        t = code // 3
        k = code - 3 * t
        if tri[t, 0] == DEAD:
            continue
        if not _edge_illegal(pts, tri, nbr, con, t, k):
            continue
        u = _flip(tri, nbr, con, vt, t, k)
        if log is not None:
            # t = (a, b, d), u = (a, d, c) now: edge b-c gave way to a-d.
            log.append((np.int64(t), np.int64(u), np.int64(tri[t, 1]), np.int64(tri[u, 2]),
                        np.int64(tri[t, 0]), np.int64(tri[t, 2])))
        flips += 1
        if flips > cap:
            return stack, -1
        stack, sp = _push(stack, sp, 3 * t + 0)
        stack, sp = _push(stack, sp, 3 * t + 2)
        stack, sp = _push(stack, sp, 3 * u + 0)
        stack, sp = _push(stack, sp, 3 * u + 1)
    return stack, flips


@njit(cache=True)
def _legalize_vertex(pts, tri, nbr, con, vt, p, stack, sp):  # type: ignore[no-untyped-def]
    """Lawson flips after inserting p: the stack holds triangles around p; only the edges
    opposite p can be illegal (flips keep p at corner 0 of both new triangles)."""
    while sp > 0:
        sp -= 1
        t = np.int64(stack[sp])
        k = _corner(tri, t, p)
        if _edge_illegal(pts, tri, nbr, con, t, k):
            u = _flip(tri, nbr, con, vt, t, k)
            stack, sp = _push(stack, sp, t)
            stack, sp = _push(stack, sp, u)
    return stack


# ---------------------------------------------------------------------------------------------
# Point location


@njit(cache=True)
def _any_live_real(tri, meta):  # type: ignore[no-untyped-def]
    for t in range(meta[0]):
        if tri[t, 0] != DEAD and not _is_ghost(tri, t):
            return t
    return -1


@njit(cache=True)
def _locate(pts, tri, nbr, meta, px, py, state):  # type: ignore[no-untyped-def]
    """Visibility walk towards (px, py) from triangle meta[2].

    Returns (t, kind, k): kind 0 strictly inside real triangle t; 1 on the edge opposite corner
    k of t; 2 equal to vertex tri[t, k]; 3 outside the hull, t a ghost the point is beyond;
    -1 nothing found (empty structure).  Edges are tried from a pseudo-random corner so the
    walk cannot cycle on a non-Delaunay triangulation; a capped walk falls back to a scan.
    """
    t = meta[2]
    if t < 0 or t >= meta[0] or tri[t, 0] == DEAD:
        t = _any_live_real(tri, meta)
        if t < 0:
            return -1, -1, -1
    if _is_ghost(tri, t):
        t = nbr[t, _corner(tri, t, GHOST)]
    cap = 4 * meta[0] + 64
    prev = -1
    for _ in range(cap):
        state[0] = (state[0] * 1103515245 + 12345) & 0x7FFFFFFF
        r = (state[0] >> 16) % 3
        moved = False
        zeros = 0
        zk0 = -1
        zk1 = -1
        for j in range(3):
            k = (r + j) % 3
            if nbr[t, k] == prev:
                continue  # the edge just crossed: the point is strictly on this side
            b = tri[t, (k + 1) % 3]
            c = tri[t, (k + 2) % 3]
            o = orient2d(pts[b, 0], pts[b, 1], pts[c, 0], pts[c, 1], px, py)
            if o < 0.0:
                prev = t
                t = nbr[t, k]
                moved = True
                break
            if o == 0.0:
                if zeros == 0:
                    zk0 = k
                else:
                    zk1 = k
                zeros += 1
        if moved:
            if t < 0:
                return -1, 3, -1
            if _is_ghost(tri, t):
                return t, 3, _corner(tri, t, GHOST)
            continue
        if zeros == 0:
            return t, 0, 0
        if zeros == 1:
            return t, 1, zk0
        return t, 2, 3 - zk0 - zk1
    return _locate_scan(pts, tri, meta, px, py)


@njit(cache=True)
def _locate_scan(pts, tri, meta, px, py):  # type: ignore[no-untyped-def]
    """Point location by testing every triangle: the fallback when a walk does not end."""
    for t in range(meta[0]):
        if tri[t, 0] == DEAD or _is_ghost(tri, t):
            continue
        zeros = 0
        zk0 = -1
        zk1 = -1
        inside = True
        for k in range(3):
            b = tri[t, (k + 1) % 3]
            c = tri[t, (k + 2) % 3]
            o = orient2d(pts[b, 0], pts[b, 1], pts[c, 0], pts[c, 1], px, py)
            if o < 0.0:
                inside = False
                break
            if o == 0.0:
                if zeros == 0:
                    zk0 = k
                else:
                    zk1 = k
                zeros += 1
        if inside:
            if zeros == 0:
                return t, 0, 0
            if zeros == 1:
                return t, 1, zk0
            return t, 2, 3 - zk0 - zk1
    for t in range(meta[0]):
        if tri[t, 0] == DEAD or not _is_ghost(tri, t):
            continue
        g = _corner(tri, t, GHOST)
        v = tri[t, (g + 1) % 3]
        u = tri[t, (g + 2) % 3]
        if orient2d(pts[v, 0], pts[v, 1], pts[u, 0], pts[u, 1], px, py) > 0.0:
            return t, 3, g
    return -1, -1, -1


# ---------------------------------------------------------------------------------------------
# Insertion


@njit(cache=True)
def _split3(tri, nbr, con, vt, meta, free, t, p):  # type: ignore[no-untyped-def]
    """Split t = (a, b, c) at p into (a, b, p), (b, c, p), (c, a, p); returns the two new rows."""
    a = tri[t, 0]
    b = tri[t, 1]
    c = tri[t, 2]
    na = nbr[t, 0]
    nb = nbr[t, 1]
    ca = con[t, 0]
    cb = con[t, 1]
    t1 = _alloc(meta, free)
    t2 = _alloc(meta, free)
    tri[t, 2] = p
    nbr[t, 0] = t1
    nbr[t, 1] = t2
    con[t, 0] = 0
    con[t, 1] = 0
    tri[t1, 0] = b
    tri[t1, 1] = c
    tri[t1, 2] = p
    nbr[t1, 0] = t2
    nbr[t1, 1] = t
    nbr[t1, 2] = na
    con[t1, 0] = 0
    con[t1, 1] = 0
    con[t1, 2] = ca
    tri[t2, 0] = c
    tri[t2, 1] = a
    tri[t2, 2] = p
    nbr[t2, 0] = t
    nbr[t2, 1] = t1
    nbr[t2, 2] = nb
    con[t2, 0] = 0
    con[t2, 1] = 0
    con[t2, 2] = cb
    _replace_nbr(nbr, na, t, t1)
    _replace_nbr(nbr, nb, t, t2)
    _set_vt(tri, vt, t)
    _set_vt(tri, vt, t1)
    _set_vt(tri, vt, t2)
    return t1, t2


@njit(cache=True)
def _split_edge(tri, nbr, con, vt, meta, free, t, k, p):  # type: ignore[no-untyped-def]
    """Split the edge opposite corner k of t at p: t, its neighbour u -> four triangles."""
    k1 = (k + 1) % 3
    k2 = (k + 2) % 3
    a = tri[t, k]
    b = tri[t, k1]
    c = tri[t, k2]
    u = nbr[t, k]
    l = _corner(nbr, u, t)
    l1 = (l + 1) % 3
    l2 = (l + 2) % 3
    d = tri[u, l]
    n_ab = nbr[t, k2]
    n_ca = nbr[t, k1]
    n_bd = nbr[u, l1]
    n_dc = nbr[u, l2]
    c_bc = con[t, k]
    c_ab = con[t, k2]
    c_ca = con[t, k1]
    c_bd = con[u, l1]
    c_dc = con[u, l2]
    t1 = _alloc(meta, free)
    u1 = _alloc(meta, free)
    tri[t, 0] = a
    tri[t, 1] = b
    tri[t, 2] = p
    nbr[t, 0] = u1
    nbr[t, 1] = t1
    nbr[t, 2] = n_ab
    con[t, 0] = c_bc
    con[t, 1] = 0
    con[t, 2] = c_ab
    tri[t1, 0] = a
    tri[t1, 1] = p
    tri[t1, 2] = c
    nbr[t1, 0] = u
    nbr[t1, 1] = n_ca
    nbr[t1, 2] = t
    con[t1, 0] = c_bc
    con[t1, 1] = c_ca
    con[t1, 2] = 0
    tri[u, 0] = d
    tri[u, 1] = c
    tri[u, 2] = p
    nbr[u, 0] = t1
    nbr[u, 1] = u1
    nbr[u, 2] = n_dc
    con[u, 0] = c_bc
    con[u, 1] = 0
    con[u, 2] = c_dc
    tri[u1, 0] = d
    tri[u1, 1] = p
    tri[u1, 2] = b
    nbr[u1, 0] = t
    nbr[u1, 1] = n_bd
    nbr[u1, 2] = u
    con[u1, 0] = c_bc
    con[u1, 1] = c_bd
    con[u1, 2] = 0
    _replace_nbr(nbr, n_ca, t, t1)
    _replace_nbr(nbr, n_bd, u, u1)
    _set_vt(tri, vt, t)
    _set_vt(tri, vt, t1)
    _set_vt(tri, vt, u)
    _set_vt(tri, vt, u1)
    return t1, u, u1


@njit(cache=True)
def _insert(pts, tri, nbr, con, vt, meta, free, p, stack, state):  # type: ignore[no-untyped-def]
    """Insert vertex p (its coordinates are pts[p]).

    Returns (-1, stack) when inserted, (v, stack) when p duplicates vertex v (p is then left
    out), (-2, stack) when it cannot be located.
    """
    px = pts[p, 0]
    py = pts[p, 1]
    t, kind, k = _locate(pts, tri, nbr, meta, px, py, state)
    if kind < 0 or t < 0:
        return -2, stack
    if kind == 2:
        return tri[t, k], stack
    sp = 0
    if kind == 1:
        t1, u, u1 = _split_edge(tri, nbr, con, vt, meta, free, t, k, p)
        stack, sp = _push(stack, sp, t)
        stack, sp = _push(stack, sp, t1)
        stack, sp = _push(stack, sp, u)
        stack, sp = _push(stack, sp, u1)
    else:
        t1, t2 = _split3(tri, nbr, con, vt, meta, free, t, p)
        stack, sp = _push(stack, sp, t)
        stack, sp = _push(stack, sp, t1)
        stack, sp = _push(stack, sp, t2)
    stack = _legalize_vertex(pts, tri, nbr, con, vt, p, stack, sp)
    meta[2] = vt[p]
    return -1, stack


# ---------------------------------------------------------------------------------------------
# Construction


@njit(cache=True)
def _hilbert_keys(pts):  # type: ignore[no-untyped-def]
    """Hilbert-curve index of each point on a 2^16 x 2^16 grid over the bounding box."""
    n = pts.shape[0]
    xmin = pts[0, 0]
    xmax = pts[0, 0]
    ymin = pts[0, 1]
    ymax = pts[0, 1]
    for i in range(n):
        xmin = min(xmin, pts[i, 0])
        xmax = max(xmax, pts[i, 0])
        ymin = min(ymin, pts[i, 1])
        ymax = max(ymax, pts[i, 1])
    span = max(xmax - xmin, ymax - ymin)
    side = 65536
    scale = (side - 1) / span if span > 0.0 else 0.0
    keys = np.empty(n, dtype=np.int64)
    for i in range(n):
        x = np.int64((pts[i, 0] - xmin) * scale)
        y = np.int64((pts[i, 1] - ymin) * scale)
        x = min(max(x, 0), side - 1)
        y = min(max(y, 0), side - 1)
        d = np.int64(0)
        s = side // 2
        while s > 0:
            rx = 1 if (x & s) > 0 else 0
            ry = 1 if (y & s) > 0 else 0
            d += np.int64(s) * np.int64(s) * ((3 * rx) ^ ry)
            if ry == 0:
                if rx == 1:
                    x = side - 1 - x
                    y = side - 1 - y
                x, y = y, x
            s //= 2
        keys[i] = d
    return keys


@njit(cache=True)
def _brio_keys(pts):  # type: ignore[no-untyped-def]
    """Sort keys of a biased randomized insertion order (Amenta, Choi, Rote 2003).

    Each point joins round r with probability 2^-(r+1) (the last round holds about half of
    the points), the rounds are inserted from the smallest, and each round runs along the
    Hilbert curve.  The early rounds spread over the whole domain, so later points land in
    well-shaped triangles instead of slivers along a growing front.  The "random" draw is a
    hash of the point's index: the order, hence the triangulation, is reproducible.
    """
    hk = _hilbert_keys(pts)
    n = pts.shape[0]
    rounds = 0
    m = n
    while m > 64:
        m //= 2
        rounds += 1
    keys = np.empty(n, dtype=np.int64)
    for i in range(n):
        # splitmix64 of the index
        z = np.uint64(i) + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
        # r = number of leading one bits: P(r) = 2^-(r+1).
        r = 0
        bit = np.uint64(1) << np.uint64(63)
        while r < rounds and (z & bit) != np.uint64(0):
            r += 1
            bit = bit >> np.uint64(1)
        keys[i] = np.int64(rounds - r) * np.int64(1 << 32) + hk[i]
    return keys


@njit(cache=True)
def _build(pts, order, tri, nbr, con, vt, meta, free, dup):  # type: ignore[no-untyped-def]
    """Insert the points in ``order`` into an empty structure; duplicates go to ``dup``.

    Returns OK, or ERR_COLLINEAR when no three points span a triangle.
    """
    n = order.shape[0]
    for i in range(n):
        vt[order[i]] = -1
    if n < 3:
        return ERR_COLLINEAR
    i0 = order[0]
    j1 = -1
    for j in range(1, n):
        q = order[j]
        if pts[q, 0] != pts[i0, 0] or pts[q, 1] != pts[i0, 1]:
            j1 = j
            break
    if j1 < 0:
        return ERR_COLLINEAR
    i1 = order[j1]
    j2 = -1
    for j in range(j1 + 1, n):
        if _orient(pts, i0, i1, order[j]) != 0.0:
            j2 = j
            break
    if j2 < 0:
        return ERR_COLLINEAR
    i2 = order[j2]
    if _orient(pts, i0, i1, i2) < 0.0:
        i1, i2 = i2, i1
    # The first triangle and its three ghosts.
    meta[0] = 4
    meta[1] = 0
    meta[2] = 0
    tri[0, 0] = i0
    tri[0, 1] = i1
    tri[0, 2] = i2
    nbr[0, 0] = 2
    nbr[0, 1] = 3
    nbr[0, 2] = 1
    tri[1, 0] = i1
    tri[1, 1] = i0
    tri[1, 2] = GHOST
    nbr[1, 0] = 3
    nbr[1, 1] = 2
    nbr[1, 2] = 0
    tri[2, 0] = i2
    tri[2, 1] = i1
    tri[2, 2] = GHOST
    nbr[2, 0] = 1
    nbr[2, 1] = 3
    nbr[2, 2] = 0
    tri[3, 0] = i0
    tri[3, 1] = i2
    tri[3, 2] = GHOST
    nbr[3, 0] = 2
    nbr[3, 1] = 1
    nbr[3, 2] = 0
    for t in range(4):
        for k in range(3):
            con[t, k] = 0
    vt[i0] = 0
    vt[i1] = 0
    vt[i2] = 0
    stack = np.empty(64, dtype=np.int32)
    state = np.zeros(1, dtype=np.int64)
    for j in range(1, n):
        p = order[j]
        if j == j1 or j == j2:
            continue
        res, stack = _insert(pts, tri, nbr, con, vt, meta, free, p, stack, state)
        if res >= 0:
            dup[p] = res
        elif res == -2:
            return ERR_LOOP
    return OK


@njit(cache=True)
def _compact(tri, nbr, m):  # type: ignore[no-untyped-def]
    """Real triangles in row order, and their neighbours renumbered (-1 beyond the hull)."""
    new = np.full(m, -1, dtype=np.int32)
    count = 0
    for t in range(m):
        if tri[t, 0] != DEAD and not _is_ghost(tri, t):
            new[t] = count
            count += 1
    out_t = np.empty((count, 3), dtype=np.int32)
    out_n = np.empty((count, 3), dtype=np.int32)
    for t in range(m):
        s = new[t]
        if s < 0:
            continue
        for k in range(3):
            out_t[s, k] = tri[t, k]
            u = nbr[t, k]
            out_n[s, k] = new[u] if u >= 0 else -1
    return out_t, out_n


@njit(cache=True)
def _renumber_rows(pts, tri, nbr, con, vt, meta, free):  # type: ignore[no-untyped-def]
    """Reorder the rows along the Hilbert curve (by each triangle's first real vertex).

    Neighbouring triangles then sit close in memory, which roughly halves the time of a sweep
    such as :func:`flip_to_delaunay` on a large mesh.  Free rows go last, and ``meta[0]``
    shrinks to the live rows.
    """
    m = meta[0]
    hk = _hilbert_keys(pts)
    big = np.int64(1) << np.int64(40)
    key = np.empty(m, dtype=np.int64)
    for t in range(m):
        if tri[t, 0] == DEAD:
            key[t] = big + t
            continue
        v = tri[t, 0] if tri[t, 0] >= 0 else tri[t, 1]
        key[t] = hk[v]
    perm = np.argsort(key, kind="mergesort")
    inv = np.empty(m, dtype=np.int32)
    for s in range(m):
        inv[perm[s]] = s
    t_old = tri[:m].copy()
    n_old = nbr[:m].copy()
    c_old = con[:m].copy()
    live = 0
    for s in range(m):
        t = perm[s]
        for k in range(3):
            tri[s, k] = t_old[t, k]
            u = n_old[t, k]
            nbr[s, k] = inv[u] if u >= 0 else -1
            con[s, k] = c_old[t, k]
        if t_old[t, 0] != DEAD:
            live += 1
    for v in range(vt.shape[0]):
        if vt[v] >= 0:
            vt[v] = inv[vt[v]]
    meta[0] = live
    meta[1] = 0
    meta[2] = inv[meta[2]] if 0 <= meta[2] < m else 0
    _ = free
    return live


# ---------------------------------------------------------------------------------------------
# Operations on the live structure


@njit(cache=True)
def find_edge(tri, nbr, vt, i, j):  # type: ignore[no-untyped-def]
    """(t, k) with edge i-j opposite corner k of triangle t (i -> j counter-clockwise in t), or
    (-1, -1) when i-j is not an edge.  Walks around i from vt[i]."""
    t0 = vt[i]
    if t0 < 0:
        return -1, -1
    t = t0
    for _ in range(tri.shape[0] + 1):
        ki = _corner(tri, t, i)
        if ki < 0:
            return -1, -1
        if tri[t, (ki + 1) % 3] == j:
            return t, (ki + 2) % 3
        # Next triangle clockwise around i: across the edge (i, tri[t, ki+1]).
        t = nbr[t, (ki + 2) % 3]
        if t < 0 or t == t0:
            break
    # Compact arrays (no ghosts): the rotation may have stopped at the hull; go the other way.
    t = t0
    for _ in range(tri.shape[0] + 1):
        ki = _corner(tri, t, i)
        if tri[t, (ki + 1) % 3] == j:
            return t, (ki + 2) % 3
        t = nbr[t, (ki + 1) % 3]
        if t < 0 or t == t0:
            break
    return -1, -1


@njit(cache=True)
def flip_to_delaunay(points, tri, nbr, constrained, vt, log=None):  # type: ignore[no-untyped-def]
    """Lawson flips until every unconstrained edge is locally Delaunay.

    For use after the vertices moved a little.  Works on the live structure (with ghosts: a
    hull vertex that became reflex is filled in) and on compact arrays (``-1`` neighbours, the
    hull left as it is).  Returns the number of flips, or ``-(10 + t)`` when triangle row t is
    inverted or flat (no flip is made then: the caller should rebuild), or ERR_LOOP when the
    flip cap (50 per triangle) is reached.  ``log``: see :func:`_legalize` (and
    :func:`flips_logged`).
    """
    m = tri.shape[0]
    for t in range(m):
        if tri[t, 0] == DEAD or _is_ghost(tri, t):
            continue
        if _orient(points, tri[t, 0], tri[t, 1], tri[t, 2]) <= 0.0:
            return -(10 + t)
    # One sweep over the rows in memory order; a flip's four outer edges go on a small stack
    # that is emptied at once.  An edge swept earlier changes only through a flip, which
    # re-checks it, so every edge is locally Delaunay at the end.
    stack = np.empty(256, dtype=np.int32)
    cap = 50 * m + 1000
    flips = 0
    for t in range(m):
        if tri[t, 0] == DEAD:
            continue
        for k in range(3):
            if nbr[t, k] > t and _edge_illegal(points, tri, nbr, constrained, t, k):
                stack[0] = 3 * t + k
                stack, f = _legalize(points, tri, nbr, constrained, vt, stack, 1, cap - flips, log)
                if f < 0:
                    return ERR_LOOP
                flips += f
    return flips


@njit(cache=True)
def flip_rows_to_delaunay(points, tri, nbr, constrained, vt, rows, log=None):  # type: ignore[no-untyped-def]
    """:func:`flip_to_delaunay` started from the edges of ``rows`` only.

    For use after only some vertices moved, the rest of the mesh being Delaunay: every edge
    whose empty-circle test involves a moved vertex is an edge of a triangle incident to it, so
    ``rows`` must hold every triangle incident to a moved vertex.  Flips spread from there as
    far as they need to (each flip re-checks its four outer edges).  Same return codes.

    Once a row has been swept, every edge of the triangle it holds is locally Delaunay, and
    stays so: a later flip can only change the four outer edges of its quadrilateral, which it
    re-checks (its own new diagonal is Delaunay).  So an edge to a row swept earlier (the two
    triangles of a moved vertex share their edges), or a row listed twice, is not tested again:
    the test would find it Delaunay.  The flips made are the same, in the same order.
    """
    for a in range(rows.shape[0]):
        t = np.int64(rows[a])
        if tri[t, 0] == DEAD or _is_ghost(tri, t):
            continue
        if _orient(points, tri[t, 0], tri[t, 1], tri[t, 2]) <= 0.0:
            return -(10 + t)
    stack = np.empty(256, dtype=np.int32)
    cap = 50 * rows.shape[0] + 1000
    flips = 0
    swept = np.zeros(tri.shape[0], dtype=np.bool_)
    for a in range(rows.shape[0]):
        t = np.int64(rows[a])
        if tri[t, 0] == DEAD or swept[t]:
            continue
        swept[t] = True
        for k in range(3):
            u = nbr[t, k]
            if u >= 0 and not swept[u] and _edge_illegal(points, tri, nbr, constrained, t, k):
                stack[0] = 3 * t + k
                stack, f = _legalize(points, tri, nbr, constrained, vt, stack, 1, cap - flips, log)
                if f < 0:
                    return ERR_LOOP
                flips += f
    return flips


@njit(cache=True)
def flips_logged(points, tri, nbr, constrained, vt, rows, everywhere):  # type: ignore[no-untyped-def]
    """:func:`flip_rows_to_delaunay` (with ``everywhere``: :func:`flip_to_delaunay`, ``rows``
    unused), and what the flips did: ``(k, 6)`` int64 rows ``(t, u, b, c, a, d)``, one per flip
    in order (rows t and u changed, edge b-c gave way to a-d).  A caller that keeps lists
    derived from the triangles follows the flips from this, instead of comparing every row
    with a copy kept from before."""
    log = [(np.int64(0), np.int64(0), np.int64(0), np.int64(0), np.int64(0), np.int64(0))]
    log.pop()
    if everywhere:
        res = flip_to_delaunay(points, tri, nbr, constrained, vt, log)
    else:
        res = flip_rows_to_delaunay(points, tri, nbr, constrained, vt, rows, log)
    out = np.empty((len(log), 6), dtype=np.int64)
    for r in range(len(log)):
        for c in range(6):
            out[r, c] = log[r][c]
    return res, out


@njit(cache=True)
def flip_edge(points, tri, nbr, constrained, vt, i, j):  # type: ignore[no-untyped-def]
    """Flip edge i-j when its quadrilateral is strictly convex and the edge is unconstrained.

    Returns OK, ERR_NOT_FOUND, ERR_CONSTRAINED or ERR_NOT_CONVEX (hull edges and edges to the
    ghost vertex count as not convex).
    """
    t, k = find_edge(tri, nbr, vt, i, j)
    if t < 0:
        return ERR_NOT_FOUND
    if constrained[t, k] != 0:
        return ERR_CONSTRAINED
    u = nbr[t, k]
    if u < 0 or _is_ghost(tri, t) or _is_ghost(tri, u):
        return ERR_NOT_CONVEX
    a = tri[t, k]
    b = tri[t, (k + 1) % 3]
    c = tri[t, (k + 2) % 3]
    d = tri[u, _corner(nbr, u, t)]
    if _orient(points, a, b, d) <= 0.0 or _orient(points, a, d, c) <= 0.0:
        return ERR_NOT_CONVEX
    _flip(tri, nbr, constrained, vt, t, k)
    return OK


@njit(cache=True)
def locate(points, tri, nbr, meta, x, y):  # type: ignore[no-untyped-def]
    """Walk to the point (x, y); returns (t, kind, k) as :func:`_locate` (kind 3: outside)."""
    state = np.zeros(1, dtype=np.int64)
    t, kind, k = _locate(points, tri, nbr, meta, x, y, state)
    if t >= 0 and kind != 3:
        meta[2] = t
    return t, kind, k


@njit(cache=True)
def insert_point(points, tri, nbr, constrained, vt, meta, free, p):  # type: ignore[no-untyped-def]
    """Insert vertex p (coordinates points[p]) locally: locate, split, Lawson flips.

    The arrays must have room for two more triangles.  Returns -1 when inserted, v >= 0 when p
    duplicates vertex v (p is left out), ERR_NOT_FOUND when the point cannot be located.
    """
    stack = np.empty(64, dtype=np.int32)
    state = np.zeros(1, dtype=np.int64)
    res, stack = _insert(points, tri, nbr, constrained, vt, meta, free, p, stack, state)
    if res == -2:
        return ERR_NOT_FOUND
    if res >= 0:
        vt[p] = -1
    return res


@njit(cache=True)
def _star(tri, nbr, con, vt, v):  # type: ignore[no-untyped-def]
    """The triangles around v counter-clockwise: rows T, link vertices L (T[i] = (v, L[i],
    L[i+1])), the outer neighbours O and outer constraint flags OC; deg < 0 on error."""
    t0 = vt[v]
    deg = 0
    t = t0
    for _ in range(tri.shape[0] + 1):
        deg += 1
        kv = _corner(tri, t, v)
        t = nbr[t, (kv + 1) % 3]
        if t == t0:
            break
        if t < 0:
            return -1, np.empty(0, np.int32), np.empty(0, np.int32), np.empty(0, np.int32), np.empty(
                0, np.uint8
            )
    T = np.empty(deg, dtype=np.int32)
    L = np.empty(deg + 1, dtype=np.int32)
    O = np.empty(deg, dtype=np.int32)
    OC = np.empty(deg, dtype=np.uint8)
    t = t0
    spoke_constrained = False
    for i in range(deg):
        kv = _corner(tri, t, v)
        T[i] = t
        L[i] = tri[t, (kv + 1) % 3]
        O[i] = nbr[t, kv]
        OC[i] = con[t, kv]
        if con[t, (kv + 1) % 3] != 0:
            spoke_constrained = True
        t = nbr[t, (kv + 1) % 3]
    L[deg] = L[0]
    if spoke_constrained:
        return -2, T, L, O, OC
    return deg, T, L, O, OC


@njit(cache=True)
def _ear_ok(pts, poly, npoly, i):  # type: ignore[no-untyped-def]
    """Is (poly[i-1], poly[i], poly[i+1]) a strictly convex ear with no other polygon vertex
    strictly inside its circumcircle (a Delaunay ear)?"""
    x = poly[(i - 1) % npoly]
    y = poly[i]
    z = poly[(i + 1) % npoly]
    if _orient(pts, x, y, z) <= 0.0:
        return False
    for j in range(npoly):
        q = poly[j]
        if q == x or q == y or q == z:
            continue
        if (
            incircle(
                pts[x, 0], pts[x, 1], pts[y, 0], pts[y, 1], pts[z, 0], pts[z, 1], pts[q, 0], pts[q, 1]
            )
            > 0.0
        ):
            return False
    return True


@njit(cache=True)
def _ear_empty(pts, poly, npoly, i):  # type: ignore[no-untyped-def]
    """Strictly convex ear containing no other polygon vertex (inside or on its boundary)."""
    x = poly[(i - 1) % npoly]
    y = poly[i]
    z = poly[(i + 1) % npoly]
    if _orient(pts, x, y, z) <= 0.0:
        return False
    for j in range(npoly):
        q = poly[j]
        if q == x or q == y or q == z:
            continue
        if _orient(pts, x, y, q) >= 0.0 and _orient(pts, y, z, q) >= 0.0 and _orient(pts, z, x, q) >= 0.0:
            return False
    return True


@njit(cache=True)
def remove_vertex(points, tri, nbr, constrained, vt, meta, free, v):  # type: ignore[no-untyped-def]
    """Remove vertex v and re-triangulate its star by ear clipping with Delaunay ears.

    A hull vertex is removed too: the ears are clipped while the link chain has a convex one,
    and the chain left is the new hull.  Lawson flips over the new edges follow as a safety net.
    Returns OK, ERR_NOT_FOUND, ERR_CONSTRAINED (an edge at v is constrained), ERR_DEGENERATE
    (no triangle would be left) or ERR_LOOP.
    """
    if v < 0 or v >= vt.shape[0] or vt[v] < 0:
        return ERR_NOT_FOUND
    deg, T, L, O, OC = _star(tri, nbr, constrained, vt, v)
    if deg == -2:
        return ERR_CONSTRAINED
    if deg < 3:
        return ERR_LOOP
    # The new triangles, as vertex triples, in nt[:count].
    nt = np.empty((deg, 3), dtype=np.int32)
    count = 0
    g = -1
    for i in range(deg):
        if L[i] == GHOST:
            g = i
    if g < 0:
        poly = L[:deg].copy()
        npoly = deg
        while npoly > 3:
            ear = -1
            for i in range(npoly):
                if _ear_ok(points, poly, npoly, i):
                    ear = i
                    break
            if ear < 0:
                for i in range(npoly):
                    if _ear_empty(points, poly, npoly, i):
                        ear = i
                        break
            if ear < 0:
                return ERR_LOOP
            nt[count, 0] = poly[(ear - 1) % npoly]
            nt[count, 1] = poly[ear]
            nt[count, 2] = poly[(ear + 1) % npoly]
            count += 1
            for j in range(ear, npoly - 1):
                poly[j] = poly[j + 1]
            npoly -= 1
        nt[count, 0] = poly[0]
        nt[count, 1] = poly[1]
        nt[count, 2] = poly[2]
        count += 1
    else:
        # The chain L[g+1], ..., L[g-1] (cyclically) runs counter-clockwise around v between its
        # two hull neighbours.
        chain = np.empty(deg - 1, dtype=np.int32)
        for i in range(deg - 1):
            chain[i] = L[(g + 1 + i) % deg]
        nch = deg - 1
        while nch > 2:
            ear = -1
            for i in range(1, nch - 1):
                x = chain[i - 1]
                y = chain[i]
                z = chain[i + 1]
                if _orient(points, x, y, z) <= 0.0:
                    continue
                good = True
                for j in range(nch):
                    q = chain[j]
                    if q == x or q == y or q == z:
                        continue
                    if (
                        incircle(
                            points[x, 0], points[x, 1], points[y, 0], points[y, 1],
                            points[z, 0], points[z, 1], points[q, 0], points[q, 1],
                        )
                        > 0.0
                    ):
                        good = False
                        break
                if good:
                    ear = i
                    break
            if ear < 0:
                for i in range(1, nch - 1):
                    x = chain[i - 1]
                    y = chain[i]
                    z = chain[i + 1]
                    if _orient(points, x, y, z) <= 0.0:
                        continue
                    empty = True
                    for j in range(nch):
                        q = chain[j]
                        if q == x or q == y or q == z:
                            continue
                        if (
                            _orient(points, x, y, q) >= 0.0
                            and _orient(points, y, z, q) >= 0.0
                            and _orient(points, z, x, q) >= 0.0
                        ):
                            empty = False
                            break
                    if empty:
                        ear = i
                        break
            if ear < 0:
                break  # the chain left is convex seen from outside: it is the new hull
            nt[count, 0] = chain[ear - 1]
            nt[count, 1] = chain[ear]
            nt[count, 2] = chain[ear + 1]
            count += 1
            for j in range(ear, nch - 1):
                chain[j] = chain[j + 1]
            nch -= 1
        if count == 0:
            # No ear: the chain is the new hull.  If nothing real lies beyond it either, the
            # remaining points are collinear and no triangle would be left.
            beyond = False
            for i in range(deg):
                if L[i] >= 0 and L[i + 1] >= 0 and not _is_ghost(tri, O[i]):
                    beyond = True
            if not beyond:
                return ERR_DEGENERATE
        for i in range(nch - 1):
            # Hull edge chain[i+1] -> chain[i] (the mesh is on the far side of the chain from v).
            nt[count, 0] = chain[i]
            nt[count, 1] = chain[i + 1]
            nt[count, 2] = GHOST
            count += 1
    if count != deg - 2:
        return ERR_LOOP
    # Write the new triangles into the first deg - 2 rows of the star; free the last two.
    for s in range(count):
        t = T[s]
        for k in range(3):
            tri[t, k] = nt[s, k]
            nbr[t, k] = -1
            constrained[t, k] = 0
    _release(tri, nbr, constrained, meta, free, T[deg - 1])
    _release(tri, nbr, constrained, meta, free, T[deg - 2])
    # Link each new edge to its twin among the new triangles or to the outer edge it copies.
    for s in range(count):
        t = T[s]
        for k in range(3):
            x = tri[t, (k + 1) % 3]
            y = tri[t, (k + 2) % 3]
            found = False
            for s2 in range(count):
                if s2 == s:
                    continue
                t2 = T[s2]
                for k2 in range(3):
                    if tri[t2, (k2 + 1) % 3] == y and tri[t2, (k2 + 2) % 3] == x:
                        nbr[t, k] = t2
                        found = True
            if found:
                continue
            for i in range(deg):
                if L[i] == x and L[i + 1] == y:
                    o = O[i]
                    nbr[t, k] = o
                    constrained[t, k] = OC[i]
                    for ko in range(3):
                        if tri[o, (ko + 1) % 3] == y and tri[o, (ko + 2) % 3] == x:
                            nbr[o, ko] = t
                    found = True
            if not found:
                return ERR_LOOP
    vt[v] = -1
    stack = np.empty(3 * count + 16, dtype=np.int32)
    sp = 0
    for s in range(count):
        _set_vt(tri, vt, T[s])
        for k in range(3):
            stack[sp] = 3 * T[s] + k
            sp += 1
    stack, flips = _legalize(points, tri, nbr, constrained, vt, stack, sp, 50 * deg + 1000)
    if flips < 0:
        return ERR_LOOP
    meta[2] = T[0]
    return OK


@njit(cache=True)
def _crosses(pts, i, j, a, d):  # type: ignore[no-untyped-def]
    """Do the open segments i-j and a-d cross at a single interior point?"""
    o1 = _orient(pts, i, j, a)
    o2 = _orient(pts, i, j, d)
    if not ((o1 > 0.0 and o2 < 0.0) or (o1 < 0.0 and o2 > 0.0)):
        return False
    o3 = _orient(pts, a, d, i)
    o4 = _orient(pts, a, d, j)
    return (o3 > 0.0 and o4 < 0.0) or (o3 < 0.0 and o4 > 0.0)


@njit(cache=True)
def recover_edge(points, tri, nbr, constrained, vt, i, j):  # type: ignore[no-untyped-def]
    """Make segment i-j an edge by flips (Sloan 1993) and mark it constrained.

    Afterwards the edges created are made locally Delaunay again except across constrained
    edges (a constrained Delaunay triangulation).  Returns OK; ``-(10 + w)`` when vertex w lies
    on the open segment (recover i-w and w-j instead); ERR_CONSTRAINED when a constrained edge
    crosses it; ERR_NOT_FOUND when i or j is not in the mesh; ERR_LOOP when the segment leaves
    the triangulated region or a cap is reached.
    """
    if i == j or vt[i] < 0 or vt[j] < 0:
        return ERR_NOT_FOUND
    t, k = find_edge(tri, nbr, vt, i, j)
    if t < 0:
        # On compact arrays a hull edge has one triangle, which may hold it as j -> i.
        t, k = find_edge(tri, nbr, vt, j, i)
    if t >= 0:
        constrained[t, k] = 1
        u = nbr[t, k]
        if u >= 0:
            constrained[u, _corner(nbr, u, t)] = 1
        return OK
    # The triangle at i whose wedge holds j, then walk along the segment collecting the edges
    # it crosses, each as (left, right) of the directed line i -> j.  The rotation around i is
    # counter-clockwise, then clockwise from the start if it met the hull of compact arrays.
    t0 = vt[i]
    start = -1
    for direction in range(2):
        t = t0
        for _ in range(tri.shape[0] + 1):
            ki = _corner(tri, t, i)
            b = tri[t, (ki + 1) % 3]
            c = tri[t, (ki + 2) % 3]
            if b >= 0 and c >= 0:
                ob = _orient(points, i, b, j)
                oc = _orient(points, i, c, j)
                if ob >= 0.0 and oc <= 0.0:
                    if ob == 0.0:
                        return -(10 + b)
                    if oc == 0.0:
                        return -(10 + c)
                    start = t
                    break
            t = nbr[t, (ki + 1) % 3] if direction == 0 else nbr[t, (ki + 2) % 3]
            if t < 0 or t == t0:
                break
        if start >= 0 or t == t0:
            break
    if start < 0:
        return ERR_LOOP
    qx = np.empty(16, dtype=np.int32)
    qy = np.empty(16, dtype=np.int32)
    nq = 0
    cur = start
    ki = _corner(tri, cur, i)
    left = tri[cur, (ki + 2) % 3]
    right = tri[cur, (ki + 1) % 3]
    for _ in range(tri.shape[0] + 1):
        kc = 3 - _corner(tri, cur, left) - _corner(tri, cur, right)
        if constrained[cur, kc] != 0:
            return ERR_CONSTRAINED
        qy, _ = _push(qy, nq, right)
        qx, nq = _push(qx, nq, left)
        nxt = nbr[cur, kc]
        if nxt < 0 or _is_ghost(tri, nxt):
            return ERR_LOOP
        e = tri[nxt, _corner(nbr, nxt, cur)]
        cur = nxt
        if e == j:
            break
        oe = _orient(points, i, j, e)
        if oe == 0.0:
            return -(10 + e)
        if oe > 0.0:
            left = e
        else:
            right = e
    # Sloan: flip crossing edges whose quadrilateral is convex; a new edge that still crosses
    # goes back in the queue.  The queue is circular; it never holds more than nq edges.
    size = nq
    head = 0
    count = nq
    created = np.empty(16, dtype=np.int32)
    ncreated = 0
    cap = 10 * size * size + 1000
    it = 0
    while count > 0:
        it += 1
        if it > cap:
            return ERR_LOOP
        x = qx[head]
        y = qy[head]
        head = (head + 1) % size
        count -= 1
        t, k = find_edge(tri, nbr, vt, x, y)
        if t < 0:
            return ERR_LOOP
        u = nbr[t, k]
        a = tri[t, k]
        b = tri[t, (k + 1) % 3]
        c = tri[t, (k + 2) % 3]
        d = tri[u, _corner(nbr, u, t)]
        tail = (head + count) % size
        if _orient(points, a, b, d) > 0.0 and _orient(points, a, d, c) > 0.0:
            _flip(tri, nbr, constrained, vt, t, k)
            if _crosses(points, i, j, a, d):
                qx[tail] = a
                qy[tail] = d
                count += 1
            else:
                created, ncreated = _push(created, ncreated, a)
                created, ncreated = _push(created, ncreated, d)
        else:
            qx[tail] = x
            qy[tail] = y
            count += 1
    t, k = find_edge(tri, nbr, vt, i, j)
    if t < 0:
        return ERR_LOOP
    constrained[t, k] = 1
    u = nbr[t, k]
    constrained[u, _corner(nbr, u, t)] = 1
    stack = np.empty(ncreated + 16, dtype=np.int32)
    sp = 0
    for s in range(0, ncreated, 2):
        t, k = find_edge(tri, nbr, vt, created[s], created[s + 1])
        if t >= 0:
            stack, sp = _push(stack, sp, 3 * t + k)
    stack, flips = _legalize(points, tri, nbr, constrained, vt, stack, sp, 50 * tri.shape[0] + 1000)
    if flips < 0:
        return ERR_LOOP
    return OK


@njit(cache=True)
def recover_segments(points, tri, nbr, constrained, seg):  # type: ignore[no-untyped-def]
    """Recover every segment of ``seg (k, 2)`` as a constrained edge; one status per segment.

    Works on compact arrays (``-1`` beyond the hull) as well as on the live structure.  The
    segments that are already edges are marked constrained first, so recovering the others
    (whose final Lawson pass flips unconstrained edges only) cannot flip them away.  Statuses
    as :func:`recover_edge`; ERR_NOT_FOUND for an index outside the points.
    """
    n = points.shape[0]
    vt = np.full(n, -1, dtype=np.int32)
    for t in range(tri.shape[0]):
        if tri[t, 0] == DEAD:
            continue
        for k in range(3):
            if tri[t, k] >= 0:
                vt[tri[t, k]] = t
    ns = seg.shape[0]
    status = np.zeros(ns, dtype=np.int64)
    missing = np.zeros(ns, dtype=np.bool_)
    for s in range(ns):
        i = seg[s, 0]
        j = seg[s, 1]
        if i < 0 or j < 0 or i >= n or j >= n or i == j or vt[i] < 0 or vt[j] < 0:
            status[s] = ERR_NOT_FOUND
            continue
        t, k = find_edge(tri, nbr, vt, i, j)
        if t < 0:
            t, k = find_edge(tri, nbr, vt, j, i)
        if t < 0:
            missing[s] = True
            continue
        constrained[t, k] = 1
        u = nbr[t, k]
        if u >= 0:
            constrained[u, _corner(nbr, u, t)] = 1
    for s in range(ns):
        if missing[s]:
            status[s] = recover_edge(points, tri, nbr, constrained, vt, seg[s, 0], seg[s, 1])
    return status


# ---------------------------------------------------------------------------------------------
# Python interface


class DelaunayError(ValueError):
    """The points cannot be triangulated, or an operation on the triangulation is impossible."""


class InvertedTriangleError(DelaunayError):
    """A triangle became clockwise or flat after the points moved: rebuild the triangulation.

    ``triangle`` holds its three vertices.
    """

    def __init__(self, message: str, triangle: tuple[int, int, int]) -> None:
        super().__init__(message)
        self.triangle = triangle


class BlockedSegmentError(DelaunayError):
    """A vertex lies on the open segment to recover; ``vertex`` is its index."""

    def __init__(self, message: str, vertex: int) -> None:
        super().__init__(message)
        self.vertex = vertex


def _as_points(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise DelaunayError(f"points must be an (n, 2) array, got shape {p.shape}")
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        raise DelaunayError(f"point {int(np.flatnonzero(bad)[0])} is not finite: {p[bad][0].tolist()}")
    return np.ascontiguousarray(p)


def hilbert_order(points: FloatArray) -> NDArray[np.intp]:
    """Indices of ``points`` along a Hilbert curve over their bounding box (ties by index).

    Renumbering nodes in this order puts mesh neighbours near each other in memory.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=np.intp)
    keys = _hilbert_keys(np.ascontiguousarray(points, dtype=np.float64))
    return np.argsort(keys, kind="stable").astype(np.intp, copy=False)


def insertion_order(points: FloatArray) -> IntArray:
    """The order in which points are inserted: BRIO rounds, each along a Hilbert curve.

    Consecutive points are close, so each walk from the last triangle is a few steps long.
    """
    keys = _brio_keys(points)
    return np.argsort(keys, kind="stable").astype(np.int32)


class LiveTriangulation:
    """A Delaunay triangulation kept up to date under moves, flips, insertions and removals.

    Parameters
    ----------
    points : (n, 2) float64
        The vertices.  Exact duplicates are left out of the triangulation and reported in
        :attr:`duplicates`.

    Notes
    -----
    The arrays are the live structure of :mod:`injmesh.kernels.delaunay` (with ghost triangles
    and free rows); :attr:`triangles` and :attr:`neighbors` return the compact public form:
    real triangles only, counter-clockwise, ``-1`` for a neighbour beyond the hull.

    Examples
    --------
    >>> import numpy as np
    >>> live = LiveTriangulation(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]))
    >>> v = live.insert([0.5, 0.4])
    >>> len(live.triangles)
    4
    >>> live.remove(v)
    >>> len(live.triangles)
    2
    """

    def __init__(self, points: ArrayLike) -> None:
        p = _as_points(points)
        n = len(p)
        if n < 3:
            raise DelaunayError(f"cannot triangulate {n} points; at least 3 are needed")
        self._n = n
        self._pts = p.copy()
        cap = 2 * n + 8
        self._tri = np.full((cap, 3), DEAD, dtype=np.int32)
        self._nbr = np.full((cap, 3), -1, dtype=np.int32)
        self._con = np.zeros((cap, 3), dtype=np.uint8)
        self._vt = np.full(n, -1, dtype=np.int32)
        self._meta = np.zeros(4, dtype=np.int64)
        self._free = np.empty(cap, dtype=np.int32)
        self._dup = np.full(n, -1, dtype=np.int32)
        status = _build(self._pts, insertion_order(self._pts), self._tri, self._nbr, self._con,
                        self._vt, self._meta, self._free, self._dup)
        if status == ERR_COLLINEAR:
            raise DelaunayError(f"the {n} points are all collinear (or coincide): no triangle exists")
        if status != OK:
            raise DelaunayError(f"triangulation failed (status {status})")

    # -- views ---------------------------------------------------------------------------------

    @property
    def points(self) -> FloatArray:
        """The vertices ``(n, 2)`` (a copy)."""
        return self._pts[: self._n].copy()

    @property
    def n_points(self) -> int:
        return self._n

    @property
    def triangles(self) -> IntArray:
        """Real triangles ``(m, 3)`` int32, counter-clockwise."""
        return _compact(self._tri, self._nbr, int(self._meta[0]))[0]  # type: ignore[no-any-return]

    @property
    def neighbors(self) -> IntArray:
        """``(m, 3)`` int32: the triangle opposite each corner of :attr:`triangles`, -1 on the hull."""
        return _compact(self._tri, self._nbr, int(self._meta[0]))[1]  # type: ignore[no-any-return]

    def compact(self) -> tuple[IntArray, IntArray]:
        """:attr:`triangles` and :attr:`neighbors` from one pass over the structure."""
        return _compact(self._tri, self._nbr, int(self._meta[0]))  # type: ignore[no-any-return]

    @property
    def duplicates(self) -> IntArray:
        """``(n,)`` int32: for a point left out as an exact duplicate, the vertex it repeats; else -1."""
        return self._dup[: self._n].copy()

    @property
    def constrained_edges(self) -> IntArray:
        """Constrained edges ``(k, 2)`` with ``i < j``, sorted."""
        m = int(self._meta[0])
        tri, con = self._tri[:m], self._con[:m]
        t, k = np.nonzero(con)
        a = tri[t, (k + 1) % 3]
        b = tri[t, (k + 2) % 3]
        e = np.unique(np.sort(np.stack([a, b], axis=1), axis=1), axis=0)
        return e.astype(np.int32).reshape(-1, 2)

    def arrays(self) -> tuple[FloatArray, IntArray, IntArray, NDArray[np.uint8], IntArray]:
        """The live arrays ``(points, tri, nbr, constrained, vt)`` for other kernels (no copies)."""
        return self._pts[: self._n], self._tri, self._nbr, self._con, self._vt[: self._n]

    def renumber_rows(self) -> None:
        """Reorder the triangle rows along the Hilbert curve (a memory layout change only).

        Neighbouring triangles end up close in memory: worth it before many sweeps over a large
        triangulation (a flip pass after a move runs about twice as fast at 1e6 points).
        """
        _renumber_rows(self._pts[: self._n], self._tri, self._nbr, self._con, self._vt[: self._n],
                       self._meta, self._free)

    # -- operations ----------------------------------------------------------------------------

    def locate(self, point: ArrayLike) -> IntArray | None:
        """The vertices of a triangle containing ``point`` (closed), or None outside the hull."""
        x, y = (float(c) for c in np.asarray(point, dtype=np.float64).reshape(2))
        t, kind, _ = locate(self._pts, self._tri, self._nbr, self._meta, x, y)
        if t < 0 or kind == 3:
            return None
        return self._tri[t].copy()

    def _reserve(self) -> None:
        if self._n + 1 > len(self._pts):
            grow = max(16, len(self._pts))
            self._pts = np.concatenate([self._pts, np.zeros((grow, 2))])
            self._vt = np.concatenate([self._vt, np.full(grow, -1, np.int32)])
            self._dup = np.concatenate([self._dup, np.full(grow, -1, np.int32)])
        if self._meta[0] + 2 > len(self._tri):
            grow = max(16, len(self._tri))
            self._tri = np.concatenate([self._tri, np.full((grow, 3), DEAD, np.int32)])
            self._nbr = np.concatenate([self._nbr, np.full((grow, 3), -1, np.int32)])
            self._con = np.concatenate([self._con, np.zeros((grow, 3), np.uint8)])
            self._free = np.concatenate([self._free, np.empty(grow, np.int32)])

    def insert(self, point: ArrayLike) -> int:
        """Insert a point (locally: walk, split, Lawson flips); returns its vertex index.

        A point equal to an existing vertex is not inserted: the index of that vertex is
        returned and nothing changes.
        """
        p = _as_points(np.reshape(point, (1, 2)))[0]
        self._reserve()
        v = self._n
        self._pts[v] = p
        res = insert_point(self._pts, self._tri, self._nbr, self._con, self._vt, self._meta, self._free, v)
        if res >= 0:
            return int(res)
        if res != -1:
            raise DelaunayError(f"point {p.tolist()} could not be located (status {res})")
        self._n += 1
        return v

    def remove(self, v: int) -> None:
        """Remove vertex ``v`` (its index stays reserved); its star is re-triangulated."""
        if not 0 <= v < self._n:
            raise DelaunayError(f"vertex {v} does not exist (there are {self._n})")
        res = remove_vertex(self._pts, self._tri, self._nbr, self._con, self._vt, self._meta, self._free, v)
        messages = {
            ERR_NOT_FOUND: f"vertex {v} is not in the triangulation",
            ERR_CONSTRAINED: f"vertex {v} has a constrained edge",
            ERR_DEGENERATE: f"removing vertex {v} would leave no triangle",
        }
        if res != OK:
            raise DelaunayError(messages.get(res, f"removing vertex {v} failed (status {res})"))

    def move(self, points: ArrayLike) -> None:
        """Replace the coordinates of all vertices (same count); call :meth:`flip_to_delaunay`."""
        p = _as_points(points)
        if len(p) != self._n:
            raise DelaunayError(f"move needs {self._n} points, got {len(p)}")
        self._pts[: self._n] = p

    def flip_to_delaunay(self) -> int:
        """Lawson flips after a move, never across constrained edges; returns the flip count.

        Raises
        ------
        InvertedTriangleError
            A triangle is clockwise or flat: no flip was made; rebuild instead.
        """
        res = flip_to_delaunay(self._pts, self._tri, self._nbr, self._con, self._vt)
        if res == ERR_LOOP:
            raise DelaunayError("flip cap reached: the triangulation is not valid")
        if res < 0:
            t = -res - 10
            tri = tuple(int(v) for v in self._tri[t])
            raise InvertedTriangleError(f"triangle {tri} is inverted or flat", tri)  # type: ignore[arg-type]
        return int(res)

    def flip(self, i: int, j: int) -> bool:
        """Flip edge i-j if it exists, is unconstrained and its quadrilateral is strictly convex."""
        return bool(flip_edge(self._pts, self._tri, self._nbr, self._con, self._vt, i, j) == OK)

    def recover_edge(self, i: int, j: int) -> None:
        """Make segment i-j an edge by flips and mark it constrained.

        Raises
        ------
        BlockedSegmentError
            A vertex lies on the open segment (recover the two parts instead).
        """
        res = recover_edge(self._pts, self._tri, self._nbr, self._con, self._vt, i, j)
        if res <= -10:
            w = -res - 10
            raise BlockedSegmentError(f"vertex {w} lies on segment {i}-{j}", w)
        messages = {
            ERR_NOT_FOUND: f"vertex {i} or {j} is not in the triangulation",
            ERR_CONSTRAINED: f"a constrained edge crosses segment {i}-{j}",
        }
        if res != OK:
            raise DelaunayError(messages.get(res, f"recovering segment {i}-{j} failed (status {res})"))


def delaunay(points: ArrayLike) -> NDArray[np.intp]:
    """Delaunay triangles of ``points`` ``(n, 2)``: ``(m, 3)`` counter-clockwise indices.

    The triangulation of the convex hull; exact duplicates are left out (their indices appear in
    no triangle).  Ties between cocircular points are broken deterministically.

    Raises
    ------
    DelaunayError
        Fewer than three points, a non-finite coordinate, or all points collinear.

    Examples
    --------
    >>> import numpy as np
    >>> delaunay(np.array([[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [1.0, 3.0]])).tolist()
    [[0, 2, 3], [3, 2, 1], [1, 2, 0]]
    """
    return LiveTriangulation(points).triangles.astype(np.intp)


__all__ = [
    "BlockedSegmentError",
    "DelaunayError",
    "InvertedTriangleError",
    "LiveTriangulation",
    "delaunay",
    "find_edge",
    "flip_edge",
    "flip_to_delaunay",
    "insert_point",
    "locate",
    "recover_edge",
    "recover_segments",
    "remove_vertex",
]
