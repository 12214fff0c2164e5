"""The repair rounds' bookkeeping (``smoothing._repair_rounds``) as numba kernels.

A repair round on one of the paper's small cases works on a sub-mesh of a few hundred
triangles: its NumPy lines (the bad triangles and their edges' midpoints, the choice of edits,
the collapse and split renumbering, the neighbour table before the flips, quality, chords and
each part's minimum, a patch's extraction) were hundreds of calls of 1-5 us each per round, more
than the work.  Each kernel here does one of those steps in one call, with the numbers of the
NumPy lines it replaced (the same operations on the same doubles, the same orders and ties).

Arrays are int64 and float64 (each kernel is compiled for one signature); masks are
``np.bool_``.

Examples
--------
>>> import numpy as np
>>> from injmesh.kernels.repair import components
>>> components(np.array([[0, 1, 2], [3, 4, 5]]), 7)[0].tolist()
[0, 0, 0, 1, 1, 1, 2]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .delaunay import flip_rows_to_delaunay, flip_to_delaunay
from .mesh import by_least_vertex, neighbours, rows_with, triangle_quality
from .smooth import adjacency, rings


@njit(cache=True)
def _root(parent, v):  # type: ignore[no-untyped-def]
    while parent[v] != v:
        parent[v] = parent[parent[v]]
        v = parent[v]
    return v


@njit(cache=True)
def components(tri, n):  # type: ignore[no-untyped-def]
    """The connected parts of the graph of the triangles' edges over ``n`` nodes: each node's
    part, numbered in the order of the parts' least nodes (a node in no triangle is a part of
    its own), and the number of parts.  Returns ``(label (n,) int64, parts)``."""
    parent = np.arange(n)
    for t in range(tri.shape[0]):
        a = _root(parent, tri[t, 0])
        for k in range(1, 3):
            b = _root(parent, tri[t, k])
            if a != b:
                if b < a:
                    a, b = b, a
                parent[b] = a
    label = np.empty(n, dtype=np.int64)
    parts = 0
    for v in range(n):
        r = _root(parent, v)
        if r == v:
            label[v] = parts
            parts += 1
        else:
            label[v] = label[r]
    return label, parts


@njit(cache=True)
def chords(p, tri, n_boundary, seg_keys, key):  # type: ignore[no-untyped-def]
    """For each triangle of three boundary nodes (``< n_boundary``): the local index k of its
    edge ``(t[k], t[k+1])`` to split, or -1 (``smoothing._chords``: its longest edge, by
    ``hypot`` with the first of equal lengths, when that is not among the sorted edge keys
    ``seg_keys`` (``min * key + max``) and the triangle across it has a free node)."""
    m = tri.shape[0]
    out = np.full(m, -1, dtype=np.int64)
    cand = np.empty(m, dtype=np.int64)
    kk = np.empty(m, dtype=np.int64)
    c = 0
    for t in range(m):
        if max(tri[t, 0], tri[t, 1], tri[t, 2]) >= n_boundary:
            continue
        best = -1.0
        k = 0
        for j in range(3):
            a, b = tri[t, j], tri[t, (j + 1) % 3]
            d = math.hypot(p[a, 0] - p[b, 0], p[a, 1] - p[b, 1])
            if d > best or j == 0:
                best = d
                k = j
        a, b = tri[t, k], tri[t, (k + 1) % 3]
        e = min(a, b) * key + max(a, b)
        at = np.searchsorted(seg_keys, e)
        if at < seg_keys.shape[0] and seg_keys[at] == e:
            continue
        cand[c] = t
        kk[c] = k
        c += 1
    if c == 0:
        return out
    # The triangle across edge k (opposite corner k + 2) is split with it: it must have a free
    # node (see smoothing._chords).
    nbr = neighbours(tri, p.shape[0])
    for r in range(c):
        t, k = cand[r], kk[r]
        u = nbr[t, (k + 2) % 3]
        if u >= 0 and max(tri[u, 0], tri[u, 1], tri[u, 2]) < n_boundary:
            continue
        out[t] = k
    return out


@njit(cache=True)
def frozen_key(a, b, c, n_fixed):  # type: ignore[no-untyped-def]
    """One int64 for the triangle of fixed nodes ``a, b, c`` (``< n_fixed``) in any order:
    fixed nodes keep their numbers through the rounds, so it names the same triangle in
    every round."""
    lo = min(a, b, c)
    hi = max(a, b, c)
    mid = a + b + c - lo - hi
    return (lo * n_fixed + mid) * n_fixed + hi


@njit(cache=True)
def frozen_key_rows(tri, n_fixed):  # type: ignore[no-untyped-def]
    """:func:`frozen_key` of each row of ``tri (m, 3)``."""
    out = np.empty(tri.shape[0], dtype=np.int64)
    for t in range(tri.shape[0]):
        out[t] = frozen_key(tri[t, 0], tri[t, 1], tri[t, 2], n_fixed)
    return out


@njit(cache=True)
def _listed(keys, k):  # type: ignore[no-untyped-def]
    at = np.searchsorted(keys, k)
    return at < keys.shape[0] and keys[at] == k


@njit(cache=True)
def round_state(p, tri, n_boundary, n_fixed, seg_keys, key, label, parts, pinned, repair_q,  # type: ignore[no-untyped-def]
                excused):
    """What the repair rounds need of a round's mesh: each triangle's quality q (Eq. 5.1),
    chord (:func:`chords`), whether a round can change it (a free node or a chord), each
    part's least q over all its triangles and over those a round can change (``inf`` where
    none), and the triangles a round repairs: q below ``repair_q``, changeable, in a part not
    ``pinned``, worst first (ties in row order).

    ``excused``: sorted keys (:func:`frozen_key`) of triangles of three fixed nodes left out of
    the parts' least q (a sharp tip's triangle, which no round can change, would otherwise
    be every round's score and hide what the rounds do to the rest of its part).

    Returns ``(q, chord, changeable, score, score_changeable, bad)``."""
    m = tri.shape[0]
    q = triangle_quality(p, tri)
    chord = chords(p, tri, n_boundary, seg_keys, key)
    changeable = np.empty(m, dtype=np.bool_)
    score = np.full(parts, np.inf)
    score_c = np.full(parts, np.inf)
    nb = 0
    for t in range(m):
        changeable[t] = max(tri[t, 0], tri[t, 1], tri[t, 2]) >= n_fixed or chord[t] >= 0
        part = label[tri[t, 0]]
        if changeable[t] or not _listed(excused, frozen_key(tri[t, 0], tri[t, 1], tri[t, 2], n_fixed)):
            score[part] = min(score[part], q[t])
        if changeable[t]:
            score_c[part] = min(score_c[part], q[t])
            if q[t] < repair_q and not pinned[part]:
                nb += 1
    bad = np.empty(nb, dtype=np.int64)
    b = 0
    for t in range(m):
        if changeable[t] and q[t] < repair_q and not pinned[label[tri[t, 0]]]:
            bad[b] = t
            b += 1
    qb = np.empty(nb)
    for r in range(nb):
        qb[r] = q[bad[r]]
    bad = bad[np.argsort(qb, kind="mergesort")]
    return q, chord, changeable, score, score_c, bad


@njit(cache=True)
def edge_midpoints(p, tri, bad):  # type: ignore[no-untyped-def]
    """The midpoints of the edges ``(t[k], t[k+1])`` of the triangles ``bad``, ``(3 len, 2)``
    row by row: where h gives their desired lengths."""
    mid = np.empty((3 * bad.shape[0], 2))
    for r in range(bad.shape[0]):
        for k in range(3):
            a, b = tri[bad[r], k], tri[bad[r], (k + 1) % 3]
            mid[3 * r + k, 0] = 0.5 * (p[a, 0] + p[b, 0])
            mid[3 * r + k, 1] = 0.5 * (p[a, 1] + p[b, 1])
    return mid


@njit(cache=True)
def _sees_star(p, tri, keep, drop):  # type: ignore[no-untyped-def]
    """Whether ``drop``'s triangles without ``keep`` stay counter-clockwise with ``keep`` in
    its place (a collapse of drop into a fixed node keep inverts none of them)."""
    for t in range(tri.shape[0]):
        at = -1
        for k in range(3):
            if tri[t, k] == keep:
                at = -2
                break
            if tri[t, k] == drop:
                at = k
        if at < 0:
            continue
        u, v = tri[t, (at + 1) % 3], tri[t, (at + 2) % 3]
        cross = ((p[u, 0] - p[keep, 0]) * (p[v, 1] - p[keep, 1])
                 - (p[u, 1] - p[keep, 1]) * (p[v, 0] - p[keep, 0]))
        if not cross > 0.0:
            return False
    return True


@njit(cache=True)
def choose_edits(p, tri, bad, chord, h_mid, n_fixed):  # type: ignore[no-untyped-def]
    """``smoothing._choose_repairs`` after h: the edge operations for the triangles ``bad``
    (worst first) whose edges' desired lengths are ``h_mid`` (:func:`edge_midpoints`).

    In each triangle the edge furthest from h (length over h: the shortest if it is further
    below 1 than the longest is above, the first of equal ratios) is collapsed or split, its
    chord split if it has one; a collapse keeps a fixed node and drops the free one.  An edge
    between two fixed nodes is never split but for a chord: when it is the one to split, the
    triangle's third node, if free and inside the edge's diametral circle, is collapsed into
    the nearer of the two instead, where that keeps its star counter-clockwise.  An operation
    is dropped unless it is the first, in this order, to use each of its two nodes (so an
    edge chosen by both its triangles is taken once).

    Returns ``(collapse (c, 2), split (s, 2))`` int64, collapse rows ``(keep, drop)``."""
    nb = bad.shape[0]
    n = p.shape[0]
    ea = np.empty(nb, dtype=np.int64)
    eb = np.empty(nb, dtype=np.int64)
    col = np.empty(nb, dtype=np.bool_)
    ratio = np.empty(3)
    c = 0
    for r in range(nb):
        t = bad[r]
        for k in range(3):
            a, b = tri[t, k], tri[t, (k + 1) % 3]
            ratio[k] = math.hypot(p[a, 0] - p[b, 0], p[a, 1] - p[b, 1]) / h_mid[3 * r + k]
        short = 0
        long_ = 0
        for k in range(1, 3):
            if ratio[k] < ratio[short]:
                short = k
            if ratio[k] > ratio[long_]:
                long_ = k
        capped = chord[t] >= 0
        do_collapse = (1.0 - ratio[short]) > (ratio[long_] - 1.0) and not capped
        k = chord[t] if capped else (short if do_collapse else long_)
        a, b = tri[t, k], tri[t, (k + 1) % 3]
        if do_collapse and b < n_fixed:
            a, b = b, a
        if b >= n_fixed or (not do_collapse and a >= n_fixed) or capped:
            ea[c], eb[c], col[c] = a, b, do_collapse
            c += 1
        elif not do_collapse:
            # Too long, between two fixed nodes (a wall segment, a strip's rung): the free node
            # opposite it is squeezed against it, the triangle obtuse there (a strip narrowing
            # from two layers to one, a wall segment at a corner).  Nothing can split the
            # edge, so that node goes, into the nearer end.
            w = tri[t, (k + 2) % 3]
            squeezed = ((p[a, 0] - p[w, 0]) * (p[b, 0] - p[w, 0])
                        + (p[a, 1] - p[w, 1]) * (p[b, 1] - p[w, 1])) < 0.0
            if w >= n_fixed and squeezed:
                da = math.hypot(p[a, 0] - p[w, 0], p[a, 1] - p[w, 1])
                db = math.hypot(p[b, 0] - p[w, 0], p[b, 1] - p[w, 1])
                keep = a if da <= db else b
                # Only where the fixed node sees the whole star of w: an inverted triangle
                # would end the rounds (``smoothing._repair_rounds``).
                if _sees_star(p, tri, keep, w):
                    ea[c], eb[c], col[c] = keep, w, True
                    c += 1
    first = np.full(n, c, dtype=np.int64)
    for i in range(c - 1, -1, -1):
        first[ea[i]] = i
        first[eb[i]] = i
    # The same edge chosen twice (by its two triangles) is taken once, the first time: the
    # node test already drops the later one, whose nodes the first one used.
    n_col = 0
    n_split = 0
    ok = np.empty(c, dtype=np.bool_)
    for i in range(c):
        ok[i] = first[ea[i]] == i and first[eb[i]] == i
        if ok[i]:
            if col[i]:
                n_col += 1
            else:
                n_split += 1
    collapse = np.empty((n_col, 2), dtype=np.int64)
    split = np.empty((n_split, 2), dtype=np.int64)
    n_col = 0
    n_split = 0
    for i in range(c):
        if not ok[i]:
            continue
        if col[i]:
            collapse[n_col, 0], collapse[n_col, 1] = ea[i], eb[i]
            n_col += 1
        else:
            split[n_split, 0], split[n_split, 1] = ea[i], eb[i]
            n_split += 1
    return collapse, split


@njit(cache=True)
def apply_edits(p, tri, kept, label, collapse, split, n_fixed):  # type: ignore[no-untyped-def]
    """A round's edge operations on the arrays (they share no node).

    Collapse ``(keep, drop)``: drop disappears, keep moves to the midpoint unless it is fixed,
    drop's triangles are keep's and those that had both go.  Split ``a-b``: a new node at the
    midpoint (after the collapses' moves), numbered after the surviving nodes in the order of
    ``split``; each triangle ``(a, b, w)`` on the edge becomes ``(a, m, w)`` in its row and
    ``(m, b, w)`` appended, in row order.  The surviving nodes keep their order.  The result
    may have inverted triangles.

    Returns ``(p, tri, kept, label, touched)``: the new points, triangles, ``kept`` (-1 for a
    new node), ``label`` (a new node joins its edge's part) and the nodes the operations
    touched in the new numbering (keepers, split ends, new nodes)."""
    n = p.shape[0]
    nc = collapse.shape[0]
    ns = split.shape[0]
    q = p.copy()
    alive = np.ones(n, dtype=np.bool_)
    for r in range(nc):
        a, b = collapse[r, 0], collapse[r, 1]
        if a >= n_fixed:
            q[a, 0] = 0.5 * (p[a, 0] + p[b, 0])
            q[a, 1] = 0.5 * (p[a, 1] + p[b, 1])
        alive[b] = False
    index = np.empty(n + ns, dtype=np.int64)
    w = 0
    for v in range(n):
        index[v] = w - 1 if not alive[v] else w
        if alive[v]:
            w += 1
    n_alive = w
    for s in range(ns):
        index[n + s] = n_alive + s
    out_p = np.empty((n_alive + ns, 2))
    out_kept = np.empty(n_alive + ns, dtype=np.int64)
    out_label = np.empty(n_alive + ns, dtype=np.int64)
    for v in range(n):
        if alive[v]:
            i = index[v]
            out_p[i, 0], out_p[i, 1] = q[v, 0], q[v, 1]
            out_kept[i] = kept[v]
            out_label[i] = label[v]
    for s in range(ns):
        a, b = split[s, 0], split[s, 1]
        out_p[n_alive + s, 0] = 0.5 * (q[a, 0] + q[b, 0])
        out_p[n_alive + s, 1] = 0.5 * (q[a, 1] + q[b, 1])
        out_kept[n_alive + s] = -1
        out_label[n_alive + s] = label[a]
    # Split edges by node (each node in one operation at most).
    op = np.full(n, -1, dtype=np.int64)
    for s in range(ns):
        op[split[s, 0]] = s
        op[split[s, 1]] = s
    m = tri.shape[0]
    t = np.empty((m + 2 * ns, 3), dtype=np.int64)
    for r in range(m):
        t[r, 0], t[r, 1], t[r, 2] = tri[r, 0], tri[r, 1], tri[r, 2]
    rows = m
    if ns:
        for r in range(m):
            for k in range(3):
                u, v = tri[r, k], tri[r, (k + 1) % 3]
                s = op[u]
                if s >= 0 and op[v] == s:
                    mid = n + s
                    w3 = tri[r, (k + 2) % 3]
                    t[r, 0], t[r, 1], t[r, 2] = u, mid, w3
                    t[rows, 0], t[rows, 1], t[rows, 2] = mid, v, w3
                    rows += 1
    rename = np.arange(n + ns)
    for r in range(nc):
        rename[collapse[r, 1]] = collapse[r, 0]
    out_tri = np.empty((rows, 3), dtype=np.int64)
    c = 0
    for r in range(rows):
        a, b, d = rename[t[r, 0]], rename[t[r, 1]], rename[t[r, 2]]
        if a != b and b != d and d != a:
            out_tri[c, 0], out_tri[c, 1], out_tri[c, 2] = index[a], index[b], index[d]
            c += 1
    touched = np.empty(nc + 3 * ns, dtype=np.int64)
    for r in range(nc):
        touched[r] = index[collapse[r, 0]]
    for s in range(ns):
        touched[nc + 2 * s] = index[split[s, 0]]
        touched[nc + 2 * s + 1] = index[split[s, 1]]
    for s in range(ns):
        touched[nc + 2 * ns + s] = n_alive + s
    return out_p, out_tri[:c].copy(), out_kept, out_label, touched


@njit(cache=True)
def flip_near(p, tri, near, everywhere):  # type: ignore[no-untyped-def]
    """Lawson flips (exact predicates, edges with one triangle kept) on a copy of ``tri``,
    started from the triangles of the nodes ``near``, in row order (from every triangle with
    ``everywhere``): the neighbour table and the vertex-to-triangle map are made here.  Returns
    ``(res, tri)`` as :func:`~injmesh.kernels.delaunay.flip_rows_to_delaunay` (negative: an
    inverted or flat triangle, or no triangles at all), ``tri`` as int32."""
    n = p.shape[0]
    m = tri.shape[0]
    t32 = np.empty((m, 3), dtype=np.int32)
    for r in range(m):
        for k in range(3):
            t32[r, k] = tri[r, k]
    if m == 0:
        return -1, t32
    nbr = neighbours(t32, n).astype(np.int32)
    vt = np.full(n, -1, dtype=np.int32)
    for r in range(m):
        for k in range(3):
            vt[t32[r, k]] = r
    con = np.zeros((m, 3), dtype=np.uint8)
    if everywhere:
        return flip_to_delaunay(p, t32, nbr, con, vt), t32
    mark = np.zeros(n, dtype=np.bool_)
    for v in near:
        mark[v] = True
    return flip_rows_to_delaunay(p, t32, nbr, con, vt, rows_with(t32, mark).astype(np.int32)), t32


@njit(cache=True)
def patch_of(tri, n, indptr, adj, touched, ring, slide, walls, n_fixed):  # type: ignore[no-untyped-def]
    """A repair patch (``smoothing._patch_local``) cut from the triangles ``tri`` over ``n``
    nodes: the nodes within ``ring`` edges of ``touched`` move, every triangle with a node
    within ``ring + 1`` is in the patch.  ``indptr, adj``: the node lists of ``tri``
    (:func:`~injmesh.kernels.smooth.adjacency`, free slots allowed), made here when empty.

    Returns ``(rows, nodes, t32, nbr, active, slide, walls, n_fixed)``: the rows of ``tri`` in
    the patch (increasing), its nodes (sorted), its triangles in its numbering ordered by their
    least node (ties in row order) as int32 with their neighbour table, which of its nodes
    move, the sliding rows ``slide (k, 3)`` of moving nodes and the segments ``walls`` whose
    nodes are all in it (renumbered), and how many of its nodes come before ``n_fixed``."""
    if indptr.shape[0] == 0:
        # int32 triangles and no free slots, given as the empty indptr's length, not as a
        # literal 0: the specialisation the relaxations compile (a literal argument makes
        # numba compile a callee once more for that constant).
        indptr, adj, _, _ = adjacency(n, tri.astype(np.int32), indptr.shape[0])
    active = rings(indptr, adj, touched, ring)
    near = rings(indptr, adj, touched, ring + 1)
    m = tri.shape[0]
    rows = np.empty(m, dtype=np.int64)
    inv = np.full(n, -1, dtype=np.int64)
    c = 0
    for r in range(m):
        if near[tri[r, 0]] or near[tri[r, 1]] or near[tri[r, 2]]:
            rows[c] = r
            c += 1
            for k in range(3):
                inv[tri[r, k]] = 0
    rows = rows[:c].copy()
    nn = 0
    local_fixed = 0
    for v in range(n):
        if inv[v] == 0:
            inv[v] = nn
            nn += 1
            if v < n_fixed:
                local_fixed += 1
    nodes = np.empty(nn, dtype=np.int64)
    moving = np.empty(nn, dtype=np.bool_)
    for v in range(n):
        if inv[v] >= 0:
            nodes[inv[v]] = v
            moving[inv[v]] = active[v]
    local = np.empty((c, 3), dtype=np.int64)
    for a in range(c):
        for k in range(3):
            local[a, k] = inv[tri[rows[a], k]]
    t32, nbr, sl = _local_mesh(local, nodes.shape[0], slide, active, inv)
    return rows, nodes, t32, nbr, moving, sl, _pairs_inside(walls, inv), local_fixed


@njit(cache=True)
def _local_mesh(local, n, slide, movable, inv):  # type: ignore[no-untyped-def]
    """A sub-mesh's triangles ``local`` (renumbered) listed by their least node as int32, their
    neighbour table, and the rows of ``slide`` whose node is ``movable`` and whose three nodes
    have a number in ``inv``, renumbered: what :func:`patch_of` and :func:`sub_mesh_of` give
    a relaxation."""
    c = local.shape[0]
    order = by_least_vertex(local, n)
    t32 = np.empty((c, 3), dtype=np.int32)
    for a in range(c):
        for k in range(3):
            t32[a, k] = local[order[a], k]
    nbr = neighbours(t32, n).astype(np.int32)
    ks = 0
    sl = np.empty(slide.shape, dtype=np.int64)
    for r in range(slide.shape[0]):
        if not movable[slide[r, 0]]:
            continue
        i0, i1, i2 = inv[slide[r, 0]], inv[slide[r, 1]], inv[slide[r, 2]]
        if i0 >= 0 and i1 >= 0 and i2 >= 0:
            sl[ks, 0], sl[ks, 1], sl[ks, 2] = i0, i1, i2
            ks += 1
    return t32, nbr, sl[:ks].copy()


@njit(cache=True)
def canonical(tri):  # type: ignore[no-untyped-def]
    """The triangles ``tri`` as a set: each row sorted, then the rows in lexicographic order,
    ``(m, 3)`` int64.  Two rounds have the same triangles when these are equal.  The rows are
    counted out by their first node, then put in order by the other two within each node's
    few (no general sort: it would compile for seconds)."""
    m = tri.shape[0]
    s = np.empty((m, 3), dtype=np.int64)
    n = 0
    for r in range(m):
        a, b, c = tri[r, 0], tri[r, 1], tri[r, 2]
        if a > b:
            a, b = b, a
        if b > c:
            b, c = c, b
        if a > b:
            a, b = b, a
        s[r, 0], s[r, 1], s[r, 2] = a, b, c
        n = max(n, c + 1)
    start = np.zeros(n + 1, dtype=np.int64)
    for r in range(m):
        start[s[r, 0] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    out = np.empty((m, 3), dtype=np.int64)
    fill = start[:n].copy()
    for r in range(m):
        at = fill[s[r, 0]]
        fill[s[r, 0]] += 1
        # Insertion within the first node's rows, by the second then the third node.
        while at > start[s[r, 0]] and (out[at - 1, 1] > s[r, 1] or (out[at - 1, 1] == s[r, 1]
                                                                    and out[at - 1, 2] > s[r, 2])):
            out[at, 0], out[at, 1], out[at, 2] = out[at - 1, 0], out[at - 1, 1], out[at - 1, 2]
            at -= 1
        out[at, 0], out[at, 1], out[at, 2] = s[r, 0], s[r, 1], s[r, 2]
    return out


@njit(cache=True)
def patch_merge(p, tri, rows, nodes, patch_p, patch_tri):  # type: ignore[no-untyped-def]
    """A relaxed patch written back (``smoothing._patch``): the points with the patch's
    ``nodes`` at ``patch_p``, and the triangles outside the patch's ``rows`` (in order) then the
    patch's ``patch_tri`` in the mesh's numbering.  Returns ``(p, tri)``."""
    out = p.copy()
    for a in range(nodes.shape[0]):
        out[nodes[a], 0], out[nodes[a], 1] = patch_p[a, 0], patch_p[a, 1]
    m = tri.shape[0]
    inside = np.zeros(m, dtype=np.bool_)
    for a in range(rows.shape[0]):
        inside[rows[a]] = True
    t = np.empty((m - rows.shape[0] + patch_tri.shape[0], 3), dtype=np.int64)
    c = 0
    for r in range(m):
        if not inside[r]:
            t[c, 0], t[c, 1], t[c, 2] = tri[r, 0], tri[r, 1], tri[r, 2]
            c += 1
    for r in range(patch_tri.shape[0]):
        for k in range(3):
            t[c, k] = nodes[patch_tri[r, k]]
        c += 1
    return out, t


@njit(cache=True)
def sub_mesh_of(p, tri, indptr, adj, repair_q, reach, band, n_fixed, slide, walls, curves):  # type: ignore[no-untyped-def]
    """The repair's sub-mesh (``smoothing._repair``) around the triangles of quality below
    ``repair_q`` (Eq. 5.1): its free nodes within ``reach`` edges of their nodes may move, the
    ones within ``reach + band`` stay, and it holds the triangles whose three nodes are within
    ``reach + band``.  ``indptr, adj``: the node lists of ``tri`` (free slots allowed).

    Its nodes are numbered: the mesh's fixed nodes (``< n_fixed``), the band's, then the
    movable free nodes, each group in increasing order.  Returns ``(nodes, n_boundary,
    n_fixed, inner, t32, nbr, slide, walls, curves, outer_q)``: the nodes (empty when no
    triangle is bad), how many are the mesh's fixed nodes and how many are fixed here, which
    rows of ``tri`` it holds, its triangles in its numbering ordered by their least node (ties
    in row order) as int32 and their neighbour table, the sliding rows of movable nodes and
    the segments and ``curves`` whose nodes it holds (renumbered), and the least quality of
    the triangles outside it (``inf`` when none)."""
    n = p.shape[0]
    m = tri.shape[0]
    q = triangle_quality(p, tri)
    mark = np.zeros(n, dtype=np.bool_)
    for t in range(m):
        if q[t] < repair_q:
            for k in range(3):
                mark[tri[t, k]] = True
    seeds = np.flatnonzero(mark).astype(np.int64)
    n_seeds = seeds.shape[0]
    inner = np.zeros(m, dtype=np.bool_)
    if n_seeds == 0:
        empty2 = np.zeros((0, 2), dtype=np.int64)
        return (np.zeros(0, dtype=np.int64), 0, 0, inner, np.zeros((0, 3), dtype=np.int32),
                np.zeros((0, 3), dtype=np.int32), np.zeros((0, 3), dtype=np.int64), empty2, empty2,
                np.inf)
    movable = rings(indptr, adj, seeds, reach)
    span = rings(indptr, adj, seeds, reach + band)
    used = np.zeros(n, dtype=np.bool_)
    outer_q = np.inf
    c = 0
    for t in range(m):
        if span[tri[t, 0]] and span[tri[t, 1]] and span[tri[t, 2]]:
            inner[t] = True
            c += 1
            for k in range(3):
                used[tri[t, k]] = True
        else:
            outer_q = min(outer_q, q[t])
    inv = np.full(n, -1, dtype=np.int64)
    nn = 0
    for group in range(3):
        for v in range(n):
            if not used[v]:
                continue
            g = 0 if v < n_fixed else (1 if not movable[v] else 2)
            if g == group:
                inv[v] = nn
                nn += 1
    nodes = np.empty(nn, dtype=np.int64)
    n_boundary = 0
    n_stay = 0
    for v in range(n):
        if inv[v] >= 0:
            nodes[inv[v]] = v
            if v < n_fixed:
                n_boundary += 1
            elif not movable[v]:
                n_stay += 1
    local = np.empty((c, 3), dtype=np.int64)
    a = 0
    for t in range(m):
        if inner[t]:
            for k in range(3):
                local[a, k] = inv[tri[t, k]]
            a += 1
    t32, nbr, sl = _local_mesh(local, nodes.shape[0], slide, movable, inv)
    return (nodes, n_boundary, n_boundary + n_stay, inner, t32, nbr, sl,
            _pairs_inside(walls, inv), _pairs_inside(curves, inv), outer_q)


@njit(cache=True)
def _pairs_inside(pairs, inv):  # type: ignore[no-untyped-def]
    """The rows of ``pairs (k, 2)`` whose two nodes have a number in ``inv``, renumbered."""
    out = np.empty(pairs.shape, dtype=np.int64)
    c = 0
    for r in range(pairs.shape[0]):
        i0, i1 = inv[pairs[r, 0]], inv[pairs[r, 1]]
        if i0 >= 0 and i1 >= 0:
            out[c, 0], out[c, 1] = i0, i1
            c += 1
    return out[:c].copy()


@njit(cache=True)
def stitch(p, tri, inner, kept, nodes, sub_p, sub_tri, sub_kept):  # type: ignore[no-untyped-def]
    """The repaired sub-mesh put back into the mesh (``smoothing._repair``): the nodes outside
    it and those of it that survive (``sub_kept >= 0``: its node numbers) keep their order,
    the new ones come last in theirs; the triangles outside it (rows not ``inner``) in order,
    then its triangles.  Returns ``(p, tri, kept)``, ``kept`` -1 for the new nodes."""
    n = p.shape[0]
    survive = np.ones(n, dtype=np.bool_)
    for a in range(nodes.shape[0]):
        survive[nodes[a]] = False
    n_new = 0
    for i in range(sub_kept.shape[0]):
        if sub_kept[i] >= 0:
            survive[nodes[sub_kept[i]]] = True
        else:
            n_new += 1
    index = np.empty(n, dtype=np.int64)
    n_old = 0
    for v in range(n):
        index[v] = n_old if survive[v] else n_old - 1
        if survive[v]:
            n_old += 1
    out = np.empty((n_old + n_new, 2))
    out_kept = np.empty(n_old + n_new, dtype=np.int64)
    for v in range(n):
        if survive[v]:
            out[index[v], 0], out[index[v], 1] = p[v, 0], p[v, 1]
            out_kept[index[v]] = kept[v]
    to_global = np.empty(sub_kept.shape[0], dtype=np.int64)
    w = n_old
    for i in range(sub_kept.shape[0]):
        if sub_kept[i] >= 0:
            to_global[i] = index[nodes[sub_kept[i]]]
        else:
            to_global[i] = w
            out_kept[w] = -1
            w += 1
        out[to_global[i], 0], out[to_global[i], 1] = sub_p[i, 0], sub_p[i, 1]
    m = tri.shape[0]
    n_outer = 0
    for t in range(m):
        if not inner[t]:
            n_outer += 1
    out_tri = np.empty((n_outer + sub_tri.shape[0], 3), dtype=np.int64)
    c = 0
    for t in range(m):
        if not inner[t]:
            for k in range(3):
                out_tri[c, k] = index[tri[t, k]]
            c += 1
    for r in range(sub_tri.shape[0]):
        for k in range(3):
            out_tri[c, k] = to_global[sub_tri[r, k]]
        c += 1
    return out, out_tri, out_kept
