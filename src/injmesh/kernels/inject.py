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
        for j in range(cj - k, cj + k + 1):
            if j < 0 or j >= ny:
                continue
            on_edge = j == cj - k or j == cj + k
            step = 1 if on_edge else 2 * k
            i = ci - k
            while i <= ci + k:
                if 0 <= i < nx:
                    n = head[j * nx + i]
                    while n >= 0:
                        if n < stop:
                            dx = pts[n, 0] - qx
                            dy = pts[n, 1] - qy
                            d2 = dx * dx + dy * dy
                            if d2 < best2:
                                best2 = d2
                                who = n
                        n = link[n]
                if k == 0:
                    break
                i += step
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
