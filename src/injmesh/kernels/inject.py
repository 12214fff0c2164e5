"""Proximity tests of Advancing Node Injection on a background grid (:mod:`injmesh.injection`).

The nodes placed so far live in a uniform grid of square cells (a spatial hash without hashing:
the cell of a point is ``(floor((x - x0) / cell), floor((y - y0) / cell))``, clamped to the
grid).  Each cell holds a singly linked list of its nodes (``head[cell]`` is the last node put
there, ``link[node]`` the one before), so a layer of new nodes is inserted in time linear in
the layer, with no rebuild of anything: the whole injection costs O(n) insertions where a k-d
tree rebuilt per layer costs O(n) per layer.

Queries visit the cells in square rings around the query point and stop as soon as the ring is
farther than the answer can be: the nearest node is found exactly (ring k lies at least
``(k - 1) * cell`` away).  The boundary segments are in a second, static structure on the same
cells (each segment listed in every cell its bounding box touches, compressed rows).

Every function is deterministic: cells and lists are visited in a fixed order and ties in the
nearest-node search go to the node met first.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .raster import ring_cell


@numba.njit(cache=True, inline="always")
def _cell_of(x: float, y: float, x0: float, y0: float, inv: float, nx: int, ny: int) -> tuple[int, int]:
    """Column and row of the cell holding ``(x, y)``, clamped to the grid."""
    i = int(math.floor((x - x0) * inv))
    j = int(math.floor((y - y0) * inv))
    i = min(max(i, 0), nx - 1)
    j = min(max(j, 0), ny - 1)
    return i, j


@numba.njit(cache=True)
def insert(pts: np.ndarray, start: int, stop: int, head: np.ndarray, link: np.ndarray,
           x0: float, y0: float, inv: float, nx: int, ny: int) -> None:
    """Put nodes ``start:stop`` of ``pts`` into the lists of their cells."""
    for k in range(start, stop):
        i, j = _cell_of(pts[k, 0], pts[k, 1], x0, y0, inv, nx, ny)
        c = j * nx + i
        link[k] = head[c]
        head[c] = k


@numba.njit(cache=True)
def nearest(qx: float, qy: float, reach: float, pts: np.ndarray, stop: int, head: np.ndarray,
            link: np.ndarray, x0: float, y0: float, cell: float, nx: int, ny: int) -> tuple[float, int]:
    """Distance to the nearest node numbered below ``stop`` and that node, if within ``reach``.

    Returns ``(inf, -1)`` when no such node lies within ``reach``.
    """
    inv = 1.0 / cell
    ci, cj = _cell_of(qx, qy, x0, y0, inv, nx, ny)
    best2 = np.inf
    who = -1
    k = 0
    kmax = max(nx, ny)
    while k <= kmax:
        if k > 0:
            gap = (k - 1) * cell
            if gap >= reach or gap * gap >= best2:
                break
        for t in range(8 * k if k > 0 else 1):
            c = ring_cell(ci, cj, k, t, nx, ny)
            n = head[c] if c >= 0 else -1
            while n >= 0:
                if n < stop:
                    dx = pts[n, 0] - qx
                    dy = pts[n, 1] - qy
                    d2 = dx * dx + dy * dy
                    if d2 < best2:
                        best2 = d2
                        who = n
                n = link[n]
        k += 1
    if who < 0 or best2 >= reach * reach:
        return np.inf, -1
    return math.sqrt(best2), who


@numba.njit(cache=True)
def segment_lists(a: np.ndarray, b: np.ndarray, x0: float, y0: float, cell: float, nx: int,
                  ny: int) -> tuple[np.ndarray, np.ndarray]:
    """Compressed rows: the segments ``a[s] -> b[s]`` whose bounding box touches each cell."""
    inv = 1.0 / cell
    m = a.shape[0]
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for c in range(nx * ny):
                count[c + 1] += count[c]
            items = np.empty(count[nx * ny], dtype=np.int64)
            fill = count[:-1].copy()
        for s in range(m):
            i0, j0 = _cell_of(min(a[s, 0], b[s, 0]), min(a[s, 1], b[s, 1]), x0, y0, inv, nx, ny)
            i1, j1 = _cell_of(max(a[s, 0], b[s, 0]), max(a[s, 1], b[s, 1]), x0, y0, inv, nx, ny)
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    c = j * nx + i
                    if pass_ == 0:
                        count[c + 1] += 1
                    else:
                        items[fill[c]] = s
                        fill[c] += 1
    return count, items


@numba.njit(cache=True)
def _clear_of_walls(qx: float, qy: float, r: float, a: np.ndarray, b: np.ndarray, rows: np.ndarray,
                    items: np.ndarray, x0: float, y0: float, cell: float, nx: int, ny: int) -> bool:
    """No boundary segment passes closer than ``r`` to ``(qx, qy)``."""
    inv = 1.0 / cell
    i0, j0 = _cell_of(qx - r, qy - r, x0, y0, inv, nx, ny)
    i1, j1 = _cell_of(qx + r, qy + r, x0, y0, inv, nx, ny)
    r2 = r * r
    for j in range(j0, j1 + 1):
        for i in range(i0, i1 + 1):
            c = j * nx + i
            for t in range(rows[c], rows[c + 1]):
                s = items[t]
                ax, ay = a[s, 0], a[s, 1]
                ex, ey = b[s, 0] - ax, b[s, 1] - ay
                px, py = qx - ax, qy - ay
                e2 = ex * ex + ey * ey
                u = 0.0
                if e2 > 0.0:
                    u = min(max((px * ex + py * ey) / e2, 0.0), 1.0)
                dx, dy = px - u * ex, py - u * ey
                if dx * dx + dy * dy < r2:
                    return False
    return True


@numba.njit(cache=True)
def admit(q: np.ndarray, hq: np.ndarray, keep: np.ndarray, merge: float, clearance: float,
          pts: np.ndarray, hs: np.ndarray, n_old: int, h_max: float, head: np.ndarray,
          link: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, rows: np.ndarray, items: np.ndarray,
          x0: float, y0: float, cell: float, nx: int, ny: int) -> int:
    """Decide the candidates ``q`` of one layer and insert the survivors (Step 3 of injection).

    A candidate with ``keep`` already False (outside the domain) stays out.  Otherwise it is
    refused when a boundary segment is closer than ``clearance * hq``, when the nearest of the
    ``n_old`` nodes placed before this layer is closer than ``merge * (hq + h_node) / 2``, or when
    a survivor of this layer numbered lower is closer than ``merge * (hq + h_other) / 2``
    (greedy in candidate order).  Survivors are appended to ``pts``/``hs`` from ``n_old`` on and
    inserted into the grid; ``keep`` is updated in place.

    Returns
    -------
    int
        The number of nodes in ``pts`` afterwards.
    """
    inv = 1.0 / cell
    m = q.shape[0]
    # Existing nodes and walls first, for every candidate: survivors of this layer must not
    # shadow the old nodes in the nearest-node search.
    for t in range(m):
        if not keep[t]:
            continue
        qx, qy, h = q[t, 0], q[t, 1], hq[t]
        if not _clear_of_walls(qx, qy, clearance * h, seg_a, seg_b, rows, items, x0, y0, cell, nx, ny):
            keep[t] = False
            continue
        d, n = nearest(qx, qy, merge * 0.5 * (h + h_max), pts, n_old, head, link, x0, y0, cell, nx, ny)
        if n >= 0 and d < merge * 0.5 * (h + hs[n]):
            keep[t] = False
    # Lower-numbered survivors of the same layer win, in candidate order.
    layer_max = 0.0
    for t in range(m):
        if keep[t]:
            layer_max = max(layer_max, hq[t])
    n_now = n_old
    for t in range(m):
        if not keep[t]:
            continue
        qx, qy, h = q[t, 0], q[t, 1], hq[t]
        reach = merge * 0.5 * (h + layer_max)
        i0, j0 = _cell_of(qx - reach, qy - reach, x0, y0, inv, nx, ny)
        i1, j1 = _cell_of(qx + reach, qy + reach, x0, y0, inv, nx, ny)
        ok = True
        for j in range(j0, j1 + 1):
            if not ok:
                break
            for i in range(i0, i1 + 1):
                n = head[j * nx + i]
                while n >= n_old:  # this layer's nodes head every list
                    dx, dy = pts[n, 0] - qx, pts[n, 1] - qy
                    lim = merge * 0.5 * (h + hs[n])
                    if dx * dx + dy * dy < lim * lim:
                        ok = False
                        break
                    n = link[n]
                if not ok:
                    break
        if not ok:
            keep[t] = False
            continue
        pts[n_now, 0], pts[n_now, 1] = qx, qy
        hs[n_now] = h
        insert(pts, n_now, n_now + 1, head, link, x0, y0, inv, nx, ny)
        n_now += 1
    return n_now


@numba.njit(cache=True)
def survivors(points: np.ndarray, start: np.ndarray, closed: np.ndarray,
              keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of consecutive kept points of each chain, as new chains (injection's step 4).

    Chain ``c`` is ``points[start[c]:start[c + 1]]``; a closed chain that lost a point is read
    from just after its first lost point, so that no run wraps around its start.  A chain that
    lost nothing stays one chain, closed if it was.

    Returns the kept points in run order ``(k, 2)``, the length of each run and whether it is
    closed.
    """
    n_chain = start.shape[0] - 1
    out = np.empty((points.shape[0], 2))
    lengths = np.empty(points.shape[0], dtype=np.int64)
    is_closed = np.empty(points.shape[0], dtype=np.bool_)
    n_out = 0
    n_run = 0
    for c in range(n_chain):
        s, e = start[c], start[c + 1]
        size = e - s
        if size == 0:
            continue
        first_lost = -1
        for k in range(s, e):
            if not keep[k]:
                first_lost = k
                break
        if first_lost < 0:
            for k in range(s, e):
                out[n_out, 0], out[n_out, 1] = points[k, 0], points[k, 1]
                n_out += 1
            lengths[n_run] = size
            is_closed[n_run] = closed[c]
            n_run += 1
            continue
        rot = first_lost - s + 1 if closed[c] else 0
        in_run = False
        for p in range(size):
            k = s + (p + rot) % size
            if keep[k]:
                if not in_run:
                    lengths[n_run] = 0
                    is_closed[n_run] = False
                    n_run += 1
                    in_run = True
                out[n_out, 0], out[n_out, 1] = points[k, 0], points[k, 1]
                n_out += 1
                lengths[n_run - 1] += 1
            else:
                in_run = False
    return out[:n_out], lengths[:n_run], is_closed[:n_run]


@numba.njit(cache=True)
def front_edges(points: np.ndarray, start: np.ndarray, closed: np.ndarray,
                fan_step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Edges of the front and the arcs at its reflex vertices (injection's step 1, geometry).

    Edge ``e`` joins front node ``first[e]`` to its successor in the chain (closed chains wrap).
    At a node with an incoming and an outgoing edge whose interior angle theta (on the left)
    exceeds 180 degrees, ``m = round((theta - 120) / fan_step) - 1`` arc points are placed.

    Returns
    -------
    first : (k,) int
        The node each edge starts from, increasing.
    mid, normal : (k, 2)
        Edge midpoints and unit left normals (towards the unmeshed side).
    fan_node : (f,) int
        The node of each arc point, increasing, each repeated m times.
    fan_angle : (f,)
        Direction of each arc point from its node, radians.
    """
    n = points.shape[0]
    n_chain = start.shape[0] - 1
    succ = np.full(n, -1, dtype=np.int64)
    for c in range(n_chain):
        s, e = start[c], start[c + 1]
        for k in range(s, e - 1):
            succ[k] = k + 1
        if closed[c] and e > s:
            succ[e - 1] = s
    n_edge = 0
    for k in range(n):
        if succ[k] >= 0:
            n_edge += 1
    first = np.empty(n_edge, dtype=np.int64)
    tan = np.empty((n_edge, 2))
    mid = np.empty((n_edge, 2))
    normal = np.empty((n_edge, 2))
    out_edge = np.full(n, -1, dtype=np.int64)
    in_edge = np.full(n, -1, dtype=np.int64)
    e = 0
    for k in range(n):
        j = succ[k]
        if j < 0:
            continue
        first[e] = k
        tx, ty = points[j, 0] - points[k, 0], points[j, 1] - points[k, 1]
        length = max(math.hypot(tx, ty), 1e-300)
        tx, ty = tx / length, ty / length
        tan[e, 0], tan[e, 1] = tx, ty
        normal[e, 0], normal[e, 1] = -ty, tx
        mid[e, 0] = 0.5 * (points[k, 0] + points[j, 0])
        mid[e, 1] = 0.5 * (points[k, 1] + points[j, 1])
        out_edge[k] = e
        in_edge[j] = e
        e += 1
    # Reflex nodes: the interior angle on the left is 180 minus the signed turn.
    m = np.zeros(n, dtype=np.int64)
    theta = np.zeros(n)
    total = 0
    for k in range(n):
        ei, eo = in_edge[k], out_edge[k]
        if ei < 0 or eo < 0:
            continue
        cross = tan[ei, 0] * tan[eo, 1] - tan[ei, 1] * tan[eo, 0]
        dot = tan[ei, 0] * tan[eo, 0] + tan[ei, 1] * tan[eo, 1]
        theta[k] = 180.0 - np.degrees(math.atan2(cross, dot))
        m[k] = max(int(math.floor((theta[k] - 120.0) / fan_step + 0.5)) - 1, 0)
        total += m[k]
    fan_node = np.empty(total, dtype=np.int64)
    fan_angle = np.empty(total)
    f = 0
    for k in range(n):
        if m[k] == 0:
            continue
        # From the incoming apex direction (normal of the incoming edge turned back by 30
        # degrees) to the outgoing one, through the interior, in m + 1 equal steps.
        ei = in_edge[k]
        start_ang = math.atan2(normal[ei, 1], normal[ei, 0]) + np.radians(30.0)
        sweep = np.radians(theta[k] - 120.0)
        for q in range(1, m[k] + 1):
            fan_node[f] = k
            fan_angle[f] = start_ang - q / (m[k] + 1) * sweep
            f += 1
    return first, mid, normal, fan_node, fan_angle


@numba.njit(cache=True)
def interleave(chain: np.ndarray, n_chain: int, first: np.ndarray, apex: np.ndarray,
               fan_node: np.ndarray, fan: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The new chains: for each front node in order, its arc points, then its edge's apex.

    ``chain`` gives each front node's chain (non-decreasing); returns the points ``(k, 2)`` and
    the number of them per chain.
    """
    out = np.empty((apex.shape[0] + fan.shape[0], 2))
    lengths = np.zeros(n_chain, dtype=np.int64)
    o = 0
    f = 0
    e = 0
    n = chain.shape[0]
    for k in range(n):
        while f < fan_node.shape[0] and fan_node[f] == k:
            out[o, 0], out[o, 1] = fan[f, 0], fan[f, 1]
            o += 1
            f += 1
            lengths[chain[k]] += 1
        if e < first.shape[0] and first[e] == k:
            out[o, 0], out[o, 1] = apex[e, 0], apex[e, 1]
            o += 1
            e += 1
            lengths[chain[k]] += 1
    return out, lengths


@numba.njit(cache=True)
def chain_polylines(points: np.ndarray, start: np.ndarray,
                    closed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All chains as one vertex list, a closed chain's first node repeated after its last.

    Returns the vertices ``(v, 2)`` and the chain of each.
    """
    n_chain = start.shape[0] - 1
    n = points.shape[0]
    extra = 0
    for c in range(n_chain):
        if closed[c] and start[c + 1] > start[c]:
            extra += 1
    poly = np.empty((n + extra, 2))
    pchain = np.empty(n + extra, dtype=np.int64)
    o = 0
    for c in range(n_chain):
        s, e = start[c], start[c + 1]
        for k in range(s, e):
            poly[o, 0], poly[o, 1] = points[k, 0], points[k, 1]
            pchain[o] = c
            o += 1
        if closed[c] and e > s:
            poly[o, 0], poly[o, 1] = points[s, 0], points[s, 1]
            pchain[o] = c
            o += 1
    return poly, pchain


#: Fewest segments in a window of :func:`relay`.
MIN_WINDOW = 4
#: :func:`relay` lays a chain with windows only where no step along it is shorter than this
#: (in h): shorter ones are apexes crowding at a corner or inside a crack's bend, which the
#: merge test, not a window, should thin (of 4000 fuzzed cases 27 got a better q_min, by up to
#: 0.06, and 15 a worse one, by up to 0.14; windowed there too, 43 and 36, down to 0.15).
RING_SHORTEST = 0.5


@numba.njit(cache=True)
def _uncrowded(ds, f, n_in):  # type: ignore[no-untyped-def]
    """Whether every step ``ds[f:f + n_in]`` of a chain is at least ``RING_SHORTEST``."""
    for i in range(n_in):
        if ds[f + i] < RING_SHORTEST:
            return False
    return True


@numba.njit(cache=True)
def _windowed(s, f, n_in, m, total, base, window, target, o):  # type: ignore[no-untyped-def]
    """A closed chain's ``m`` new abscissae written at ``target[o:]``, keeping its ``n_in``
    vertices (abscissae ``s[f:f + n_in + 1]``, the first repeated at the end) and taking up the
    points gained or lost in windows of ``window`` segments re-laid at equal spacing.

    Vertex i lies at ``(s_i - s_f) * m / total`` in the uniform layout; kept, it is number
    ``i + done`` (``done``: points gained so far).  Their difference, the slip, runs from 0 to
    ``m - n_in``.  A window opens at vertex i when the slip at its far end rounds to another
    value than ``done``, and takes up the difference (at most half its segments): the slip is
    taken up where it builds (evenly round a ring, at the crowded ends of a crack's loop).
    Returns the number of abscissae written, which is ``m`` unless the windows could not take
    the slip up (then the caller lays the chain uniformly)."""
    k = 0
    done = 0
    i = 0
    cap = target.shape[0] - o
    while i < n_in:
        span = min(window, n_in - i)
        ahead = int(np.rint((s[f + i + span] - s[f]) * m / total - (i + span))) - done
        if ahead != 0:
            # At most half the window's points at once (a crowded end takes up several).
            ahead = max(min(ahead, span // 2), -(span // 2))
            pts = span + ahead  # at least 1: |ahead| <= span // 2
            if k + pts > cap:
                return -1
            sa, sb = s[f + i], s[f + i + span]
            for q in range(pts):
                target[o + k] = sa + q * (sb - sa) / pts + base
                k += 1
            done += ahead
            i += span
        else:
            if k + 1 > cap:
                return -1
            target[o + k] = s[f + i] + base
            k += 1
            i += 1
    return k


@numba.njit(cache=True)
def relay(poly: np.ndarray, pchain: np.ndarray, ds: np.ndarray, closed: np.ndarray, points: np.ndarray,
          start: np.ndarray, window: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each chain re-laid at equal h-length (injection's step 2), given the h-length ``ds`` of
    every step between consecutive vertices of :func:`chain_polylines` (0 across chains).

    A chain of h-length S gets ``round(S)`` segments (open: ``round(S) + 1`` points; closed: at
    least three); a closed chain shorter than 2.5 collapses to its centroid.  One increasing
    abscissa runs over all chains (each offset by its predecessors' lengths plus one), as the
    interpolation is done in one call.

    With ``window > 0`` a closed chain whose count changes by d keeps its vertices and takes
    the d points up in windows of at most ``window`` segments (:func:`_windowed`), when at
    least ``MIN_WINDOW`` segments fit in each of ``2 (|d| + 1)`` windows and no step is shorter
    than ``RING_SHORTEST``; otherwise, and for open chains, it is laid uniformly.  The vertices
    of a ring's injected layer are the apexes over the edges of the layer before, in step with
    it; laid uniformly with d more points, the new layer slips out of step by d spacings, a
    little at every vertex.

    Returns the new points, their count per chain and which chains stay closed.
    """
    n_chain = closed.shape[0]
    nv = poly.shape[0]
    s = np.empty(nv)
    s[0] = 0.0
    acc = 0.0
    for i in range(nv - 1):
        acc += ds[i]
        s[i + 1] = acc
    first = np.empty(n_chain, dtype=np.int64)
    last = np.empty(n_chain, dtype=np.int64)
    for i in range(nv):
        c = pchain[i]
        if i == 0 or pchain[i - 1] != c:
            first[c] = i
        last[c] = i
    total = np.empty(n_chain)
    count = np.empty(n_chain, dtype=np.int64)
    collapse = np.zeros(n_chain, dtype=np.bool_)
    for c in range(n_chain):
        total[c] = s[last[c]] - s[first[c]]
        r = np.rint(total[c])
        k = int(r) if closed[c] else int(r + 1)
        k = max(k, 1)
        if closed[c] and total[c] < 2.5:
            collapse[c] = True
            k = 1
        elif closed[c]:
            k = max(k, 3)
        count[c] = k
    offset = np.empty(n_chain)
    acc = 0.0
    for c in range(n_chain):
        offset[c] = acc
        acc += total[c] + 1.0
    gs = np.empty(nv)
    for i in range(nv):
        c = pchain[i]
        gs[i] = s[i] - s[first[c]] + offset[c]
    n_out = 0
    for c in range(n_chain):
        n_out += count[c]
    target = np.empty(n_out)
    piece = np.empty(n_out, dtype=np.int64)
    o = 0
    for c in range(n_chain):
        n_in = last[c] - first[c]
        d = count[c] - n_in
        span = min(window, n_in // (2 * (abs(d) + 1)))
        if closed[c] and not collapse[c] and d != 0 and span >= MIN_WINDOW and _uncrowded(ds, first[c], n_in):
            k_out = _windowed(s, first[c], n_in, count[c], total[c], offset[c] - s[first[c]], span,
                              target, o)
            if k_out == count[c]:
                for q in range(o, o + k_out):
                    piece[q] = c
                o += k_out
                continue
        denom = count[c] if closed[c] else max(count[c] - 1, 1)
        for k in range(count[c]):
            target[o] = offset[c] + k * total[c] / denom
            piece[o] = c
            o += 1
    out = np.empty((n_out, 2))
    out[:, 0] = np.interp(target, gs, poly[:, 0])
    out[:, 1] = np.interp(target, gs, poly[:, 1])
    for o in range(n_out):
        c = piece[o]
        if collapse[c]:
            cx, cy = 0.0, 0.0
            for k in range(start[c], start[c + 1]):
                cx += points[k, 0]
                cy += points[k, 1]
            size = max(start[c + 1] - start[c], 1)
            out[o, 0], out[o, 1] = cx / size, cy / size
    stays = np.empty(n_chain, dtype=np.bool_)
    for c in range(n_chain):
        stays[c] = closed[c] and not collapse[c]
    return out, count, stays


@numba.njit(cache=True)
def nearest_occupied_below(occupied: np.ndarray, cell_h: np.ndarray, cj: np.ndarray, ci: np.ndarray,
                           limit: float, max_radius: int) -> tuple[np.ndarray, np.ndarray]:
    """Whether the nearest occupied cell of each cell ``(cj[k], ci[k])`` has ``cell_h`` below
    ``limit`` (gap filling's test, :func:`injmesh.injection._fill_gaps`).

    Nearest is by Euclidean distance between cell indices, as a distance transform of the
    occupied cells gives it.  Square rings of cells are searched outwards: once the nearest
    occupied cell found is at squared distance ``D <= r^2`` after ring r, every cell beyond
    is farther, and every cell at distance ``D`` has been seen.  Where several occupied cells
    are nearest, the answer stands only if they all agree (a distance transform picks one of
    them by its own order of work).

    Returns
    -------
    below, settled : (k,) bool arrays
        ``below`` holds only where ``settled``: not where no occupied cell lies within
        ``max_radius`` rings, nor where the nearest occupied cells disagree.
    """
    ny, nx = occupied.shape
    k = cj.shape[0]
    below = np.zeros(k, dtype=np.bool_)
    settled = np.zeros(k, dtype=np.bool_)
    for t in range(k):
        j0, i0 = cj[t], ci[t]
        best = -1
        verdict = False
        tied = False
        for r in range(max_radius + 1):
            for j in range(max(j0 - r, 0), min(j0 + r, ny - 1) + 1):
                dj = j - j0
                whole_row = dj == -r or dj == r
                i = max(i0 - r, 0)
                while i <= min(i0 + r, nx - 1):
                    if occupied[j, i]:
                        di = i - i0
                        d = dj * dj + di * di
                        v = cell_h[j, i] < limit
                        if best < 0 or d < best:
                            best, verdict, tied = d, v, False
                        elif d == best and v != verdict:
                            tied = True
                    # Inner rows of the ring: only its two ends (a cell seen again changes nothing).
                    i = i + 1 if whole_row or i >= i0 + r else i0 + r
            if 0 <= best <= r * r:
                settled[t] = not tied
                below[t] = verdict
                break
    return below, settled


@numba.njit(cache=True)
def fill_census(pts: np.ndarray, hs: np.ndarray, x0: float, y0: float, s: float, nx: int, ny: int,
                outside: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """One level of gap filling's cells (:func:`injmesh.injection._fill_gaps`), in two passes.

    Cell ``(j, i)`` of side s holds the points with ``floor((x - x0) / s) == i`` and
    ``floor((y - y0) / s) == j``.  A cell is *deep* when it and its eight neighbours hold no
    point (cells beyond the grid hold none); the cells to offer are the empty ones, not
    ``outside``, next to (or being) a deep one.

    Returns
    -------
    occupied : (ny, nx) bool array
    cells : (ny, nx) bool array
        The cells to offer.
    cell_h : (ny, nx) float array
        ``hs`` of the last point in each occupied cell, 0 elsewhere.
    n_deep : int
        How many cells are deep.
    n_near : int
        How many cells to offer are not deep (touch an occupied cell).
    """
    # One cell of margin all round; 3 x 3 neighbourhoods as a pass along rows, then columns.
    occ = np.zeros((ny + 2, nx + 2), dtype=np.uint8)
    cell_h = np.zeros((ny, nx))
    for k in range(pts.shape[0]):
        fx = math.floor((pts[k, 0] - x0) / s)
        fy = math.floor((pts[k, 1] - y0) / s)
        if 0.0 <= fx < nx and 0.0 <= fy < ny:
            occ[int(fy) + 1, int(fx) + 1] = 1
            cell_h[int(fy), int(fx)] = hs[k]
    rows = np.zeros((ny + 2, nx), dtype=np.uint8)
    for j in range(ny + 2):
        for i in range(nx):
            rows[j, i] = occ[j, i] | occ[j, i + 1] | occ[j, i + 2]
    deep = np.zeros((ny + 2, nx + 2), dtype=np.uint8)
    n_deep = 0
    for j in range(ny):
        for i in range(nx):
            e = 1 - (rows[j, i] | rows[j + 1, i] | rows[j + 2, i])
            deep[j + 1, i + 1] = e
            n_deep += e
    occupied = np.zeros((ny, nx), dtype=np.bool_)
    for j in range(ny):
        for i in range(nx):
            occupied[j, i] = occ[j + 1, i + 1] != 0
    cells = np.zeros((ny, nx), dtype=np.bool_)
    if n_deep == 0:
        return occupied, cells, cell_h, 0, 0
    for j in range(ny + 2):
        for i in range(nx):
            rows[j, i] = deep[j, i] | deep[j, i + 1] | deep[j, i + 2]
    n_near = 0
    for j in range(ny):
        for i in range(nx):
            c = (rows[j, i] | rows[j + 1, i] | rows[j + 2, i]) & (1 - occ[j + 1, i + 1])
            if c and not outside[j, i]:
                cells[j, i] = True
                n_near += 1 - deep[j + 1, i + 1]
    return occupied, cells, cell_h, n_deep, n_near
