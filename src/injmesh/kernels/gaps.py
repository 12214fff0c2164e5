"""Gaps between a region's walls and the walls facing them (the regions' feature size).

:func:`thinnest_chords` is the kernel behind ``pipeline._gap_cones``: for every vertex of a
part's boundary polylines, the thinnest chord to a facing segment of the same part, judged as
:func:`injmesh.kernels.outline.facing_walls` judges a vertex and a segment, where one of the two
lies on a region's wall and the partner is within the vertex's (or the partner's) own search
radius.  Candidates come from two uniform grids of cells (all vertices, and the region walls'
vertices alone), so the cost is the number of vertex pairs within the radii that touch a region
wall, with nothing stored per pair.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .outline import _judge


@nb.njit(cache=True)
def _grid(v, pick, size, x0, y0, nx, ny):  # type: ignore[no-untyped-def]
    """The vertices ``pick`` bucketed in cells ``size`` wide from ``(x0, y0)``: the vertices in
    cell order and where each cell's run starts (``nx * ny + 1`` entries)."""
    m = pick.shape[0]
    cell = np.empty(m, dtype=np.int64)
    for k in range(m):
        i = pick[k]
        cx = min(max(int((v[i, 0] - x0) / size), 0), nx - 1)
        cy = min(max(int((v[i, 1] - y0) / size), 0), ny - 1)
        cell[k] = cy * nx + cx
    order = np.argsort(cell, kind="mergesort")
    members = pick[order]
    first = np.full(nx * ny + 1, m, dtype=np.int64)
    for k in range(m - 1, -1, -1):
        first[cell[order[k]]] = k
    for c in range(nx * ny - 1, -1, -1):
        if first[c] == m:
            first[c] = first[c + 1]
    return members, first


@nb.njit(cache=True, inline="always")
def _try(a, s, v, seg, seg_len, v_n, seg_n, cos, best_w, best_f):  # type: ignore[no-untyped-def]
    """Vertex a against segment s (``outline._judge``'s facing test, at any distance); a facing
    pair whose thickness ``dist / (e . n_a)`` is below a's best so far replaces it."""
    kind, fx, fy, dist = _judge(a, s, v, seg, seg_len, v_n, seg_n, np.inf, 0.0, cos)
    if kind != 2:
        return
    w = dist / ((fx - v[a, 0]) / dist * v_n[a, 0] + (fy - v[a, 1]) / dist * v_n[a, 1])
    if w < best_w[a]:
        best_w[a] = w
        best_f[a, 0], best_f[a, 1] = fx, fy


@nb.njit(cache=True)
def thinnest_chords(v, prv, seg, seg_len, v_n, seg_n, wall, radius, cos):  # type: ignore[no-untyped-def]
    """For each vertex a, the thinnest facing chord to a segment of the same loops.

    Vertex k starts segment k (``seg[k]``, length ``seg_len[k]``, outward-facing test on
    ``seg_n[k]``) and follows vertex ``prv[k]``; ``v_n`` are the vertices' inward normals.  A
    vertex a and a segment s (starting at a vertex b, or at ``prv[b]``; not one of a's own two)
    face each other when the direction e from a to the foot f of a on s has ``e . v_n[a] >
    cos`` and ``-e . seg_n[s] > cos``; the chord's thickness is ``|f - a| / (e . v_n[a])``.
    Pairs are examined when a or b is a ``wall`` vertex, with ``|a - b| <= max(radius[a],
    radius[b])``; a segment counts as on the wall when the vertex b is.

    Returns
    -------
    width : (n,) array
        The least thickness of a's facing chords (``inf`` when none).
    foot : (n, 2) array
        The foot of that chord.
    """
    n = v.shape[0]
    best_w = np.full(n, np.inf)
    best_f = np.zeros((n, 2))
    inner = np.flatnonzero(wall)
    if n < 3 or inner.shape[0] == 0:
        return best_w, best_f
    size = 0.0
    for k in range(inner.shape[0]):
        size = max(size, radius[inner[k]])
    if not size > 0.0:
        return best_w, best_f
    x0, y0 = v[:, 0].min(), v[:, 1].min()
    nx = int((v[:, 0].max() - x0) / size) + 1
    ny = int((v[:, 1].max() - y0) / size) + 1
    slack = 2.0 * seg_len.max()
    everyone, first_all = _grid(v, np.arange(n), size, x0, y0, nx, ny)
    walls, first_wall = _grid(v, inner, size, x0, y0, nx, ny)
    for i in range(n):
        r = radius[i]
        if not wall[i] and not r > 0.0:
            continue
        # A wall vertex looks at every vertex within its radius (cells of ``size``, its largest
        # radius); another vertex only at wall vertices within its own (a few more cells).
        reach = 1 if wall[i] else max(1, int(math.ceil(r / size)))
        look = size if wall[i] else r
        members = everyone if wall[i] else walls
        first = first_all if wall[i] else first_wall
        cx = min(max(int((v[i, 0] - x0) / size), 0), nx - 1)
        cy = min(max(int((v[i, 1] - y0) / size), 0), ny - 1)
        for gy in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
            for gx in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
                c = gy * nx + gx
                for kk in range(first[c], first[c + 1]):
                    j = members[kk]
                    if j == i:
                        continue
                    dx, dy = v[j, 0] - v[i, 0], v[j, 1] - v[i, 1]
                    d2 = dx * dx + dy * dy
                    lim = max(radius[i], radius[j]) if wall[i] else r
                    if not d2 <= lim * lim or d2 > look * look and wall[i]:
                        continue
                    # A pair seen from j already (j came first and saw i: j is a wall vertex,
                    # or i is one within j's radius) was judged both ways round then: seen
                    # again, it could not lower a width (strictly), so it is skipped.
                    if j < i and (wall[j] or wall[i] and d2 <= radius[j] * radius[j]):
                        continue
                    # A foot on a segment at b lies within the longest segment L of b, so a
                    # partner whose direction from a makes e . n_a <= cos impossible (b's offset
                    # along n_a at most cos |ab| - 2 L) is not judged: the same answers.
                    d = math.sqrt(d2)
                    fwd = dx * v_n[i, 0] + dy * v_n[i, 1] > cos * d - slack
                    bwd = -dx * v_n[j, 0] - dy * v_n[j, 1] > cos * d - slack
                    # Nor is a side whose chord cannot be thinner than that side's best so far
                    # or its radius (the caller keeps only chords thinner than the radius): the
                    # chord's thickness is at least |f - a| >= |a - b| - L.
                    fwd = fwd and d - slack < min(best_w[i], radius[i])
                    bwd = bwd and d - slack < min(best_w[j], radius[j])
                    # Both ways round, both segments at the partner (a's own two excluded).
                    for q in range(4):
                        if not (fwd if q < 2 else bwd):
                            continue
                        a, b = (i, j) if q < 2 else (j, i)
                        s = b if q % 2 == 0 else prv[b]
                        if s == a or s == prv[a]:
                            continue
                        _try(a, s, v, seg, seg_len, v_n, seg_n, cos, best_w, best_f)
    return best_w, best_f
