"""Inside/outside of a grid's nodes from boundary polylines, by scanlines (background grids).

A background grid of a domain with an exact boundary needs the signed distance only near the
boundary: farther away the sign is all that is read.  :func:`scan` gives the sign of every node
by the even-odd rule along each grid row (one pass over the segments, then a sort of each row's
crossings) and marks the nodes within a given distance of a segment's bounding box, which the
caller evaluates exactly.  Linear in nodes plus segments; deterministic.  :func:`near_nodes`
marks the nodes within a distance of the segments themselves (a band as wide as asked), and
:func:`cell_signs` is the per-point cell lookup of the node estimate's inside test
(:func:`injmesh.sizing.background.inside_test`).  :func:`ring_cell` gives the cells of a square
ring round a cell, the walk of the cell-grid nearest-point searches (injection's proximity
test, the feature size's nearest vertices).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def scan(x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray,
         reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Nodes inside the closed polylines ``a[s] -> b[s]`` and nodes near a segment.

    ``x`` (nx,) and ``y`` (ny,) are uniform, increasing axes.  A node is *near* when it lies
    within ``reach`` of a segment's bounding box.  A row crosses a segment when
    ``min(ya, yb) <= y < max(ya, yb)``, so a vertex on a row is counted once.

    Returns
    -------
    inside : (ny, nx) bool
        Even-odd rule (meaningful away from the segments; near ones are to be evaluated).
    near : (ny, nx) bool
    """
    nx, ny, m = x.shape[0], y.shape[0], a.shape[0]
    sx = (x[nx - 1] - x[0]) / max(nx - 1, 1)
    sy = (y[ny - 1] - y[0]) / max(ny - 1, 1)
    near = np.zeros((ny, nx), dtype=np.bool_)
    count = np.zeros(ny + 1, dtype=np.int64)
    for pass_ in range(2):
        if pass_ == 1:
            for j in range(ny):
                count[j + 1] += count[j]
            xs = np.empty(count[ny])
            fill = count[:-1].copy()
        for s in range(m):
            ya, yb = a[s, 1], b[s, 1]
            lo_y, hi_y = min(ya, yb), max(ya, yb)
            # One row of slack each way: the test below decides exactly.
            j0 = max(int(math.ceil((lo_y - y[0]) / sy)) - 1, 0)
            j1 = min(int(math.floor((hi_y - y[0]) / sy)) + 1, ny - 1)
            for j in range(j0, j1 + 1):
                yj = y[j]
                if yj < lo_y or yj >= hi_y:
                    continue
                if pass_ == 0:
                    count[j + 1] += 1
                else:
                    t = (yj - ya) / (yb - ya)
                    xs[fill[j]] = a[s, 0] + t * (b[s, 0] - a[s, 0])
                    fill[j] += 1
            if pass_ == 0:
                lo_x, hi_x = min(a[s, 0], b[s, 0]), max(a[s, 0], b[s, 0])
                i0 = max(int(math.floor((lo_x - reach - x[0]) / sx)), 0)
                i1 = min(int(math.ceil((hi_x + reach - x[0]) / sx)), nx - 1)
                k0 = max(int(math.floor((lo_y - reach - y[0]) / sy)), 0)
                k1 = min(int(math.ceil((hi_y + reach - y[0]) / sy)), ny - 1)
                for k in range(k0, k1 + 1):
                    for i in range(i0, i1 + 1):
                        near[k, i] = True
    inside = np.zeros((ny, nx), dtype=np.bool_)
    for j in range(ny):
        row = np.sort(xs[count[j]:count[j + 1]])
        for c in range(0, row.shape[0] - 1, 2):
            i0 = max(int(math.ceil((row[c] - x[0]) / sx)) - 1, 0)
            i1 = min(int(math.floor((row[c + 1] - x[0]) / sx)) + 1, nx - 1)
            for i in range(i0, i1 + 1):
                if row[c] <= x[i] <= row[c + 1]:
                    inside[j, i] = True
    return inside, near


@numba.njit(cache=True)
def near_nodes(x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray, reach: float) -> np.ndarray:
    """Nodes within ``reach`` of a segment ``a[s] -> b[s]`` (distance to the segment itself,
    not to its box: a band about ``reach`` wide each side of the polylines).

    ``x`` (nx,) and ``y`` (ny,) are uniform, increasing axes.  A node whose rounded distance
    is a hair above ``reach`` may be left out: callers ask for a margin (see
    :func:`injmesh.sizing.background.inside_test`).
    """
    nx, ny, m = x.shape[0], y.shape[0], a.shape[0]
    sx = (x[nx - 1] - x[0]) / max(nx - 1, 1)
    sy = (y[ny - 1] - y[0]) / max(ny - 1, 1)
    near = np.zeros((ny, nx), dtype=np.bool_)
    r2 = reach * reach
    for s in range(m):
        ax, ay, bx, by = a[s, 0], a[s, 1], b[s, 0], b[s, 1]
        i0 = max(int(math.floor((min(ax, bx) - reach - x[0]) / sx)), 0)
        i1 = min(int(math.ceil((max(ax, bx) + reach - x[0]) / sx)), nx - 1)
        j0 = max(int(math.floor((min(ay, by) - reach - y[0]) / sy)), 0)
        j1 = min(int(math.ceil((max(ay, by) + reach - y[0]) / sy)), ny - 1)
        dx, dy = bx - ax, by - ay
        l2 = dx * dx + dy * dy
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                if near[j, i]:
                    continue
                px, py = x[i] - ax, y[j] - ay
                t = 0.0 if l2 <= 0.0 else min(max((px * dx + py * dy) / l2, 0.0), 1.0)
                ex, ey = px - t * dx, py - t * dy
                if ex * ex + ey * ey <= r2:
                    near[j, i] = True
    return near


@numba.njit(cache=True)
def cell_signs(p: np.ndarray, x0: float, y0: float, spacing: float, known: np.ndarray,
               neg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sign of each point ``p (m, 2)`` where its grid cell is ``known`` (cell ``(j, i)``
    spans ``[x0 + i spacing, x0 + (i + 1) spacing)`` and likewise in y, by ``floor``), and
    the points whose cell is not known or outside the grid.

    Returns ``inside (m,)`` (``neg`` of the cell; False where not known) and the rows of the
    points left to decide.
    """
    m = p.shape[0]
    ny, nx = known.shape
    inside = np.zeros(m, dtype=np.bool_)
    rest = np.empty(m, dtype=np.int64)
    k = 0
    for q in range(m):
        # Compared as floats, as NumPy would: a NaN or huge coordinate is simply not in a cell.
        i = np.floor((p[q, 0] - x0) / spacing)
        j = np.floor((p[q, 1] - y0) / spacing)
        if i >= 0 and i < nx and j >= 0 and j < ny and known[int(j), int(i)]:
            inside[q] = neg[int(j), int(i)]
        else:
            rest[k] = q
            k += 1
    return inside, rest[:k].copy()


@numba.njit(cache=True)
def quarter_samples(centres: np.ndarray, side: float, quarter: np.ndarray, r2: np.ndarray) -> np.ndarray:
    """The node estimate's samples (:func:`injmesh.boundary.estimate_nodes`): for each quarter
    q of each cell c (``quarter (4, 2)`` offsets in cells, quarter-major), ``centres[c] + side
    (quarter[q] + 0.5 j_c)`` with the jitter ``j_c = (c r2) mod 1 - 0.5`` of the R2 sequence;
    the numbers of its NumPy form, ``(4 k, 2)``."""
    k = centres.shape[0]
    out = np.empty((quarter.shape[0] * k, 2))
    for c in range(k):
        jx = (c * r2[0]) % 1.0 - 0.5
        jy = (c * r2[1]) % 1.0 - 0.5
        for q in range(quarter.shape[0]):
            out[q * k + c, 0] = centres[c, 0] + side * (quarter[q, 0] + 0.5 * jx)
            out[q * k + c, 1] = centres[c, 1] + side * (quarter[q, 1] + 0.5 * jy)
    return out


@numba.njit(cache=True)
def densify(loop: np.ndarray, step: float) -> np.ndarray:
    """A closed polyline ``loop (n, 2)`` with extra vertices so that no segment is longer than
    ``step``: each segment cut into ``max(1, ceil(length / step))`` equal pieces, vertex k of a
    piece at ``a + (k / pieces) (b - a)`` (:func:`injmesh.sizing.background.densify`; the
    numbers of its NumPy form)."""
    n = loop.shape[0]
    pieces = np.empty(n, dtype=np.int64)
    total = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        cut = np.ceil(math.hypot(loop[j, 0] - loop[i, 0], loop[j, 1] - loop[i, 1]) / step)
        pieces[i] = int(max(1.0, cut))
        total += pieces[i]
    out = np.empty((total, 2))
    m = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        dx, dy = loop[j, 0] - loop[i, 0], loop[j, 1] - loop[i, 1]
        for k in range(pieces[i]):
            frac = k / pieces[i]
            out[m, 0] = loop[i, 0] + frac * dx
            out[m, 1] = loop[i, 1] + frac * dy
            m += 1
    return out


@numba.njit(cache=True, inline="always")
def ring_cell(cx: int, cy: int, ring: int, t: int, nx: int, ny: int) -> int:
    """Cell ``t`` of the square ring ``ring`` cells out from cell ``(cx, cy)`` on an ``nx`` by
    ``ny`` grid, as ``gy * nx + gx``, or -1 when it is off the grid.

    A ring has ``8 * ring`` cells (one for ring 0), in rows from ``cy - ring`` up, each row
    left to right: all of the first and the last row, the two end cells of the others.  The
    cell-grid searches visit them in this order, so their ties are settled as they were.
    Arithmetic only: no scratch array in a search called once per point.
    """
    side = 2 * ring + 1
    if t < side or ring == 0:
        gy, gx = cy - ring, cx - ring + t
    elif t < side + 2 * (side - 2):
        u = t - side
        gy, gx = cy - ring + 1 + u // 2, (cx - ring if u % 2 == 0 else cx + ring)
    else:
        gy, gx = cy + ring, cx - ring + (t - side - 2 * (side - 2))
    if gx < 0 or gx >= nx or gy < 0 or gy >= ny:
        return -1
    return gy * nx + gx
