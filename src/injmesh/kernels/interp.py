"""Bilinear interpolation on a rectilinear grid (the kernel of :class:`injmesh.sizing.GriddedSize`)."""

from __future__ import annotations

import numba
import numpy as np

from . import threads


@numba.njit(cache=True, inline="always")
def _cell(axis: np.ndarray, inv_step: float, v: float) -> tuple[int, float]:
    """Cell index ``i`` (``axis[i] <= v < axis[i+1]``, clamped) and the local coordinate in [0, 1].

    A uniform axis (``inv_step > 0``) guesses the cell arithmetically and corrects it by a step;
    any other axis bisects.  The correction makes ``v == axis[i]`` give exactly ``t = 0``, so the
    grid values are reproduced bit for bit at the nodes.
    """
    n = axis.shape[0]
    if v <= axis[0]:
        return 0, 0.0
    if v >= axis[n - 1]:
        return n - 2, 1.0
    if inv_step > 0.0:
        i = int((v - axis[0]) * inv_step)
        i = min(max(i, 0), n - 2)
        while i > 0 and v < axis[i]:
            i -= 1
        while i < n - 2 and v >= axis[i + 1]:
            i += 1
    else:
        lo, hi = 0, n - 1
        while hi - lo > 1:
            mid = (lo + hi) >> 1
            if axis[mid] <= v:
                lo = mid
            else:
                hi = mid
        i = lo
    return i, (v - axis[i]) / (axis[i + 1] - axis[i])


@numba.njit(cache=True, nogil=True)
def bilinear(
    x: np.ndarray, y: np.ndarray, values: np.ndarray, inv_dx: float, inv_dy: float, p: np.ndarray
) -> np.ndarray:
    """Bilinear interpolation of ``values`` (ny, nx) at the points ``p`` (n, 2).

    Points outside the grid take the value at the nearest point of the grid's rectangle
    (coordinates clamped); a NaN coordinate gives NaN.
    """
    n = p.shape[0]
    out = np.empty(n)
    for k in range(n):
        px = p[k, 0]
        py = p[k, 1]
        if px != px or py != py:
            out[k] = np.nan
            continue
        i, tx = _cell(x, inv_dx, px)
        j, ty = _cell(y, inv_dy, py)
        v00 = values[j, i]
        v10 = values[j, i + 1]
        v01 = values[j + 1, i]
        v11 = values[j + 1, i + 1]
        # Exact at nodes: with tx = ty = 0 only v00 survives, multiplied by 1.
        out[k] = (1.0 - ty) * ((1.0 - tx) * v00 + tx * v10) + ty * ((1.0 - tx) * v01 + tx * v11)
    return out


@numba.njit(cache=True)
def bucket_triangles(
    pts: np.ndarray, tri: np.ndarray, x0: float, y0: float, inv: float, nx: int, ny: int
) -> tuple[np.ndarray, np.ndarray]:
    """Triangles listed per cell of a uniform bucket grid (CSR: ``start`` (nx*ny+1,), ``items``).

    A triangle is listed in every cell its bounding box touches, in increasing triangle order.
    """
    m = tri.shape[0]
    count = np.zeros(nx * ny + 1, dtype=np.int64)
    for t in range(m):
        i0, i1, j0, j1 = _box(pts, tri, t, x0, y0, inv, nx, ny)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                count[j * nx + i + 1] += 1
    start = np.cumsum(count)
    items = np.empty(start[-1], dtype=np.int64)
    fill = start[:-1].copy()
    for t in range(m):
        i0, i1, j0, j1 = _box(pts, tri, t, x0, y0, inv, nx, ny)
        for j in range(j0, j1 + 1):
            for i in range(i0, i1 + 1):
                c = j * nx + i
                items[fill[c]] = t
                fill[c] += 1
    return start, items


@numba.njit(cache=True, inline="always")
def _box(
    pts: np.ndarray, tri: np.ndarray, t: int, x0: float, y0: float, inv: float, nx: int, ny: int
) -> tuple[int, int, int, int]:
    xa = min(pts[tri[t, 0], 0], pts[tri[t, 1], 0], pts[tri[t, 2], 0])
    xb = max(pts[tri[t, 0], 0], pts[tri[t, 1], 0], pts[tri[t, 2], 0])
    ya = min(pts[tri[t, 0], 1], pts[tri[t, 1], 1], pts[tri[t, 2], 1])
    yb = max(pts[tri[t, 0], 1], pts[tri[t, 1], 1], pts[tri[t, 2], 1])
    i0 = min(max(int((xa - x0) * inv), 0), nx - 1)
    i1 = min(max(int((xb - x0) * inv), 0), nx - 1)
    j0 = min(max(int((ya - y0) * inv), 0), ny - 1)
    j1 = min(max(int((yb - y0) * inv), 0), ny - 1)
    return i0, i1, j0, j1


@numba.njit(cache=True)
def barycentric(
    pts: np.ndarray,
    tri: np.ndarray,
    values: np.ndarray,
    start: np.ndarray,
    items: np.ndarray,
    x0: float,
    y0: float,
    inv: float,
    nx: int,
    ny: int,
    q: np.ndarray,
    eps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of ``values`` on the triangles ``tri`` at the points ``q`` (n, 2).

    Returns the values and a mask of the points found in a triangle (the first one, in
    triangle order, whose barycentric coordinates are all >= -eps).
    """
    n = q.shape[0]
    out = np.empty(n)
    found = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        x = q[k, 0]
        y = q[k, 1]
        fx = (x - x0) * inv
        fy = (y - y0) * inv
        if not (fx >= 0.0 and fy >= 0.0 and fx <= nx and fy <= ny):
            continue  # outside the buckets (or NaN): outside the triangulation
        c = min(int(fy), ny - 1) * nx + min(int(fx), nx - 1)
        for s in range(start[c], start[c + 1]):
            t = items[s]
            a, b, e = tri[t, 0], tri[t, 1], tri[t, 2]
            x1, y1 = pts[a, 0], pts[a, 1]
            x2, y2 = pts[b, 0], pts[b, 1]
            x3, y3 = pts[e, 0], pts[e, 1]
            det = (y2 - y3) * (x1 - x3) + (x3 - x2) * (y1 - y3)
            if det == 0.0:
                continue
            l1 = ((y2 - y3) * (x - x3) + (x3 - x2) * (y - y3)) / det
            l2 = ((y3 - y1) * (x - x3) + (x1 - x3) * (y - y3)) / det
            l3 = 1.0 - l1 - l2
            if l1 >= -eps and l2 >= -eps and l3 >= -eps:
                out[k] = l1 * values[a] + l2 * values[b] + l3 * values[e]
                found[k] = True
                break
    return out, found


def threaded_bilinear(
    x: np.ndarray, y: np.ndarray, values: np.ndarray, inv_dx: float, inv_dy: float, p: np.ndarray
) -> np.ndarray:
    """:func:`bilinear` over chunks of the points on several threads (the same numbers)."""
    n = p.shape[0]
    if not threads.worth(n):
        out: np.ndarray = bilinear(x, y, values, inv_dx, inv_dy, p)
        return out
    res = np.empty(n)

    def run(lo: int, hi: int) -> None:
        res[lo:hi] = bilinear(x, y, values, inv_dx, inv_dy, p[lo:hi])

    threads.each(n, run)
    return res
