"""Size fields from data: a raster (:class:`GriddedSize`) and scattered samples (:class:`ScatteredSize`).

Both are plain callables ``h(p)`` on ``(n, 2)`` points, validated once when built (so that every
evaluation is a pure interpolation) and usable wherever a size is expected.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._core import _KIND_NAMES, SizeError

FloatArray = NDArray[np.float64]


def _real(name: str, a: ArrayLike) -> FloatArray:
    """``a`` as a float64 array, refusing booleans, complex numbers, strings and objects."""
    arr = np.asarray(a)
    if arr.dtype.kind not in "fiu":
        what = _KIND_NAMES.get(arr.dtype.kind, f"dtype {arr.dtype}")
        raise SizeError(f"{name} must hold real numbers, got {what}")
    return arr.astype(np.float64, copy=False)


def _axis(name: str, a: ArrayLike) -> tuple[FloatArray, bool]:
    """A grid axis: 1-D, finite, at least two values, strictly monotone; (increasing copy, flipped)."""
    axis = _real(name, a)
    if axis.ndim != 1:
        raise SizeError(f"{name} must be a 1-D array of grid coordinates, got shape {axis.shape}")
    if len(axis) < 2:
        raise SizeError(f"{name} must have at least two grid coordinates, got {len(axis)}")
    bad = ~np.isfinite(axis)
    if bad.any():
        i = int(np.argmax(bad))
        raise SizeError(f"{name}[{i}] = {axis[i]} is not finite")
    step = np.diff(axis)
    flipped = bool(step[0] < 0)
    if flipped:
        axis, step = axis[::-1], -step[::-1]
    if not np.all(step > 0):
        i = int(np.argmax(~(step > 0)))
        if flipped:  # report in the caller's order
            i = len(axis) - 2 - i
        order = "decreasing" if flipped else "increasing"
        raise SizeError(
            f"{name} must be strictly monotone: it starts {order} but {name}[{i}] = "
            f"{float(np.asarray(a, dtype=float)[i])} and {name}[{i + 1}] = "
            f"{float(np.asarray(a, dtype=float)[i + 1])}"
        )
    return np.ascontiguousarray(axis), flipped


def _inverse_step(axis: FloatArray) -> float:
    """``1 / step`` for a uniform axis (the kernel then finds cells arithmetically), else 0."""
    step = np.diff(axis)
    mean = (axis[-1] - axis[0]) / (len(axis) - 1)
    return float(1.0 / mean) if np.all(np.abs(step - mean) <= 1e-9 * mean) else 0.0


def _check_sizes(values: FloatArray, where: Any) -> None:
    """Positive and finite, or a SizeError naming the first bad value and where it is."""
    bad = ~(np.isfinite(values) & (values > 0))
    if bad.any():
        k = int(np.argmax(bad.ravel()))
        idx = np.unravel_index(k, values.shape)
        raise SizeError(
            f"sizes must be positive and finite; values[{', '.join(map(str, idx))}] = "
            f"{float(values[idx])} at {where(idx)} ({int(bad.sum())} bad values in all)"
        )


class GriddedSize:
    """A size field given on a rectilinear grid (a raster), interpolated bilinearly.

    Parameters
    ----------
    x : (nx,) array_like
        Grid coordinates along x, strictly monotone (a decreasing axis is reversed with its
        values, as in rasters stored top row first), at least two.
    y : (ny,) array_like
        Grid coordinates along y, likewise.
    values : (ny, nx) array_like
        Positive finite sizes; ``values[j, i]`` is the size at ``(x[i], y[j])``.

    Notes
    -----
    Evaluation is bilinear in each cell and reproduces ``values`` exactly at the grid nodes.
    Outside the grid a point takes the value at the nearest point of the grid's rectangle
    (its coordinates are clamped).  A uniform axis finds the cell arithmetically, any other by
    bisection; the kernel is compiled with numba on first use.  The values are copied and kept
    read-only.

    Raises
    ------
    SizeError
        Axes that are not 1-D, finite and strictly monotone; values of the wrong shape, not real
        numbers, NaN, infinite or not positive (the message names the index and the point).

    Examples
    --------
    >>> import numpy as np
    >>> h = GriddedSize([0, 1, 2], [0, 1], [[0.1, 0.2, 0.3], [0.3, 0.4, 0.5]])
    >>> h(np.array([[0.5, 0.5], [5.0, 0.0]]))
    array([0.25, 0.3 ])
    """

    def __init__(self, x: ArrayLike, y: ArrayLike, values: ArrayLike) -> None:
        xs, flip_x = _axis("x", x)
        ys, flip_y = _axis("y", y)
        v = _real("values", values)
        if v.shape != (len(ys), len(xs)):
            hint = ""
            if v.shape == (len(xs), len(ys)):
                hint = " (it looks transposed: values[j, i] is the size at (x[i], y[j]))"
            raise SizeError(
                f"values must have shape (len(y), len(x)) = ({len(ys)}, {len(xs)}), got {v.shape}{hint}"
            )
        if flip_x:
            v = v[:, ::-1]
        if flip_y:
            v = v[::-1, :]
        _check_sizes(v, lambda idx: (float(xs[idx[1]]), float(ys[idx[0]])))
        self._set(xs, ys, v)

    @classmethod
    def _trusted(cls, x: FloatArray, y: FloatArray, values: FloatArray) -> GriddedSize:
        """Build from arrays this package made and checked (no second validation pass)."""
        self = cls.__new__(cls)
        self._set(x, y, values)
        return self

    def _set(self, x: FloatArray, y: FloatArray, values: FloatArray) -> None:
        self.x = np.array(x, dtype=np.float64)
        self.y = np.array(y, dtype=np.float64)
        self.values = np.array(values, dtype=np.float64, order="C")
        for a in (self.x, self.y, self.values):
            a.flags.writeable = False
        self._inv = (_inverse_step(self.x), _inverse_step(self.y))

    def __repr__(self) -> str:
        ny, nx = self.values.shape
        return (
            f"<GriddedSize: {nx} x {ny} grid on [{self.x[0]:g}, {self.x[-1]:g}] x "
            f"[{self.y[0]:g}, {self.y[-1]:g}], h in [{self.values.min():g}, {self.values.max():g}]>"
        )

    @property
    def spacing(self) -> tuple[float, float]:
        """The largest grid step along x and along y."""
        return float(np.diff(self.x).max()), float(np.diff(self.y).max())

    def __call__(self, p: ArrayLike) -> FloatArray:
        from ..kernels.interp import threaded_bilinear

        q = np.ascontiguousarray(np.asarray(p, dtype=np.float64).reshape(-1, 2))
        out: FloatArray = threaded_bilinear(self.x, self.y, self.values, self._inv[0], self._inv[1], q)
        return out


class ScatteredSize:
    """A size field given by samples at scattered points, linear between them.

    Parameters
    ----------
    points : (n, 2) array_like
        Sample locations, finite.  Exact duplicates are merged (their sizes averaged).
    values : (n,) array_like
        Positive finite sizes at the samples.

    Notes
    -----
    Inside the convex hull of the samples h is linear on each triangle of their Delaunay
    triangulation (barycentric interpolation, exact at the samples); outside the hull it is the
    size of the nearest sample.  With fewer than three distinct samples, or all of them on one
    line, h is the nearest sample's size everywhere.  The triangulation is computed in
    coordinates centred on the samples and scaled by their extent, so samples far from the
    origin (UTM, 1e9 offsets) triangulate as well as samples near it.

    Raises
    ------
    SizeError
        Wrong shapes, no samples, non-real or non-finite coordinates, sizes that are NaN,
        infinite or not positive (the message names the sample and its coordinates).

    Examples
    --------
    >>> import numpy as np
    >>> h = ScatteredSize([(0, 0), (1, 0), (0, 1)], [0.1, 0.2, 0.3])
    >>> h(np.array([[0.25, 0.25], [3.0, 0.0]])).round(3)
    array([0.175, 0.2  ])
    """

    def __init__(self, points: ArrayLike, values: ArrayLike) -> None:
        from scipy.spatial import cKDTree

        pts = _real("points", points)
        v = _real("values", values)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise SizeError(f"points must have shape (n, 2), got {pts.shape}")
        if len(pts) == 0:
            raise SizeError("a scattered size needs at least one sample, got none")
        if v.shape != (len(pts),):
            raise SizeError(f"values must have shape ({len(pts)},) for {len(pts)} points, got {v.shape}")
        bad = ~np.isfinite(pts).all(axis=1)
        if bad.any():
            i = int(np.argmax(bad))
            raise SizeError(f"points[{i}] = {tuple(pts[i].tolist())} is not finite")
        _check_sizes(v, lambda idx: tuple(pts[idx[0]].tolist()))
        # Merge exact duplicates (Qhull would silently keep one of them).
        uniq, inverse = np.unique(pts, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        if len(uniq) < len(pts):
            count = np.bincount(inverse, minlength=len(uniq))
            v = np.bincount(inverse, weights=v, minlength=len(uniq)) / count
            pts = uniq
        self.points = pts.copy()
        self.values = np.array(v, dtype=np.float64)
        self.points.flags.writeable = False
        self.values.flags.writeable = False
        self._centre = pts.mean(axis=0)
        extent = float(np.ptp(pts, axis=0).max())
        self._scale = 1.0 / extent if extent > 0 else 1.0
        local = (pts - self._centre) * self._scale
        self._tree = cKDTree(local)
        self._tri: Any = None
        if len(pts) >= 3:
            s = np.linalg.svd(local - local.mean(axis=0), compute_uv=False)
            if s[1] > 1e-9 * s[0]:
                self._locate(local)

    def _locate(self, local: FloatArray) -> None:
        """Triangulate the samples and bucket the triangles for point location.

        The buckets form a uniform grid over the samples' box with about one triangle per cell,
        so a point is located by testing the few triangles listed in its cell (numba).
        """
        from scipy.spatial import Delaunay

        from ..kernels.interp import bucket_triangles

        tri = np.ascontiguousarray(Delaunay(local).simplices.astype(np.int64))
        lo = local.min(axis=0)
        extent = local.max(axis=0) - lo
        side = float(np.sqrt(extent[0] * extent[1] / max(len(tri), 1)))
        side = max(side, float(extent.max()) / 4096, 1e-12)
        nx = max(1, int(np.ceil(extent[0] / side)))
        ny = max(1, int(np.ceil(extent[1] / side)))
        self._tri = tri
        self._local = np.ascontiguousarray(local)
        self._grid = (float(lo[0]), float(lo[1]), 1.0 / side, nx, ny)
        self._buckets = bucket_triangles(self._local, tri, lo[0], lo[1], 1.0 / side, nx, ny)

    def __repr__(self) -> str:
        kind = "linear" if self._tri is not None else "nearest"
        return (
            f"<ScatteredSize: {len(self.points)} samples ({kind}), "
            f"h in [{self.values.min():g}, {self.values.max():g}]>"
        )

    def __call__(self, p: ArrayLike) -> FloatArray:
        q = (np.asarray(p, dtype=np.float64).reshape(-1, 2) - self._centre) * self._scale
        out = np.empty(len(q))
        nan = np.isnan(q).any(axis=1)
        out[nan] = np.nan
        todo = np.flatnonzero(~nan)
        if self._tri is not None and len(todo):
            from ..kernels.interp import barycentric

            x0, y0, inv, nx, ny = self._grid
            vals, hit = barycentric(
                self._local, self._tri, self.values, self._buckets[0], self._buckets[1],
                x0, y0, inv, nx, ny, np.ascontiguousarray(q[todo]), 1e-12,
            )
            out[todo[hit]] = vals[hit]
            todo = todo[~hit]
        if len(todo):
            _, nearest = self._tree.query(q[todo])
            out[todo] = self.values[nearest]
        return out
