"""Bilinear interpolation on a rectilinear grid (the kernel of :class:`injmesh.sizing.GriddedSize`)."""

from __future__ import annotations

import numba
import numpy as np


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


@numba.njit(cache=True)
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
