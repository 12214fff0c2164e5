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


@nb.njit(cache=True)
def cell_grid(v, size):  # type: ignore[no-untyped-def]
    """A uniform grid of cells ``size`` wide over points ``v (n, 2)``:
    ``x0, y0, nx, ny, order, first`` (the points of cell c are ``order[first[c]:first[c + 1]]``,
    cell c = row * nx + column)."""
    _, order, first, nx, ny = _cells(v, size)
    return v[:, 0].min(), v[:, 1].min(), nx, ny, order, first


@nb.njit(cache=True)
def corner_cones(p, hp, corners, spacing, rate, k, s_min, grid, size,  # type: ignore[no-untyped-def]
                 empty_rings):
    """``min(hp, min_c (spacing[c] + rate |p - c|))`` over the ``k`` corners c nearest to each
    point of ``p (n, 2)``.

    The corners are searched on ``grid`` (:func:`cell_grid` of the corners, cells ``size``
    wide) ring of cells by ring of cells, from the point's cell outwards, until the ring is
    farther than the k-th nearest corner found so far or than ``(hp - s_min) / rate`` (no
    farther corner can lower hp: ``s_min`` is the smallest spacing).  ``empty_rings[c]`` is the
    number of rings around cell c that hold no corner (its chessboard distance in cells to the
    nearest cell that does): the search starts beyond them.  Distances are
    ``sqrt(dx * dx + dy * dy)``; of corners at exactly the same distance the one listed first
    counts first.
    """
    x0, y0, nx, ny, order, first = grid
    n = p.shape[0]
    out = np.empty(n)
    best_d2 = np.empty(max(k, 1))
    best_c = np.empty(max(k, 1), dtype=np.int64)
    big = 2.0 ** 40
    for i in range(n):
        x, y = p[i, 0], p[i, 1]
        out[i] = hp[i]
        reach = (hp[i] - s_min) / rate
        if not (math.isfinite(x) and math.isfinite(y)) or k < 1 or not reach > 0.0:
            continue
        r2_reach = reach * reach
        cx = int(math.floor(min(max((x - x0) / size, -big), big)))
        cy = int(math.floor(min(max((y - y0) / size, -big), big)))
        # Rings from the first that meets the grid to the one holding its farthest cell.
        r0 = max(0, -cx, cx - (nx - 1), -cy, cy - (ny - 1))
        if r0 == 0:
            r0 = empty_rings[cy * nx + cx]
        last = max(abs(cx), abs(cx - (nx - 1)), abs(cy), abs(cy - (ny - 1)))
        found = 0
        for ring in range(r0, last + 1):
            # Every cell of this ring is at least (ring - 1) cell widths from the point.
            gap = (ring - 1) * size
            if gap > 0.0 and (gap * gap >= r2_reach or (found == k and gap * gap > best_d2[k - 1])):
                break
            for gy in range(max(cy - ring, 0), min(cy + ring, ny - 1) + 1):
                whole = gy == cy - ring or gy == cy + ring  # top and bottom rows of the ring
                lo = max(cx - ring, 0) if whole else cx - ring
                hi = min(cx + ring, nx - 1)
                for gx in range(lo, hi + 1, 1 if whole else 2 * ring):
                    if gx < 0:
                        continue
                    c = gy * nx + gx
                    for kk in range(first[c], first[c + 1]):
                        j = order[kk]
                        dx = x - corners[j, 0]
                        dy = y - corners[j, 1]
                        d2 = dx * dx + dy * dy
                        if not d2 < r2_reach:
                            continue
                        if found == k and not (d2 < best_d2[k - 1] or (d2 == best_d2[k - 1]
                                                                      and j < best_c[k - 1])):
                            continue
                        # Insert (d2, j) by distance, then index; a full list drops its last.
                        at = found if found < k else k - 1
                        while at > 0 and (best_d2[at - 1] > d2 or (best_d2[at - 1] == d2
                                                                   and best_c[at - 1] > j)):
                            best_d2[at] = best_d2[at - 1]
                            best_c[at] = best_c[at - 1]
                            at -= 1
                        best_d2[at] = d2
                        best_c[at] = j
                        if found < k:
                            found += 1
        v = hp[i]
        for t in range(found):
            cone = spacing[best_c[t]] + rate * math.sqrt(best_d2[t])
            if cone < v:
                v = cone
        out[i] = v
    return out
