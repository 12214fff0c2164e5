"""Primitives with exact signed distances, projections, corners and boundary loops."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _tolerances as tol
from .base import BBox, Domain, FloatArray, GeometryError, as_points


class Circle(Domain):
    """The disc of radius ``r`` centred at ``center``.

    Examples
    --------
    >>> Circle((0, 0), 1).sdf([[0, 0], [2, 0]])
    array([-1.,  1.])
    """

    exact_distance = True

    def __init__(self, center: Sequence[float], r: float) -> None:
        c = np.asarray(center, dtype=float).reshape(-1)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise GeometryError(f"Circle center must be two finite numbers, got {center!r}")
        if not (math.isfinite(r) and r > 0):
            raise GeometryError(f"Circle radius must be positive, got {r!r}")
        self.center = c
        self.r = float(r)

    def __repr__(self) -> str:
        return f"Circle(({self.center[0]:g}, {self.center[1]:g}), {self.r:g})"

    def sdf(self, p: FloatArray) -> FloatArray:
        p = as_points(p)
        return np.hypot(p[:, 0] - self.center[0], p[:, 1] - self.center[1]) - self.r

    @property
    def bbox(self) -> BBox:
        cx, cy = self.center
        return (cx - self.r, cy - self.r, cx + self.r, cy + self.r)

    def project(self, p: FloatArray) -> FloatArray:
        v = as_points(p) - self.center
        n = np.hypot(v[:, 0], v[:, 1])
        v = np.where(n[:, None] > 0, v, [1.0, 0.0])
        n = np.where(n > 0, n, 1.0)
        return self.center + self.r * v / n[:, None]

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        n = max(16, math.ceil(2 * math.pi * self.r / spacing))
        t = np.linspace(0, 2 * math.pi, n, endpoint=False)
        return [self.center + self.r * np.stack([np.cos(t), np.sin(t)], axis=1)]


class Polygon(Domain):
    """A simple polygon (no self-intersection), given by its vertices in either orientation.

    The signed distance is exact: the distance to the nearest edge, negative inside (even-odd
    rule).  Vertices where the boundary turns by more than ``CORNER_ANGLE`` degrees are corners.

    Parameters
    ----------
    vertices : (k, 2) array_like
        At least three vertices; a repeated closing vertex is dropped.

    Raises
    ------
    GeometryError
        Fewer than three distinct vertices, non-finite coordinates, zero area, or edges that cross.

    Examples
    --------
    >>> tri = Polygon([(0, 0), (1, 0), (0, 1)])
    >>> float(tri.sdf([[0.25, 0.25]])[0])
    -0.25
    """

    exact_distance = True

    def __init__(self, vertices: ArrayLike) -> None:
        v = np.asarray(vertices, dtype=float)
        if v.ndim != 2 or v.shape[1] != 2:
            raise GeometryError(f"Polygon vertices must have shape (k, 2), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise GeometryError("Polygon vertices must be finite")
        if len(v) > 1 and np.allclose(v[0], v[-1]):
            v = v[:-1]
        # Drop repeated consecutive vertices: they make zero-length edges.
        keep = np.any(v != np.roll(v, 1, axis=0), axis=1)
        v = v[keep] if keep.any() else v[:1]
        if len(v) < 3:
            raise GeometryError(f"a Polygon needs at least 3 distinct vertices, got {len(v)}")
        area = _shoelace(v)
        scale = float(np.ptp(v, axis=0).max())
        if abs(area) <= 1e-12 * scale * scale:
            raise GeometryError("Polygon has zero area")
        if area < 0:
            v = v[::-1].copy()
        _check_simple(v)
        self.vertices = v
        self._a = v
        self._b = np.roll(v, -1, axis=0)

    def __repr__(self) -> str:
        return f"Polygon(<{len(self.vertices)} vertices>)"

    @property
    def area(self) -> float:
        """Enclosed area."""
        return _shoelace(self.vertices)

    @property
    def bbox(self) -> BBox:
        lo = self.vertices.min(axis=0)
        hi = self.vertices.max(axis=0)
        return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))

    def _nearest(self, p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Distance to the nearest edge, the nearest boundary point, and inside flags."""
        if len(self._a) <= 64:
            return self._nearest_by_edge(p)
        a, b = self._a, self._b
        ab = b - a
        ab2 = np.einsum("ij,ij->i", ab, ab)
        n = len(p)
        dist = np.empty(n)
        near = np.empty((n, 2))
        inside = np.empty(n, dtype=bool)
        # Chunk over points so the (points x edges) work arrays stay around 4 million entries.
        step = max(1, 4_000_000 // len(a))
        for s in range(0, n, step):
            q = p[s : s + step, None, :]
            t = np.clip(np.einsum("nmk,mk->nm", q - a, ab) / ab2, 0.0, 1.0)
            foot = a + t[..., None] * ab
            d2 = np.sum((q - foot) ** 2, axis=2)
            k = np.argmin(d2, axis=1)
            rows = np.arange(len(k))
            dist[s : s + step] = np.sqrt(d2[rows, k])
            near[s : s + step] = foot[rows, k]
            # Even-odd rule: count edges crossed by a ray towards +x.
            y = q[..., 1]
            crosses = (a[:, 1] > y) != (b[:, 1] > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                xint = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
            inside[s : s + step] = np.count_nonzero(crosses & (q[..., 0] < xint), axis=1) % 2 == 1
        return dist, near, inside

    def _nearest_by_edge(self, p: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`_nearest` for few edges: a loop over edges, vectorised over the points."""
        x, y = p[:, 0], p[:, 1]
        best = np.full(len(p), np.inf)
        near = np.empty_like(p)
        parity = np.zeros(len(p), dtype=bool)
        for (ax, ay), (bx, by) in zip(self._a, self._b, strict=True):
            ex, ey = bx - ax, by - ay
            t = np.clip(((x - ax) * ex + (y - ay) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
            fx, fy = ax + t * ex, ay + t * ey
            d2 = (x - fx) ** 2 + (y - fy) ** 2
            closer = d2 < best
            best = np.where(closer, d2, best)
            near[closer, 0] = fx[closer]
            near[closer, 1] = fy[closer]
            if ay != by:
                crosses = (ay > y) != (by > y)
                parity ^= crosses & (x < ax + (y - ay) * ex / ey)
        return np.sqrt(best), near, parity

    def sdf(self, p: FloatArray) -> FloatArray:
        dist, _, inside = self._nearest(as_points(p))
        return np.where(inside, -dist, dist)

    def project(self, p: FloatArray) -> FloatArray:
        return self._nearest(as_points(p))[1]

    def corners(self) -> FloatArray:
        v = self.vertices
        u = v - np.roll(v, 1, axis=0)
        w = np.roll(v, -1, axis=0) - v
        turn = np.degrees(np.abs(np.arctan2(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0], np.sum(u * w, 1))))
        return v[turn > tol.CORNER_ANGLE]

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        return [self.vertices.copy()]


class Rectangle(Polygon):
    """The axis-aligned rectangle with opposite corners ``p0`` and ``p1``.

    Examples
    --------
    >>> Rectangle((0, 0), (2, 1)).sdf([[1, 0.5], [3, 0.5]])
    array([-0.5,  1. ])
    """

    def __init__(self, p0: Sequence[float], p1: Sequence[float]) -> None:
        (x0, y0), (x1, y1) = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
        x0, x1 = sorted((x0, x1))
        y0, y1 = sorted((y0, y1))
        if not (x1 > x0 and y1 > y0):
            raise GeometryError(f"Rectangle needs x0 < x1 and y0 < y1, got {p0!r}, {p1!r}")
        super().__init__([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
        self.lo = np.array([x0, y0])
        self.hi = np.array([x1, y1])

    def __repr__(self) -> str:
        return f"Rectangle(({self.lo[0]:g}, {self.lo[1]:g}), ({self.hi[0]:g}, {self.hi[1]:g}))"

    def sdf(self, p: FloatArray) -> FloatArray:
        p = as_points(p)
        c = 0.5 * (self.lo + self.hi)
        q = np.abs(p - c) - 0.5 * (self.hi - self.lo)
        outside = np.hypot(*np.maximum(q, 0.0).T)
        return outside + np.minimum(q.max(axis=1), 0.0)

    def project(self, p: FloatArray) -> FloatArray:
        p = as_points(p)
        out = np.clip(p, self.lo, self.hi)
        inside = np.all((p > self.lo) & (p < self.hi), axis=1)
        if inside.any():
            q = p[inside]
            gaps = np.stack([q[:, 0] - self.lo[0], self.hi[0] - q[:, 0], q[:, 1] - self.lo[1],
                             self.hi[1] - q[:, 1]], axis=1)
            k = np.argmin(gaps, axis=1)
            r = q.copy()
            r[k == 0, 0] = self.lo[0]
            r[k == 1, 0] = self.hi[0]
            r[k == 2, 1] = self.lo[1]
            r[k == 3, 1] = self.hi[1]
            out[inside] = r
        return out


def _shoelace(v: FloatArray) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _check_simple(v: FloatArray) -> None:
    """Raise if two non-adjacent edges of the closed polyline ``v`` touch or cross."""
    a, b = v, np.roll(v, -1, axis=0)
    m = len(v)
    if m > 4000:
        return  # quadratic check: skipped for very large polygons (documented limitation)
    i, j = np.triu_indices(m, k=2)
    keep = ~((i == 0) & (j == m - 1))
    i, j = i[keep], j[keep]

    def orient(p: FloatArray, q: FloatArray, r: FloatArray) -> FloatArray:
        return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))

    o1 = orient(a[i], b[i], a[j])
    o2 = orient(a[i], b[i], b[j])
    o3 = orient(a[j], b[j], a[i])
    o4 = orient(a[j], b[j], b[i])
    cross = (o1 * o2 < 0) & (o3 * o4 < 0)
    # Collinear overlaps and touching vertices also break simplicity.
    def on_seg(p: FloatArray, q: FloatArray, r: FloatArray) -> NDArray[np.bool_]:
        return (np.minimum(p[:, 0], q[:, 0]) <= r[:, 0]) & (r[:, 0] <= np.maximum(p[:, 0], q[:, 0])) & (
            np.minimum(p[:, 1], q[:, 1]) <= r[:, 1]) & (r[:, 1] <= np.maximum(p[:, 1], q[:, 1]))

    touch = ((o1 == 0) & on_seg(a[i], b[i], a[j])) | ((o2 == 0) & on_seg(a[i], b[i], b[j])) | (
        (o3 == 0) & on_seg(a[j], b[j], a[i])) | ((o4 == 0) & on_seg(a[j], b[j], b[i]))
    bad = cross | touch
    if bad.any():
        k = int(np.argmax(bad))
        raise GeometryError(
            f"Polygon is not simple: edge {i[k]} ({tuple(a[i[k]].tolist())} to "
            f"{tuple(b[i[k]].tolist())}) meets edge {j[k]} ({tuple(a[j[k]].tolist())} to "
            f"{tuple(b[j[k]].tolist())})"
        )
