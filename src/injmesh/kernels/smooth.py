"""The Euler step of Step 3's truss model in gather (CSR) form (numba kernels).

The nodes' neighbours are stored once per connectivity in compressed sparse rows: row i of
``indptr``/``adj`` lists the neighbours of node i in increasing order, and ``eid`` gives the bar
(row of ``bars``, the edges with ``i < j`` in the same order as ``quality.unique_edges``) each
entry belongs to, so that per-bar quantities (the desired length ``ld``) are stored once.

A step gathers, for each moving node, the bar forces of its own row: no scatter-add, no two
threads writing the same node, and a fixed summation order (the row order), so the result is
bit-identical from run to run.  The step's three per-node kernels release the GIL, and
``threaded_bar_forces``, ``threaded_stable_scale`` and ``threaded_advance`` run them over
consecutive chunks of a large node list at once (:mod:`injmesh.kernels.threads`): each node's
numbers are the serial ones, whatever the number of threads.

Examples
--------
>>> import numpy as np
>>> from injmesh.kernels.smooth import adjacency
>>> indptr, adj, eid, bars = adjacency(4, np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32), 0)
>>> bars.tolist()
[[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]]
>>> adj[indptr[2]:indptr[3]].tolist()
[0, 1, 3]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import threads
from .brep import nearest as _brep_nearest
from .delaunay import flips_logged as _flips_logged


@njit(cache=True, inline="always")
def _norm(x, y):  # type: ignore[no-untyped-def]
    # Not np.hypot: numba's hypot is a libm call per pair, ~9x slower in these loops, and the
    # coordinates here are differences of nearby points (no overflow to guard against).
    return math.sqrt(x * x + y * y)


@njit(cache=True, inline="always")
def _segment_distance(qx, qy, ax, ay, bx, by):  # type: ignore[no-untyped-def]
    abx, aby = bx - ax, by - ay
    t = ((qx - ax) * abx + (qy - ay) * aby) / max(abx * abx + aby * aby, 1e-300)
    t = min(max(t, 0.0), 1.0)
    return _norm(qx - ax - t * abx, qy - ay - t * aby)


@njit(cache=True)
def slide_targets(p, slide, total, hbar, ld_prev, ld_next, dt, out):  # type: ignore[no-untyped-def]
    """Unprojected Euler step of each sliding node (rows ``(node, previous, next)``).

    The force is half the node's total bar force and half the spring force (rest length
    ``ld_prev``, ``ld_next``) of its two boundary bars; ``out[r]`` gets ``p + dt * hbar * f``.
    """
    for r in range(slide.shape[0]):
        b = slide[r, 0]
        fx, fy = total[b, 0], total[b, 1]
        for s in range(2):
            o = slide[r, 1 + s]
            d = ld_prev[r] if s == 0 else ld_next[r]
            vx, vy = p[b, 0] - p[o, 0], p[b, 1] - p[o, 1]
            lc = max(_norm(vx, vy), 1e-300)
            c = (d - lc) / (d * lc)
            fx += c * vx
            fy += c * vy
        hb = hbar[b]
        out[r, 0] = p[b, 0] + dt * hb * 0.5 * fx
        out[r, 1] = p[b, 1] + dt * hb * 0.5 * fy


@njit(cache=True)
def slide_accept(p, slide, hbar, cand, moved):  # type: ignore[no-untyped-def]
    """Take the projected positions ``cand`` of the sliding nodes where the barriers allow.

    A step is kept when it is shorter than half the gap to either boundary neighbour, when the
    projection stays next to the node's own two segments (within twice its sagitta and a tenth
    of the step), and when it does not close a gap below ``min(gap, hbar / 2)``.  Every test
    reads the positions from before this call (moves are applied after all rows are tested),
    so the result does not depend on the order of the rows.  ``moved[r]`` gets the move over
    hbar (0 where refused).
    """
    k = slide.shape[0]
    ok = np.zeros(k, dtype=np.bool_)
    for r in range(k):
        b, bp, bn = slide[r, 0], slide[r, 1], slide[r, 2]
        ox, oy = p[b, 0], p[b, 1]
        cx, cy = cand[r, 0], cand[r, 1]
        px, py, nx, ny = p[bp, 0], p[bp, 1], p[bn, 0], p[bn, 1]
        hb = hbar[b]
        gap = min(_norm(ox - px, oy - py), _norm(ox - nx, oy - ny))
        step = _norm(cx - ox, cy - oy)
        good = step < 0.5 * gap
        stray = min(_segment_distance(cx, cy, px, py, ox, oy), _segment_distance(cx, cy, ox, oy, nx, ny))
        allow = 2.0 * _segment_distance(ox, oy, px, py, nx, ny) + 0.1 * step
        good = good and stray <= allow + 1e-9 * hb
        new_gap = min(_norm(cx - px, cy - py), _norm(cx - nx, cy - ny))
        good = good and new_gap >= min(gap, 0.5 * hb)
        ok[r] = good
        moved[r] = step / hb if good else 0.0
    for r in range(k):
        if ok[r]:
            b = slide[r, 0]
            p[b, 0] = cand[r, 0]
            p[b, 1] = cand[r, 1]


@njit(cache=True)
def adjacency(n, tri, slack):  # type: ignore[no-untyped-def]
    """Node neighbours of the triangles ``tri (m, 3)`` over ``n`` nodes, in CSR form.

    Returns ``indptr (n + 1,) int64``, ``adj (2k,) int32`` (each row sorted, no repeats),
    ``eid (2k,) int64`` (the bar of each entry) and ``bars (k, 2) int64`` (``i < j``, sorted
    lexicographically).  A node in no triangle has an empty row.  With ``slack``, each row
    ends in that many free slots (``adj`` and ``eid`` -1 there), so that :func:`flip_update`
    can change a row's neighbours in place.
    """
    m = tri.shape[0]
    # Each corner contributes its two other corners; rows are deduplicated after sorting.
    cnt = np.zeros(n + 1, dtype=np.int64)
    for t in range(m):
        for k in range(3):
            cnt[tri[t, k] + 1] += 2
    start = np.cumsum(cnt)
    fill = start[:n].copy()
    raw = np.empty(start[n], dtype=np.int32)
    for t in range(m):
        for k in range(3):
            v = tri[t, k]
            raw[fill[v]] = tri[t, (k + 1) % 3]
            raw[fill[v] + 1] = tri[t, (k + 2) % 3]
            fill[v] += 2
    indptr = np.zeros(n + 1, dtype=np.int64)
    adj = np.empty(start[n], dtype=np.int32)
    w = 0
    for v in range(n):
        # Insertion sort of the row in place (a dozen entries), then drop repeats.
        lo = start[v]
        hi = start[v + 1]
        for r in range(lo + 1, hi):
            x = raw[r]
            s = r - 1
            while s >= lo and raw[s] > x:
                raw[s + 1] = raw[s]
                s -= 1
            raw[s + 1] = x
        # Room for the row and its free slots.  ``adj`` has 2 entries per corner, about
        # twice the distinct neighbours of a mesh, but not always room for the slots too (a
        # strip, nodes in no triangle): it grows when short.
        if w + (hi - lo) + slack > adj.shape[0]:
            grown = np.empty(max(2 * adj.shape[0], w + (hi - lo) + slack), dtype=np.int32)
            grown[:w] = adj[:w]
            adj = grown
        last = -1
        for r in range(lo, hi):
            x = raw[r]
            if x != last:
                adj[w] = x
                w += 1
                last = x
        for r in range(w, w + slack):
            adj[r] = -1
        w += slack
        indptr[v + 1] = w
    adj = adj[:w].copy()
    # Bars are the entries with j > i, numbered in CSR order (= lexicographic order).
    eid = np.full(w, -1, dtype=np.int64)
    bars = np.empty(((w - slack * n) // 2, 2), dtype=np.int64)  # each bar in two rows
    b = 0
    for v in range(n):
        for e in range(indptr[v], indptr[v + 1]):
            if adj[e] > v:
                bars[b, 0] = v
                bars[b, 1] = adj[e]
                eid[e] = b
                b += 1
    # Entries with j < i take the bar number of the mirrored entry (binary search in row j,
    # whose filled part ends before its free slots).
    for v in range(n):
        for e in range(indptr[v], indptr[v + 1]):
            u = adj[e]
            if 0 <= u < v:
                lo = indptr[u]
                hi = indptr[u + 1] - slack
                while lo < hi:
                    mid = (lo + hi) // 2
                    if adj[mid] < v:
                        lo = mid + 1
                    else:
                        hi = mid
                eid[e] = eid[lo]
    return indptr, adj, eid, bars


@njit(cache=True)
def mean_bar_size(indptr, eid, ld):  # type: ignore[no-untyped-def]
    """hbar: the mean desired length of the bars at each node (0 for a node with no bar)."""
    n = indptr.shape[0] - 1
    out = np.zeros(n)
    mean_bar_size_of(indptr, eid, ld, np.arange(n), out)
    return out


@njit(cache=True, nogil=True)
def bar_forces(p, nodes, indptr, adj, eid, ld, attraction, total, damp):  # type: ignore[no-untyped-def]
    """Sum of the bar forces on each node of ``nodes``, times ``damp[node]``, written to
    ``total[node]``.

    ``attraction > 0``: the attractive force of Eq. (3.4), ``f / lc = -attraction / ld``;
    ``attraction == 0``: the spring ``f / lc = (ld - lc) / (ld lc)``.  The force on i from bar
    (i, j) is ``f / lc * (p_i - p_j)``.  ``damp`` is the stability limit of
    :func:`stable_scale` (1 for almost every node).
    """
    for a in range(nodes.shape[0]):
        i = nodes[a]
        fx = 0.0
        fy = 0.0
        xi = p[i, 0]
        yi = p[i, 1]
        for e in range(indptr[i], indptr[i + 1]):
            j = adj[e]
            if j < 0:  # a free slot of the row (see adjacency)
                continue
            vx = xi - p[j, 0]
            vy = yi - p[j, 1]
            d = ld[eid[e]]
            if attraction > 0.0:
                c = -attraction / d
            else:
                lc = max(_norm(vx, vy), 1e-300)
                c = (d - lc) / (d * lc)
            fx += c * vx
            fy += c * vy
        total[i, 0] = fx * damp[i]
        total[i, 1] = fy * damp[i]


@njit(cache=True, nogil=True)
def stable_scale(p, nodes, indptr, adj, eid, ld, step, gain, out):  # type: ignore[no-untyped-def]
    """The stability limit of the Euler step of each node of ``nodes``, written to ``out``.

    The step of node i is ``step[i]`` times its spring force.  With J_i its stiffness (minus
    the derivative of that force by its own position: a 2 x 2 matrix summed over its bars,
    ``u u^T / ld`` along a bar and ``(1/ld - 1/lc) (I - u u^T)`` across a stretched one), the
    step is stable and does not overshoot while ``step[i] * lambda_max(J_i) <= 1``.  A node
    at rest among six neighbours has 0.6 there; one pulled by many stretched bars (in a hole,
    at the tip of a fan) exceeds 2 and swings across its place for ever.  ``out[i]`` is
    ``min(1, gain / (step[i] * lambda_max(J_i)))``, the factor on its force.
    """
    for a in range(nodes.shape[0]):
        i = nodes[a]
        out[i] = _stable_one(p, i, indptr, adj, eid, ld, step[i], gain)


@njit(cache=True, inline="always")
def _stable_one(p, i, indptr, adj, eid, ld, step, gain):  # type: ignore[no-untyped-def]
    """:func:`stable_scale`'s factor of node i, whose step is ``step``."""
    jxx = 0.0
    jxy = 0.0
    jyy = 0.0
    for e in range(indptr[i], indptr[i + 1]):
        j = adj[e]
        if j < 0:
            continue
        vx = p[i, 0] - p[j, 0]
        vy = p[i, 1] - p[j, 1]
        d = ld[eid[e]]
        lc = max(_norm(vx, vy), 1e-300)
        across = max(0.0, 1.0 / d - 1.0 / lc)  # across a stretched bar, else 0
        w = (1.0 / d - across) / (lc * lc)
        jxx += across + w * vx * vx
        jyy += across + w * vy * vy
        jxy += w * vx * vy
    half = 0.5 * (jxx - jyy)
    g = step * (0.5 * (jxx + jyy) + math.sqrt(half * half + jxy * jxy))
    return gain / g if g > gain else 1.0


@njit(cache=True, nogil=True)
def renew_sizes(p, nodes, indptr, adj, eid, ld, dt, gain, mean, hbar, damp):  # type: ignore[no-untyped-def]
    """After the bars of ``nodes`` changed length (and, with ``mean``, their ld): each node's
    hbar (:func:`mean_bar_size_of`, only with ``mean``) and then its stability limit
    (:func:`stable_scale` with step ``dt * hbar``), in one pass over its row.  Node i's
    numbers come from its own row only, so the pass gives what the two kernels give one after
    the other, bit for bit, and chunks of ``nodes`` may run on several threads."""
    for a in range(nodes.shape[0]):
        i = nodes[a]
        if mean:
            _mean_one(indptr, eid, ld, i, hbar)
        damp[i] = _stable_one(p, i, indptr, adj, eid, ld, dt * hbar[i], gain)


def threaded_renew_sizes(p, nodes, indptr, adj, eid, ld, dt, gain, mean, hbar, damp):  # type: ignore[no-untyped-def]
    """:func:`renew_sizes` over chunks of ``nodes`` on several threads (same numbers)."""
    if not threads.worth(len(nodes)):
        renew_sizes(p, nodes, indptr, adj, eid, ld, dt, gain, mean, hbar, damp)
        return
    threads.each(len(nodes), lambda lo, hi: renew_sizes(p, nodes[lo:hi], indptr, adj, eid, ld, dt,
                                                       gain, mean, hbar, damp))


@njit(cache=True, inline="always")
def _fold(i, mv, dr, tol, worst, at, drift, count):  # type: ignore[no-untyped-def]
    """Node i's move ``mv`` and drift ``dr`` (over hbar) folded into a step's reductions:
    the largest move and its node (the first on ties), the largest drift, moves above tol."""
    if mv > tol:
        count += 1
    if mv > worst:
        worst = mv
        at = i
    if dr > drift:
        drift = dr
    return worst, at, drift, count


@njit(cache=True, nogil=True)
def advance(p, free, total, hbar, dt, step_cap, deep, anchor, cand, near, tol):  # type: ignore[no-untyped-def]
    """Euler step (2.4) of the free nodes: ``p_i += dt * hbar_i * total_i``, the step clamped to
    ``step_cap * hbar_i``.

    Nodes with ``deep[i]`` (far enough inside that the step cannot leave the domain) move at
    once; the others' candidate positions go to ``cand[:c]`` and their indices to ``near[:c]``
    for the caller's inside test.  Returns ``(c, largest move of a deep node / hbar, that
    node, largest drift from anchor / hbar over the deep nodes, how many deep nodes moved
    more than tol * hbar)``.
    """
    c = 0
    count = 0
    worst = -1.0
    at = -1
    drift = 0.0
    for a in range(free.shape[0]):
        i = free[a]
        hb = hbar[i]
        sx = dt * hb * total[i, 0]
        sy = dt * hb * total[i, 1]
        length = _norm(sx, sy)
        limit = step_cap * hb
        if length > limit:
            sx *= limit / length
            sy *= limit / length
            length = limit
        if deep[i]:
            p[i, 0] += sx
            p[i, 1] += sy
            worst, at, drift, count = _fold(i, length / hb,
                                            _norm(p[i, 0] - anchor[i, 0], p[i, 1] - anchor[i, 1]) / hb,
                                            tol, worst, at, drift, count)
        else:
            cand[c, 0] = p[i, 0] + sx
            cand[c, 1] = p[i, 1] + sy
            near[c] = i
            c += 1
    return c, worst, at, drift, count


@njit(cache=True)
def ring_one(indptr, adj, seeds, mark):  # type: ignore[no-untyped-def]
    """The nodes within one edge of ``seeds`` (the seeds too), sorted: ``rings(..., 1)`` as
    indices.

    The cost follows the seeds' rows, not the mesh: ``mark`` is a zeroed uint8 array over the
    nodes that the call leaves zeroed, so a caller asking at every connectivity update
    allocates nothing of the mesh's size (``rings`` allocates three such arrays, and its mask
    must be scanned).
    """
    bound = seeds.shape[0]
    for s in seeds:
        bound += indptr[s + 1] - indptr[s]
    out = np.empty(bound, dtype=np.int64)
    m = 0
    for s in seeds:
        if mark[s] == 0:
            mark[s] = 1
            out[m] = s
            m += 1
        for e in range(indptr[s], indptr[s + 1]):
            u = adj[e]
            if u >= 0 and mark[u] == 0:
                mark[u] = 1
                out[m] = u
                m += 1
    n = mark.shape[0]
    if m > n // 32:
        # Many: a scan of the marks lists them in order for less than a sort.
        k = 0
        for v in range(n):
            if mark[v]:
                mark[v] = 0
                out[k] = v
                k += 1
        return out[:m].copy()
    for a in range(m):
        mark[out[a]] = 0
    res = out[:m].copy()
    res.sort()
    return res


@njit(cache=True)
def rings(indptr, adj, seeds, k):  # type: ignore[no-untyped-def]
    """Mask of the nodes within ``k`` edges of ``seeds`` (breadth-first over the CSR rows)."""
    n = indptr.shape[0] - 1
    mask = np.zeros(n, dtype=np.bool_)
    front = np.empty(n, dtype=np.int64)
    nf = 0
    for s in seeds:
        if 0 <= s < n and not mask[s]:
            mask[s] = True
            front[nf] = s
            nf += 1
    nxt = np.empty(n, dtype=np.int64)
    for _ in range(k):
        nn = 0
        for a in range(nf):
            v = front[a]
            for e in range(indptr[v], indptr[v + 1]):
                u = adj[e]
                if u >= 0 and not mask[u]:
                    mask[u] = True
                    nxt[nn] = u
                    nn += 1
        front, nxt = nxt, front
        nf = nn
    return mask


@njit(cache=True)
def corners_by_node(tri, n):  # type: ignore[no-untyped-def]
    """The corners (flat indices ``3 t + k``) of each node's triangles, in CSR form.

    Returns ``start (n + 1,)`` and ``corner``: node i's corners are
    ``corner[start[i]:start[i + 1]]``, increasing (a stable counting sort of ``tri.ravel()``).
    """
    m = tri.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for t in range(m):
        for k in range(3):
            start[tri[t, k] + 1] += 1
    for i in range(n):
        start[i + 1] += start[i]
    fill = start[:-1].copy()
    corner = np.empty(3 * m, dtype=np.int64)
    for t in range(m):
        for k in range(3):
            v = tri[t, k]
            corner[fill[v]] = 3 * t + k
            fill[v] += 1
    return start, corner


@njit(cache=True)
def star_min(start, corner, q):  # type: ignore[no-untyped-def]
    """Smallest ``q`` over each node's triangles (inf for a node in none)."""
    n = start.shape[0] - 1
    out = np.full(n, np.inf)
    for i in range(n):
        for s in range(start[i], start[i + 1]):
            v = q[corner[s] // 3]
            if v < out[i]:
                out[i] = v
    return out


@njit(cache=True)
def row_bars(indptr, eid, nodes, seen):  # type: ignore[no-untyped-def]
    """The distinct bars in the CSR rows of ``nodes``, in order of first appearance.

    ``seen`` is a scratch flag per bar, all False on entry and on return.
    """
    total = 0
    for a in range(nodes.shape[0]):
        v = nodes[a]
        total += indptr[v + 1] - indptr[v]
    out = np.empty(total, dtype=np.int64)
    w = 0
    for a in range(nodes.shape[0]):
        v = nodes[a]
        for e in range(indptr[v], indptr[v + 1]):
            b = eid[e]
            if b >= 0 and not seen[b]:
                seen[b] = True
                out[w] = b
                w += 1
    for r in range(w):
        seen[out[r]] = False
    return out[:w]


@njit(cache=True)
def mean_bar_size_of(indptr, eid, ld, nodes, out):  # type: ignore[no-untyped-def]
    """:func:`mean_bar_size` for ``nodes`` only, written to ``out[nodes]`` (rows with bars)."""
    for a in range(nodes.shape[0]):
        _mean_one(indptr, eid, ld, nodes[a], out)


@njit(cache=True, inline="always")
def _mean_one(indptr, eid, ld, v, out):  # type: ignore[no-untyped-def]
    s = 0.0
    d = 0
    for e in range(indptr[v], indptr[v + 1]):
        if eid[e] >= 0:
            s += ld[eid[e]]
            d += 1
    if d > 0:
        out[v] = s / d


@njit(cache=True)
def moved_bars(indptr, adj, eid, bars, p, nodes, mark, seen, graded):  # type: ignore[no-untyped-def]
    """What a connectivity update renews around the nodes that moved: :func:`ring_one` of
    ``nodes`` (the nodes whose bars changed length), and with ``graded`` (an h that is not
    constant) the distinct bars of their rows (:func:`row_bars`) and those bars' midpoints,
    where h gives their new ld (none without), in one call."""
    near = ring_one(indptr, adj, nodes, mark)
    b = row_bars(indptr, eid, nodes, seen) if graded else np.empty(0, dtype=np.int64)
    mid = np.empty((b.shape[0], 2))
    for r in range(b.shape[0]):
        i, j = bars[b[r], 0], bars[b[r], 1]
        mid[r, 0] = 0.5 * (p[i, 0] + p[j, 0])
        mid[r, 1] = 0.5 * (p[i, 1] + p[j, 1])
    return near, b, mid


@njit(cache=True)
def flip_update(indptr, adj, eid, bars, removed, added):  # type: ignore[no-untyped-def]
    """Edge flips applied to the padded CSR rows in place: edge ``removed[r]`` gives its bar
    number to edge ``added[r]`` (the same count of each: a flip swaps one diagonal for the
    other).  Returns the bar numbers reused, or an empty array when a row has no free slot
    left (the caller then rebuilds the rows from the triangles)."""
    k = removed.shape[0]
    ids = np.empty(k, dtype=np.int64)
    for r in range(k):
        a, b = removed[r, 0], removed[r, 1]
        bar = -1
        for side in range(2):
            u = a if side == 0 else b
            o = b if side == 0 else a
            for e in range(indptr[u], indptr[u + 1]):
                if adj[e] == o:
                    bar = eid[e]
                    adj[e] = -1
                    eid[e] = -1
                    break
        if bar < 0:
            return np.empty(0, dtype=np.int64)
        ids[r] = bar
    for r in range(k):
        c, d = added[r, 0], added[r, 1]
        bar = ids[r]
        for side in range(2):
            u = c if side == 0 else d
            o = d if side == 0 else c
            slot = -1
            for e in range(indptr[u], indptr[u + 1]):
                if adj[e] < 0:
                    slot = e
                    break
            if slot < 0:
                return np.empty(0, dtype=np.int64)
            adj[slot] = o
            eid[slot] = bar
        bars[bar, 0] = min(c, d)
        bars[bar, 1] = max(c, d)
    return ids


@njit(cache=True)
def depth_bounds(p, anchor, d0, hbar, free, deep, exact):  # type: ignore[no-untyped-def]
    """For the free nodes ``free`` whose anchors move to their positions: with ``exact`` (d
    1-Lipschitz), the bound ``d0 + |p - anchor|`` of d, kept in ``d0`` where it is below
    ``-deep * hbar`` (the node is deep whatever d is); returns the other nodes (all of them
    without ``exact``, and any whose anchor is NaN), whose d must be asked."""
    ask = np.empty(free.shape[0], dtype=np.int64)
    na = 0
    for a in range(free.shape[0]):
        i = free[a]
        if exact:
            bound = d0[i] + math.hypot(p[i, 0] - anchor[i, 0], p[i, 1] - anchor[i, 1])
            if bound < -deep * hbar[i]:  # NaN (no anchor yet) is not
                d0[i] = bound
                continue
        ask[na] = i
        na += 1
    return ask[:na]


@njit(cache=True)
def mark_deep(d0, hbar, free, deep, flags):  # type: ignore[no-untyped-def]
    """``flags[i] = d0[i] < -deep * hbar[i]`` for the nodes ``free``."""
    for a in range(free.shape[0]):
        i = free[a]
        flags[i] = d0[i] < -deep * hbar[i]


@njit(cache=True, nogil=True)
def _mark_drifted(p, anchor, hbar, tol, mark, first):  # type: ignore[no-untyped-def]
    out = np.empty(p.shape[0], dtype=np.int64)
    k = 0
    for i in range(p.shape[0]):
        m = _norm(p[i, 0] - anchor[i, 0], p[i, 1] - anchor[i, 1]) > tol * hbar[i]
        mark[i] = m
        if m:
            out[k] = first + i
            k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def _rows_using(tri, mark, first):  # type: ignore[no-untyped-def]
    rows = np.empty(tri.shape[0], dtype=np.int32)
    r = 0
    for t in range(tri.shape[0]):
        if mark[tri[t, 0]] or mark[tri[t, 1]] or mark[tri[t, 2]]:
            rows[r] = first + t
            r += 1
    return rows[:r]


def drifted(p, anchor, hbar, tol, tri):  # type: ignore[no-untyped-def]
    """The nodes that moved more than ``tol * hbar`` from their anchors, and the rows of
    ``tri`` (int32) that use one of them: where a connectivity update starts its flips.

    Both scans (nodes, then triangles) run over chunks on several threads; the lists come
    out in increasing order, as from one loop.
    """
    mark = np.empty(len(p), dtype=np.bool_)
    nodes = threads.each(len(p), lambda lo, hi: _mark_drifted(p[lo:hi], anchor[lo:hi], hbar[lo:hi],
                                                              tol, mark[lo:hi], lo))
    rows = threads.each(len(tri), lambda lo, hi: _rows_using(tri[lo:hi], mark, lo))
    return (nodes[0] if len(nodes) == 1 else np.concatenate(nodes),
            rows[0] if len(rows) == 1 else np.concatenate(rows))


def threaded_bar_forces(p, nodes, indptr, adj, eid, ld, attraction, total, damp):  # type: ignore[no-untyped-def]
    """:func:`bar_forces` over chunks of ``nodes`` on several threads (same numbers)."""
    if not threads.worth(len(nodes)):  # a small mesh: no ~8 us of hand-off per call
        bar_forces(p, nodes, indptr, adj, eid, ld, attraction, total, damp)
        return
    threads.each(len(nodes), lambda lo, hi: bar_forces(p, nodes[lo:hi], indptr, adj, eid, ld,
                                                      attraction, total, damp))


def threaded_stable_scale(p, nodes, indptr, adj, eid, ld, step, gain, out):  # type: ignore[no-untyped-def]
    """:func:`stable_scale` over chunks of ``nodes`` on several threads (same numbers)."""
    if not threads.worth(len(nodes)):
        stable_scale(p, nodes, indptr, adj, eid, ld, step, gain, out)
        return
    threads.each(len(nodes), lambda lo, hi: stable_scale(p, nodes[lo:hi], indptr, adj, eid, ld,
                                                        step, gain, out))


def threaded_advance(p, free, total, hbar, dt, step_cap, deep, anchor, cand, near, tol):  # type: ignore[no-untyped-def]
    """:func:`advance` over chunks of ``free`` on several threads, with its serial result.

    Chunk k writes its candidates to ``cand[lo:]``/``near[lo:]`` of its own range; they are
    moved down in chunk order, and the largest move keeps the serial loop's tie (the first
    node), so the result is the serial one.
    """
    if not threads.worth(len(free)):
        return advance(p, free, total, hbar, dt, step_cap, deep, anchor, cand, near, tol)
    parts = threads.each(len(free), lambda lo, hi: (lo, advance(
        p, free[lo:hi], total, hbar, dt, step_cap, deep, anchor, cand[lo:], near[lo:], tol)))
    c, worst, at, drift, count = 0, -1.0, -1, 0.0, 0
    for lo, (ck, wk, ak, dk, nk) in parts:
        if ck and lo != c:
            cand[c:c + ck] = cand[lo:lo + ck]
            near[c:c + ck] = near[lo:lo + ck]
        c += ck
        if wk > worst:
            worst, at = wk, ak
        drift = max(drift, dk)
        count += nk
    return c, worst, at, drift, count


# --- the quality pass (smoothing._optimize) -------------------------------------------------


@njit(cache=True, inline="always")
def _q_of(ax, ay, bx, by, cx, cy):  # type: ignore[no-untyped-def]
    """Eq. (5.1) of one triangle, as kernels.mesh.triangle_quality computes it."""
    a = math.sqrt((cx - bx) * (cx - bx) + (cy - by) * (cy - by))
    b = math.sqrt((ax - cx) * (ax - cx) + (ay - cy) * (ay - cy))
    c = math.sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay))
    den = a * b * c
    if den == 0.0 or not math.isfinite(den):
        return 0.0
    return (b + c - a) * (c + a - b) * (a + b - c) / den


@njit(cache=True)
def star_independent(order, tri, start, corner, scratch):  # type: ignore[no-untyped-def]
    """Greedy independent set of the nodes ``order`` (ranked, best first) over the mesh's
    edges: a node is taken unless a node of its triangles was taken before it.  Returns a mask
    over ``order``; ``scratch`` is a zeroed flag per node, zeroed again on return.

    The greedy set over the candidate pairs joined by a side of a triangle (only candidates
    are ever taken, and two nodes of a triangle are joined by one of its sides), without
    listing the pairs.
    """
    m = order.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    for a in range(m):
        v = order[a]
        ok = True
        for s in range(start[v], start[v + 1]):
            t = corner[s] // 3
            if scratch[tri[t, 0]] or scratch[tri[t, 1]] or scratch[tri[t, 2]]:
                ok = False
                break
        if ok:
            scratch[v] = True
            out[a] = True
    for a in range(m):
        if out[a]:
            scratch[order[a]] = False
    return out


@njit(cache=True)
def clear_stars(nodes, tri, start, corner, flags):  # type: ignore[no-untyped-def]
    """``flags`` False at every node of the triangles around each of ``nodes``."""
    for a in range(nodes.shape[0]):
        v = nodes[a]
        for s in range(start[v], start[v + 1]):
            t = corner[s] // 3
            flags[tri[t, 0]] = False
            flags[tri[t, 1]] = False
            flags[tri[t, 2]] = False


@njit(cache=True)
def star_targets(p, tri, start, corner, move):  # type: ignore[no-untyped-def]
    """For each node of ``move``: the mean, over its triangles, of the apex of the equilateral
    triangle on the side opposite it (counter-clockwise triangles)."""
    h = math.sqrt(3.0) / 2.0
    out = np.empty((move.shape[0], 2))
    for a in range(move.shape[0]):
        i = move[a]
        sx = 0.0
        sy = 0.0
        cnt = start[i + 1] - start[i]
        for s in range(start[i], start[i + 1]):
            t = corner[s] // 3
            k = corner[s] - 3 * t
            u = tri[t, (k + 1) % 3]
            v = tri[t, (k + 2) % 3]
            ex = p[v, 0] - p[u, 0]
            ey = p[v, 1] - p[u, 1]
            sx += 0.5 * (p[u, 0] + p[v, 0]) + h * -ey
            sy += 0.5 * (p[u, 1] + p[v, 1]) + h * ex
        out[a, 0] = sx / max(cnt, 1)
        out[a, 1] = sy / max(cnt, 1)
    return out


@njit(cache=True)
def star_trial(p, tri, start, corner, move, step, star, prev_b, next_b, on_bnd, inside, done):  # type: ignore[no-untyped-def]
    """Whether each node of ``move`` may go to ``step``: its star's worst q rises, no star
    triangle turns clockwise or flat, it stays inside (or is a sliding node) and a sliding
    node stays next to its own two boundary segments.  The nodes of ``move`` share no
    triangle, so each star is tried alone."""
    ok = np.zeros(move.shape[0], dtype=np.bool_)
    for a in range(move.shape[0]):
        if done[a] or not (inside[a] or on_bnd[a]):
            continue
        i = move[a]
        x = step[a, 0]
        y = step[a, 1]
        worst = np.inf
        flipped = False
        for s in range(start[i], start[i + 1]):
            t = corner[s] // 3
            k = corner[s] - 3 * t
            u = tri[t, (k + 1) % 3]
            v = tri[t, (k + 2) % 3]
            ux, uy, vx, vy = p[u, 0], p[u, 1], p[v, 0], p[v, 1]
            # Corners in the triangle's own order (i, u, v): the area's sign as signed_areas.
            if 0.5 * ((ux - x) * (vy - y) - (uy - y) * (vx - x)) <= 0.0:
                flipped = True
                break
            q = _q_of(x, y, ux, uy, vx, vy)
            if q < worst:
                worst = q
        if flipped or not worst > star[i]:
            continue
        if on_bnd[a]:
            pmx, pmy = p[i, 0], p[i, 1]
            pp = prev_b[i]
            pn = next_b[i]
            stray = min(_segment_distance(x, y, p[pp, 0], p[pp, 1], pmx, pmy),
                        _segment_distance(x, y, pmx, pmy, p[pn, 0], p[pn, 1]))
            moved = math.sqrt((x - pmx) * (x - pmx) + (y - pmy) * (y - pmy))
            allow = 2.0 * _segment_distance(pmx, pmy, p[pp, 0], p[pp, 1], p[pn, 0], p[pn, 1]) + 0.1 * moved
            if not stray <= allow * (1.0 + 1e-9):
                continue
        ok[a] = True
    return ok


@njit(cache=True)
def restar(p, tri, start, corner, q, star, moved):  # type: ignore[no-untyped-def]
    """After the nodes ``moved`` moved: q of their triangles, and the star minimum of every
    node of those triangles."""
    for i in moved:
        for s in range(start[i], start[i + 1]):
            t = corner[s] // 3
            a, b, c = tri[t, 0], tri[t, 1], tri[t, 2]
            q[t] = _q_of(p[a, 0], p[a, 1], p[b, 0], p[b, 1], p[c, 0], p[c, 1])
    for i in moved:
        for s in range(start[i], start[i + 1]):
            t = corner[s] // 3
            for k in range(3):
                v = tri[t, k]
                m = np.inf
                for r in range(start[v], start[v + 1]):
                    w = q[corner[r] // 3]
                    if w < m:
                        m = w
                star[v] = m


@njit(cache=True)
def flip_diff(rows, gone, made):  # type: ignore[no-untyped-def]
    """What a change of some triangle rows did in all: ``rows`` (the rows changed, repeats
    allowed) sorted and distinct, and the edges removed and the edges added, each as sorted
    distinct ``(i, j)`` rows (i < j) in increasing order.

    ``gone`` and ``made`` are node pairs ``(k, 2)`` with repeats: the edges each flip removed
    and made (``kernels.delaunay.flips_logged``), or the sides of the rows before and after a
    change of them.  An edge's count (+1 each time in ``gone``, -1 in ``made``) is +1 or +2
    when it is gone (it alternates between removed and made; two rows held it), -1 or -2 when
    it is new, and 0 when it is there before and after (a flip undid another; a side the rows
    keep).  A sort of the edges' keys ``i * 2**31 + j`` groups each edge."""
    out_rows = np.sort(rows.astype(np.int64))
    nr = 0
    for r in range(out_rows.shape[0]):
        if r == 0 or out_rows[r] != out_rows[r - 1]:
            out_rows[nr] = out_rows[r]
            nr += 1
    big = np.int64(1) << np.int64(31)
    ng, nm = gone.shape[0], made.shape[0]
    keys = np.empty(ng + nm, dtype=np.int64)
    for r in range(ng):
        a, b = np.int64(gone[r, 0]), np.int64(gone[r, 1])
        keys[r] = min(a, b) * big + max(a, b)
    for r in range(nm):
        a, b = np.int64(made[r, 0]), np.int64(made[r, 1])
        keys[ng + r] = min(a, b) * big + max(a, b)
    order = np.argsort(keys, kind="mergesort")
    removed = np.empty((ng, 2), dtype=np.int64)
    added = np.empty((nm, 2), dtype=np.int64)
    n_removed = 0
    n_added = 0
    s = 0
    while s < ng + nm:
        key = keys[order[s]]
        count = 0
        while s < ng + nm and keys[order[s]] == key:
            count += 1 if order[s] < ng else -1
            s += 1
        if count > 0:
            removed[n_removed, 0], removed[n_removed, 1] = key // big, key % big
            n_removed += 1
        elif count < 0:
            added[n_added, 0], added[n_added, 1] = key // big, key % big
            n_added += 1
    return out_rows[:nr].copy(), removed[:n_removed].copy(), added[:n_added].copy()


# --- one Euler step in few calls (smoothing._Relaxation.run) ---------------------------------
# On a sub-mesh of the repair (tens to a few hundred nodes) a step's kernels take microseconds
# each and the NumPy calls around them (gathers, hypot, reductions over the near and sliding
# nodes) cost more than the kernels: these fuse them.  Distances use math.hypot, the libm call
# np.hypot makes, so every test and reduction gives the numbers of the NumPy lines they replace.


@njit(cache=True)
def step_free(p, moving, free, indptr, adj, eid, ld, attraction, total, damp, hbar, dt, step_cap,  # type: ignore[no-untyped-def]
              deep, anchor, d0, reach, cand, near, ok, tol):
    """:func:`bar_forces` on ``moving``, :func:`advance` on ``free``, then the anchor test of
    the near nodes' candidates: ``ok[r]`` is True where candidate r is within ``reach`` of
    its anchor's depth ``-d0`` of its anchor (inside without asking the domain).

    Returns :func:`advance`'s ``(c, worst, at, drift, count)`` and how many of the ``c``
    candidates still need the domain's inside test.
    """
    bar_forces(p, moving, indptr, adj, eid, ld, attraction, total, damp)
    c, worst, at, drift, count = advance(p, free, total, hbar, dt, step_cap, deep, anchor, cand,
                                         near, tol)
    return c, worst, at, drift, count, near_inside(cand, near, c, anchor, d0, reach, ok)


@njit(cache=True)
def near_inside(cand, near, c, anchor, d0, reach, ok):  # type: ignore[no-untyped-def]
    """``ok[r]`` for the first ``c`` candidates: ``|cand[r] - anchor[i]| < -reach * d0[i]``
    with ``i = near[r]`` (see :func:`step_free`).  Returns how many are not."""
    asks = 0
    for r in range(c):
        i = near[r]
        inside = math.hypot(cand[r, 0] - anchor[i, 0], cand[r, 1] - anchor[i, 1]) < -reach * d0[i]
        ok[r] = inside
        if not inside:
            asks += 1
    return asks


@njit(cache=True)
def take_near(p, near, cand, c, ok, hbar, anchor, tol, worst, at, drift, count):  # type: ignore[no-untyped-def]
    """Move each near node ``near[r]`` (r < c) to ``cand[r]`` where ``ok[r]``, and fold the moves
    into the step's ``(worst, at, drift, count)`` as :func:`advance` does for the deep nodes:
    largest move over hbar and its node (the first one on ties), largest distance from the
    anchor over hbar, moves above ``tol``."""
    for r in range(c):
        if not ok[r]:
            continue
        i = near[r]
        hb = hbar[i]
        worst, at, drift, count = _fold(
            i, math.hypot(cand[r, 0] - p[i, 0], cand[r, 1] - p[i, 1]) / hb,
            math.hypot(cand[r, 0] - anchor[i, 0], cand[r, 1] - anchor[i, 1]) / hb,
            tol, worst, at, drift, count)
        p[i, 0] = cand[r, 0]
        p[i, 1] = cand[r, 1]
    return worst, at, drift, count


@njit(cache=True)
def fold_moves(nodes, moved, p, anchor, hbar, tol, worst, at, drift, count):  # type: ignore[no-untyped-def]
    """Fold the moves ``moved[r]`` (over hbar) of ``nodes[r]``, already taken, into the step's
    ``(worst, at, drift, count)`` (see :func:`take_near`); the drift is that of every node of
    ``nodes``, moved or not."""
    for r in range(nodes.shape[0]):
        i = nodes[r]
        worst, at, drift, count = _fold(
            i, moved[r], math.hypot(p[i, 0] - anchor[i, 0], p[i, 1] - anchor[i, 1]) / hbar[i],
            tol, worst, at, drift, count)
    return worst, at, drift, count


# --- many Euler steps in one call (smoothing._Relaxation.run on a compiled boundary) ---------
# A step of a small mesh or of a repair patch is a few microseconds of kernels, and the Python
# between them (the dispatches, the projection of the sliding nodes through the domain's
# methods, the inside test of the near nodes) cost ten times that: 52-199 steps per paper case
# at 80-130 us each.  When the domain's boundary is one the kernels can query themselves (a
# B-rep, or a circle or rectangle by the closed formulas of their methods), the whole run of
# steps up to the next connectivity update is one call.  Every number is the one the Python
# loop computes: the same kernels in the same order, and the boundary queries the methods make
# (:func:`injmesh.kernels.brep.nearest` on the same points in the same order, or the same
# closed formulas with the libm hypot that np.hypot calls).

#: ``run_steps``' outcomes: the cap reached before a step, the convergence test met, the slow
#: tail reached, a node drifted past the re-triangulation threshold, the steps used up.
RUN_CAP, RUN_CONVERGED, RUN_TAIL, RUN_RETRIANGULATE, RUN_DONE = 0, 1, 2, 3, 4
#: ``kind`` of a compiled boundary: a B-rep through its hierarchy, a circle, a rectangle.
BOUNDARY_BREP, BOUNDARY_CIRCLE, BOUNDARY_RECTANGLE = 0, 1, 2
#: The domain's boundary among :func:`pack_boundaries`' (an int64, not a literal 0: a literal
#: argument would give :func:`_query_of` a second compiled version).
_DOMAIN_BOUNDARY = np.int64(0)


@njit(cache=True)
def boundary_query(q, kind, shape, origin, g, foot):  # type: ignore[no-untyped-def]
    """Signed distance of each point of ``q (m, 2)`` to the boundary (negative inside), and,
    when ``foot`` has m rows, the nearest boundary point into it, as the domain's ``sdf`` and
    ``project`` give them.

    ``kind``/``shape``: a B-rep (``shape`` unused; ``origin`` and ``g`` its
    :meth:`~injmesh.geometry.brep.BRep.kernel_data`), a circle (``shape = (cx, cy, r)``) or an
    axis-aligned rectangle (``shape = (x0, y0, x1, y1)``).
    """
    m = q.shape[0]
    d = np.empty(m)
    want = foot.shape[0] == m
    if kind == BOUNDARY_BREP:
        local = np.empty((m, 2))
        for r in range(m):
            local[r, 0] = q[r, 0] - origin[0]
            local[r, 1] = q[r, 1] - origin[1]
        dist, f, _ = _brep_nearest(local, g)
        for r in range(m):
            d[r] = dist[r]
            if want:
                foot[r, 0] = f[r, 0] + origin[0]
                foot[r, 1] = f[r, 1] + origin[1]
    elif kind == BOUNDARY_CIRCLE:
        cx, cy, rad = shape[0], shape[1], shape[2]
        for r in range(m):
            vx, vy = q[r, 0] - cx, q[r, 1] - cy
            n = math.hypot(vx, vy)
            d[r] = n - rad
            if want:
                if not n > 0.0:
                    vx, vy, n = 1.0, 0.0, 1.0
                foot[r, 0] = cx + rad * vx / n
                foot[r, 1] = cy + rad * vy / n
    else:
        x0, y0, x1, y1 = shape[0], shape[1], shape[2], shape[3]
        mx, my = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
        wx, wy = 0.5 * (x1 - x0), 0.5 * (y1 - y0)
        for r in range(m):
            x, y = q[r, 0], q[r, 1]
            ax, ay = abs(x - mx) - wx, abs(y - my) - wy
            d[r] = math.hypot(max(ax, 0.0), max(ay, 0.0)) + min(max(ax, ay), 0.0)
            if want:
                fx, fy = min(max(x, x0), x1), min(max(y, y0), y1)
                if x > x0 and x < x1 and y > y0 and y < y1:
                    # The nearest side, the first of (left, right, bottom, top) on ties.
                    k, best = 0, x - x0
                    if x1 - x < best:
                        k, best = 1, x1 - x
                    if y - y0 < best:
                        k, best = 2, y - y0
                    if y1 - y < best:
                        k = 3
                    if k == 0:
                        fx = x0
                    elif k == 1:
                        fx = x1
                    elif k == 2:
                        fy = y0
                    else:
                        fy = y1
                foot[r, 0], foot[r, 1] = fx, fy
    return d


def pack_boundaries(boundaries):  # type: ignore[no-untyped-def]
    """Several compiled boundaries (:meth:`~injmesh.geometry.Domain.kernel_boundary`) as
    flat arrays one kernel signature takes, whatever their number: ``(kinds (B,), shapes (B,
    4), origins (B, 2), cat, offs (B + 1, 25))``, ``cat`` the 25 arrays of every ``g``
    concatenated and ``offs`` where each boundary's rows start in each (:func:`_query_of`
    slices them back; a slice of rows keeps the arrays' C layout, so ``nearest`` keeps its one
    specialisation)."""
    kinds = np.array([b[0] for b in boundaries], dtype=np.int64)
    shapes = np.zeros((len(boundaries), 4))
    for t, b in enumerate(boundaries):
        shapes[t, :len(b[1])] = b[1]
    origins = np.array([b[2] for b in boundaries], dtype=np.float64).reshape(-1, 2)
    gs = [b[3] for b in boundaries]
    if len(gs) == 1:
        cat = tuple(gs[0])
    else:
        cat = tuple(np.ascontiguousarray(np.concatenate([g[j] for g in gs])) for j in range(len(gs[0])))
    offs = np.zeros((len(gs) + 1, len(gs[0])), dtype=np.int64)
    offs[1:] = np.cumsum([[len(a) for a in g] for g in gs], axis=0)
    return kinds, shapes, origins, cat, offs


@njit(cache=True)
def _query_of(q, kinds, shapes, origins, cat, offs, t, foot):  # type: ignore[no-untyped-def]
    """:func:`boundary_query` on boundary ``t`` of :func:`pack_boundaries`' arrays."""
    o = offs[t]
    e = offs[t + 1]
    g = (cat[0][o[0]:e[0]], cat[1][o[1]:e[1]], cat[2][o[2]:e[2]], cat[3][o[3]:e[3]],
         cat[4][o[4]:e[4]], cat[5][o[5]:e[5]], cat[6][o[6]:e[6]], cat[7][o[7]:e[7]],
         cat[8][o[8]:e[8]], cat[9][o[9]:e[9]], cat[10][o[10]:e[10]], cat[11][o[11]:e[11]],
         cat[12][o[12]:e[12]], cat[13][o[13]:e[13]], cat[14][o[14]:e[14]],
         cat[15][o[15]:e[15]], cat[16][o[16]:e[16]], cat[17][o[17]:e[17]],
         cat[18][o[18]:e[18]], cat[19][o[19]:e[19]], cat[20][o[20]:e[20]],
         cat[21][o[21]:e[21]], cat[22][o[22]:e[22]], cat[23][o[23]:e[23]],
         cat[24][o[24]:e[24]])
    return boundary_query(q, kinds[t], shapes[t], origins[t], g, foot)


@njit(cache=True)
def project_rows(target, kinds, shapes, origins, cat, offs, points, out):  # type: ignore[no-untyped-def]
    """Each point onto boundary ``target[r]`` (0: the domain's), into ``out``: one query per
    boundary on its points in row order, as the Python projectors are called (on a B-rep
    the foot of an exact tie depends on the points queried before it)."""
    n = points.shape[0]
    for t in range(kinds.shape[0]):
        m = 0
        for r in range(n):
            if target[r] == t:
                m += 1
        if m == 0:
            continue
        if m == n:
            _query_of(points, kinds, shapes, origins, cat, offs, t, out)
            return
        rows = np.empty(m, dtype=np.int64)
        q = np.empty((m, 2))
        m = 0
        for r in range(n):
            if target[r] == t:
                rows[m] = r
                q[m, 0], q[m, 1] = points[r, 0], points[r, 1]
                m += 1
        foot = np.empty((m, 2))
        _query_of(q, kinds, shapes, origins, cat, offs, t, foot)
        for j in range(m):
            out[rows[j], 0], out[rows[j], 1] = foot[j, 0], foot[j, 1]


@njit(cache=True)
def run_steps(p, moving, free, indptr, adj, eid, ld, attraction, total, damp, hbar, dt, step_cap,  # type: ignore[no-untyped-def]
              deep, anchor, d0, reach, cand, near, ok, tol, slide, ld_prev, ld_next, target, kinds,
              shapes, origins, cat, offs, iterations, weight, cap, steps, tail, tail_after,
              retriangulate):
    """Up to ``steps`` Euler steps of ``smoothing._Relaxation.run`` (free nodes by
    :func:`step_free` and :func:`take_near`, sliding nodes by :func:`slide_targets`, the
    projection and :func:`slide_accept`), the boundaries asked through :func:`boundary_query`:
    boundary 0 of :func:`pack_boundaries`' arrays is the domain's (the inside test), sliding
    row r projects onto boundary ``target[r]`` (the domain's, or its interior curve's).

    Stops before a step that would take ``iterations`` past ``cap`` (each step adds
    ``weight``), or after a step whose largest move is below ``tol`` (converged), whose moving
    nodes are at most ``tail`` once ``iterations >= tail_after``, or whose largest drift is
    above ``retriangulate``.  Returns ``(outcome, steps taken, iterations, largest move of the
    last step over hbar, its node, nodes that moved more than tol in it)``.
    """
    n_sl = slide.shape[0]
    step_to = np.empty((n_sl, 2))
    cand_sl = np.empty((n_sl, 2))
    moved = np.empty(n_sl)
    sl_nodes = slide[:, 0].copy()
    no_foot = np.empty((0, 2))
    worst, at, count = 0.0, 0, 0
    for s in range(steps):
        if iterations + weight > cap + 1e-9:
            return RUN_CAP, s, iterations, worst, at, count
        iterations += weight
        c, worst, at, drift, count, asks = step_free(
            p, moving, free, indptr, adj, eid, ld, attraction, total, damp, hbar, dt, step_cap,
            deep, anchor, d0, reach, cand, near, ok, tol)
        if c:
            if asks:
                # The inside test of the candidates the anchor test left open, in their order.
                rest = np.empty(asks, dtype=np.int64)
                m = 0
                for r in range(c):
                    if not ok[r]:
                        rest[m] = r
                        m += 1
                q = np.empty((asks, 2))
                for j in range(asks):
                    q[j, 0], q[j, 1] = cand[rest[j], 0], cand[rest[j], 1]
                d = _query_of(q, kinds, shapes, origins, cat, offs, _DOMAIN_BOUNDARY, no_foot)
                for j in range(asks):
                    ok[rest[j]] = not d[j] > 0.0
            worst, at, drift, count = take_near(p, near, cand, c, ok, hbar, anchor, tol, worst, at,
                                                drift, count)
        if n_sl:
            slide_targets(p, slide, total, hbar, ld_prev, ld_next, dt, step_to)
            project_rows(target, kinds, shapes, origins, cat, offs, step_to, cand_sl)
            slide_accept(p, slide, hbar, cand_sl, moved)
            worst, at, drift, count = fold_moves(sl_nodes, moved, p, anchor, hbar, tol, worst, at,
                                                 drift, count)
        worst = max(worst, 0.0)
        at = max(at, 0)
        if worst < tol:
            return RUN_CONVERGED, s + 1, iterations, worst, at, count
        if count <= tail and iterations >= tail_after:
            return RUN_TAIL, s + 1, iterations, worst, at, count
        if drift > retriangulate:
            return RUN_RETRIANGULATE, s + 1, iterations, worst, at, count
    return RUN_DONE, steps, iterations, worst, at, count


# --- a connectivity update in two calls (smoothing._Relaxation.retriangulate, compiled run) -----
# After a compiled run the update between two runs was a dozen kernel calls and NumPy lines
# (~180 us on a paper case, three quarters of a run's time).  It is two calls around the one
# thing that must stay in Python, h at the new midpoints: :func:`relink` (flips, node lists,
# the nodes and bars to renew, the midpoints) and :func:`resize` (the new ld, hbar, stability
# limits, inside flags and anchors), the same kernels in the same order as the Python path.

#: :func:`relink`'s outcomes: the lists follow the flips; the flips met an inverted triangle
#: (a triangulation from scratch); a row ran out of free slots (rebuild the lists).
RELINK_OK, RELINK_INVERTED, RELINK_REBUILD = 0, 1, 2


@njit(cache=True)
def relink(p, anchor, hbar, local_drift, t32, nbr, con, vt, tri, indptr, adj, eid, ld, bars,  # type: ignore[no-untyped-def]
           mark, seen, graded, constant, slide):
    """The local update of ``smoothing._Relaxation.retriangulate`` up to h: the nodes that
    drifted more than ``local_drift * hbar`` (:func:`drifted`), Lawson flips from their
    triangles (``kernels.delaunay.flips_logged``), the node lists and ``tri`` following the
    flips (:func:`flip_diff`, :func:`flip_update`; ``constant`` is the ld of a new bar when h
    is constant, NaN otherwise), then what :func:`resize` renews: the nodes (the drifted ones
    and the flips' corners), their ring (:func:`moved_bars`), with ``graded`` their bars and
    the points where h is wanted (the bars' midpoints, then the midpoints of the boundary bars
    of the sliding rows that hold one of the nodes, previous side then next side) and those
    rows.

    Returns ``(outcome, nodes, near, bars, mid, rows)``.
    """
    # drifted()'s two scans, in one chunk each.
    flag = np.empty(p.shape[0], dtype=np.bool_)
    moved = _mark_drifted(p, anchor, hbar, local_drift, flag, 0)
    res, log = _flips_logged(p, t32, nbr, con, vt, _rows_using(t32, flag, 0),
                             np.bool_(False))  # a literal False: one more compile
    none_i = np.empty(0, dtype=np.int64)
    none_p = np.empty((0, 2))
    if res < 0:
        return RELINK_INVERTED, none_i, none_i, none_i, none_p, none_i
    nodes = moved
    if res > 0:
        changed, removed, added = flip_diff(log[:, :2].copy().ravel(), log[:, 2:4].copy(),
                                            log[:, 4:6].copy())
        if removed.shape[0] != added.shape[0]:
            return RELINK_REBUILD, none_i, none_i, none_i, none_p, none_i
        ids = flip_update(indptr, adj, eid, bars, removed, added)
        if ids.shape[0] != removed.shape[0]:
            return RELINK_REBUILD, none_i, none_i, none_i, none_p, none_i
        if not np.isnan(constant):
            for r in range(ids.shape[0]):
                ld[ids[r]] = constant
        for r in range(changed.shape[0]):
            t = changed[r]
            tri[t, 0], tri[t, 1], tri[t, 2] = t32[t, 0], t32[t, 1], t32[t, 2]
        nodes = np.unique(np.concatenate((moved, added.ravel())))
    graded = graded and nodes.shape[0] > 0
    near, b, mid_bars = moved_bars(indptr, adj, eid, bars, p, nodes, mark, seen, graded)
    n_sl = slide.shape[0]
    rows_sl = np.empty(n_sl, dtype=np.int64)
    m = 0
    if n_sl and nodes.shape[0]:
        for i in nodes:
            mark[i] = 1
        for r in range(n_sl):
            if mark[slide[r, 0]] or mark[slide[r, 1]] or mark[slide[r, 2]]:
                rows_sl[m] = r
                m += 1
        for i in nodes:
            mark[i] = 0
    rows_sl = rows_sl[:m]
    nb = b.shape[0]
    mid = np.empty((nb + 2 * m, 2))
    mid[:nb] = mid_bars
    _slide_mids(p, slide, rows_sl, mid, nb)
    return RELINK_OK, nodes, near, b, mid, rows_sl


@njit(cache=True, inline="always")
def _slide_mids(p, slide, rows, mid, at):  # type: ignore[no-untyped-def]
    """Into ``mid`` from row ``at``: the midpoints of the bars of the sliding rows ``rows`` to
    their previous boundary node, then those to their next one (as ``_Relaxation`` asks h)."""
    m = rows.shape[0]
    for r in range(m):
        s = rows[r]
        b, bp, bn = slide[s, 0], slide[s, 1], slide[s, 2]
        mid[at + r, 0] = 0.5 * (p[b, 0] + p[bp, 0])
        mid[at + r, 1] = 0.5 * (p[b, 1] + p[bp, 1])
        mid[at + m + r, 0] = 0.5 * (p[b, 0] + p[bn, 0])
        mid[at + m + r, 1] = 0.5 * (p[b, 1] + p[bn, 1])


@njit(cache=True)
def resize(values, b, rows, ld, ld_prev, ld_next, p, nodes, near, indptr, adj, eid, dt, gain,  # type: ignore[no-untyped-def]
           graded, hbar, damp, is_free, anchor, d0, deep_flags, deep, exact, kinds, shapes, origins,
           cat, offs):
    """The rest of the update :func:`relink` began: h's ``values`` at its points become the
    bars' ld and the sliding rows' boundary-bar ld, the ring ``near`` renews hbar and its
    stability limits (:func:`renew_sizes`), the free nodes among ``nodes`` their inside depth
    (:func:`depth_bounds`, the rest asked of boundary 0, the domain's, :func:`mark_deep`),
    and ``nodes`` their anchors."""
    nb = b.shape[0]
    m = rows.shape[0]
    if graded and nodes.shape[0] > 0:
        for r in range(nb):
            ld[b[r]] = values[r]
    for r in range(m):
        ld_prev[rows[r]] = values[nb + r]
        ld_next[rows[r]] = values[nb + m + r]
    renew_sizes(p, near, indptr, adj, eid, ld, dt, gain, graded and nodes.shape[0] > 0, hbar, damp)
    k = 0
    free = np.empty(nodes.shape[0], dtype=np.int64)
    for i in nodes:
        if is_free[i]:
            free[k] = i
            k += 1
    free = free[:k]
    if k:
        _renew_depth(p, anchor, d0, hbar, free, deep, exact, deep_flags, kinds, shapes, origins, cat,
                     offs)
    for i in nodes:
        anchor[i, 0], anchor[i, 1] = p[i, 0], p[i, 1]


#: A boundary node's trial move in the quality pass whose midpoint lies outside the domain by
#: more than this fraction of the move's length is refused (:func:`_keep_off_gaps`).
ACROSS = 0.25


@njit(cache=True)
def _keep_off_gaps(p, move, step, bnd_rows, bnd_target, kinds, shapes, origins, cat, offs):  # type: ignore[no-untyped-def]
    """Put back the trial of each node on the domain's boundary (``bnd_target`` 0) whose move
    crosses outside the domain: its midpoint more than ``ACROSS`` of its length outside.

    Projected onto the nearest boundary point, a node beside a gap narrower than the
    allowance for its boundary's curvature went to the other side of it: a circle's node
    0.0155 (h/6) from the tip of a separate triangle became a second node at the tip (a
    duplicate node; ``fuzz_csg.py`` seed 74352).  A move along the boundary has its midpoint
    inside, or outside by a concave arc's sagitta, ``m**2 / (8 R)`` (a quarter of m when m is
    2 R); across a gap, by about half of it.  The trial is then the node's own position, which
    :func:`star_trial` refuses.
    """
    n_dom = 0
    for k in range(bnd_rows.shape[0]):
        if bnd_target[k] == 0:
            n_dom += 1
    if n_dom == 0:
        return
    mid = np.empty((n_dom, 2))
    rows = np.empty(n_dom, dtype=np.int64)
    j = 0
    for k in range(bnd_rows.shape[0]):
        if bnd_target[k] == 0:
            a = bnd_rows[k]
            i = move[a]
            mid[j, 0] = 0.5 * (p[i, 0] + step[a, 0])
            mid[j, 1] = 0.5 * (p[i, 1] + step[a, 1])
            rows[j] = a
            j += 1
    d = _query_of(mid, kinds, shapes, origins, cat, offs, _DOMAIN_BOUNDARY, np.empty((0, 2)))
    for j in range(n_dom):
        a = rows[j]
        i = move[a]
        moved = math.hypot(step[a, 0] - p[i, 0], step[a, 1] - p[i, 1])
        # (Rounding in d: a move of a few ulps along the boundary is no crossing.)
        scale = max(1.0, abs(p[i, 0]), abs(p[i, 1]))
        if d[j] > ACROSS * moved + 1e-12 * scale:
            step[a, 0], step[a, 1] = p[i, 0], p[i, 1]


@njit(cache=True)
def optimize_trials(p, tri, start, corner, move, target, star, prev_b, next_b, on_bnd, reach,  # type: ignore[no-untyped-def]
                    bnd_target, kinds, shapes, origins, cat, offs):
    """One sweep's line search of ``smoothing._optimize`` on a compiled boundary: the free
    nodes' depth (boundary 0 asked at their positions), then for the step fractions 1, 1/2,
    1/4, 1/8 the trial positions, the sliding ones projected onto their boundaries
    (``bnd_target``, one per sliding row of ``move`` in order), the inside test of the others
    that go further than their depth allows, and :func:`star_trial`; the moves are taken.
    The same calls, on the same points in the same order, as the Python loop.  Returns which
    nodes moved."""
    m = move.shape[0]
    depth = np.zeros(m)
    n_free = 0
    for a in range(m):
        if not on_bnd[a]:
            n_free += 1
    if n_free:
        rows = np.empty(n_free, dtype=np.int64)
        q = np.empty((n_free, 2))
        k = 0
        for a in range(m):
            if not on_bnd[a]:
                rows[k] = a
                q[k, 0], q[k, 1] = p[move[a], 0], p[move[a], 1]
                k += 1
        d = _query_of(q, kinds, shapes, origins, cat, offs, _DOMAIN_BOUNDARY, np.empty((0, 2)))
        for k in range(n_free):
            depth[rows[k]] = -reach * d[k]
    n_bnd = m - n_free
    bnd_rows = np.flatnonzero(on_bnd).astype(np.int64)
    done = np.zeros(m, dtype=np.bool_)
    step = np.empty((m, 2))
    inside = np.empty(m, dtype=np.bool_)
    bq = np.empty((n_bnd, 2))
    bf = np.empty((n_bnd, 2))
    for frac in (1.0, 0.5, 0.25, 0.125):
        for a in range(m):
            i = move[a]
            step[a, 0] = p[i, 0] + frac * (target[a, 0] - p[i, 0])
            step[a, 1] = p[i, 1] + frac * (target[a, 1] - p[i, 1])
        if n_bnd:
            for k in range(n_bnd):
                bq[k, 0], bq[k, 1] = step[bnd_rows[k], 0], step[bnd_rows[k], 1]
            project_rows(bnd_target, kinds, shapes, origins, cat, offs, bq, bf)
            for k in range(n_bnd):
                step[bnd_rows[k], 0], step[bnd_rows[k], 1] = bf[k, 0], bf[k, 1]
            _keep_off_gaps(p, move, step, bnd_rows, bnd_target, kinds, shapes, origins, cat, offs)
        n_ask = 0
        for a in range(m):
            i = move[a]
            inside[a] = math.hypot(step[a, 0] - p[i, 0], step[a, 1] - p[i, 1]) < depth[a]
            if not inside[a] and not on_bnd[a] and not done[a]:
                n_ask += 1
        if n_ask:
            ask = np.empty(n_ask, dtype=np.int64)
            q = np.empty((n_ask, 2))
            k = 0
            for a in range(m):
                if not inside[a] and not on_bnd[a] and not done[a]:
                    ask[k] = a
                    q[k, 0], q[k, 1] = step[a, 0], step[a, 1]
                    k += 1
            d = _query_of(q, kinds, shapes, origins, cat, offs, _DOMAIN_BOUNDARY, np.empty((0, 2)))
            for k in range(n_ask):
                inside[ask[k]] = d[k] < 0.0
        ok = star_trial(p, tri, start, corner, move, step, star, prev_b, next_b, on_bnd, inside, done)
        for a in range(m):
            if ok[a]:
                i = move[a]
                p[i, 0], p[i, 1] = step[a, 0], step[a, 1]
                done[a] = True
    return done


# --- a relaxation's first connectivity in two calls (smoothing._Relaxation._connect) ----------
# Every repair round makes a relaxation of its patch: its set-up (node lists, bars, their
# midpoints, hbar, stability limits, inside depth) was ~15 NumPy lines and kernel calls around
# the call of h.  :func:`connect_bars` and :func:`connect_rest` make it in two calls, with the
# same numbers.


@njit(cache=True)
def connect_bars(p, t32, slack, slide, graded):  # type: ignore[no-untyped-def]
    """The node lists of the triangles ``t32`` (:func:`adjacency` with ``slack``), the
    triangles as int64, and with ``graded`` the points where h gives the desired lengths: the
    bars' midpoints, then those of the sliding rows' bars to their previous and to their next
    boundary node.  Returns ``(tri, indptr, adj, eid, bars, mid)``."""
    indptr, adj, eid, bars = adjacency(p.shape[0], t32, slack)
    tri = t32.astype(np.int64)
    nb = bars.shape[0]
    m = slide.shape[0] if graded else 0
    mid = np.empty((nb + 2 * m, 2) if graded else (0, 2))
    if graded:
        for r in range(nb):
            i, j = bars[r, 0], bars[r, 1]
            mid[r, 0] = 0.5 * (p[i, 0] + p[j, 0])
            mid[r, 1] = 0.5 * (p[i, 1] + p[j, 1])
        _slide_mids(p, slide, np.arange(m), mid, nb)
    return tri, indptr, adj, eid, bars, mid


@njit(cache=True)
def connect_rest(p, moving, free, indptr, adj, eid, ld, hbar, dt, gain, anchor, d0, deep_flags,  # type: ignore[no-untyped-def]
                 deep, exact, kinds, shapes, origins, cat, offs):
    """After h gave ``ld`` and hbar: the stability limits of the ``moving`` nodes
    (:func:`stable_scale` with step ``dt * hbar``; 1 for the others), the inside depth of the
    ``free`` nodes (:func:`depth_bounds` from their anchors, the rest asked of boundary 0,
    :func:`mark_deep`) and the anchors at the positions.  Returns the limits."""
    damp = np.ones(p.shape[0])
    stable_scale(p, moving, indptr, adj, eid, ld, dt * hbar, gain, damp)
    if free.shape[0]:
        _renew_depth(p, anchor, d0, hbar, free, deep, exact, deep_flags, kinds, shapes, origins, cat,
                     offs)
    for i in range(p.shape[0]):
        anchor[i, 0], anchor[i, 1] = p[i, 0], p[i, 1]
    return damp


@njit(cache=True)
def moving_nodes(n, n_fixed, active, slide):  # type: ignore[no-untyped-def]
    """A relaxation's moving nodes (``smoothing._Relaxation``): the free nodes (``>= n_fixed``)
    flagged in ``active`` (all of them when ``active`` is empty), the sliding rows ``slide``
    whose node is flagged, the free nodes then those rows' nodes, and a mask of the free ones.
    Returns ``(free, slide, moving, is_free)``."""
    every = active.shape[0] == 0
    nf = 0
    for v in range(n_fixed, n):
        if every or active[v]:
            nf += 1
    ns = 0
    for r in range(slide.shape[0]):
        if every or active[slide[r, 0]]:
            ns += 1
    free = np.empty(nf, dtype=np.int64)
    is_free = np.zeros(n, dtype=np.bool_)
    a = 0
    for v in range(n_fixed, n):
        if every or active[v]:
            free[a] = v
            is_free[v] = True
            a += 1
    sl = np.empty((ns, 3), dtype=np.int64)
    moving = np.empty(nf + ns, dtype=np.int64)
    moving[:nf] = free
    a = 0
    for r in range(slide.shape[0]):
        if every or active[slide[r, 0]]:
            sl[a, 0], sl[a, 1], sl[a, 2] = slide[r, 0], slide[r, 1], slide[r, 2]
            moving[nf + a] = slide[r, 0]
            a += 1
    return free, sl, moving, is_free


@njit(cache=True)
def vertex_rows(t32, n):  # type: ignore[no-untyped-def]
    """For each of ``n`` nodes, the last row of ``t32`` that holds it (-1: none), int32: the
    flip kernels' vertex-to-triangle map."""
    vt = np.full(n, -1, dtype=np.int32)
    for r in range(t32.shape[0]):
        for k in range(3):
            vt[t32[r, k]] = r
    return vt


@njit(cache=True)
def _renew_depth(p, anchor, d0, hbar, free, deep, exact, deep_flags, kinds, shapes, origins, cat,  # type: ignore[no-untyped-def]
                 offs):
    """``smoothing._Relaxation._inside_depth`` of the free nodes ``free``: :func:`depth_bounds`
    from their anchors, the rest asked of the domain's boundary (boundary 0), then
    :func:`mark_deep`."""
    ask = depth_bounds(p, anchor, d0, hbar, free, deep, exact)
    if ask.shape[0]:
        q = np.empty((ask.shape[0], 2))
        for r in range(ask.shape[0]):
            q[r, 0], q[r, 1] = p[ask[r], 0], p[ask[r], 1]
        d = _query_of(q, kinds, shapes, origins, cat, offs, _DOMAIN_BOUNDARY, np.empty((0, 2)))
        for r in range(ask.shape[0]):
            d0[ask[r]] = d[r]
    mark_deep(d0, hbar, free, deep, deep_flags)
