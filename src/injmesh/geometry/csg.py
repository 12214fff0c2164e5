"""Set operations on domains: ``a | b``, ``a & b``, ``a - b``.

The signed distance of a combination is the usual min/max bound (exact inside for unions,
outside for intersections).  Corners are the operands' corners that remain on the combined
boundary plus the points where the operands' boundaries cross; projection uses the operands'
exact projections and keeps the nearest candidate that lies on the combined boundary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol
from .base import BBox, Domain, FloatArray, as_points

IntArray = NDArray[np.intp]


class _Combination(Domain):
    symbol = "?"

    def __init__(self, a: Domain, b: Domain) -> None:
        self.a = a
        self.b = b

    def __repr__(self) -> str:
        return f"({self.a!r} {self.symbol} {self.b!r})"

    def leaves(self) -> list[Domain]:
        """The primitive operands, left to right."""
        out: list[Domain] = []
        for child in (self.a, self.b):
            out.extend(child.leaves() if isinstance(child, _Combination) else [child])
        return out

    def _active(self, p: FloatArray) -> tuple[FloatArray, IntArray]:
        """d and the index (in :meth:`leaves`) of the leaf that attains it at each point."""
        da, ia = self.a._active(p) if isinstance(self.a, _Combination) else (self.a.sdf(p), None)
        db, ib = self.b._active(p) if isinstance(self.b, _Combination) else (self.b.sdf(p), None)
        ia = np.zeros(len(p), dtype=np.intp) if ia is None else ia
        ib = np.zeros(len(p), dtype=np.intp) if ib is None else ib
        na = len(self.a.leaves()) if isinstance(self.a, _Combination) else 1
        d, take_a = self._combine(da, db)
        return d, np.where(take_a, ia, na + ib)

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        raise NotImplementedError

    def project(self, p: FloatArray) -> FloatArray:
        """Project onto the leaf whose distance is active at each point.

        Near the boundary the active leaf's boundary is the nearest; where its projection is
        not on the combined boundary (close to a corner) every leaf is tried, then Newton.
        """
        p = as_points(p)
        on = tol.ON_BOUNDARY * self.diameter
        leaves = self.leaves()
        _, idx = self._active(p)
        out = np.empty_like(p)
        for k, leaf in enumerate(leaves):
            sel = idx == k
            if sel.any():
                out[sel] = leaf.project(p[sel])
        miss = np.abs(self.sdf(out)) >= on
        if miss.any():
            out[miss] = self._project_search(p[miss])
        return out

    def _project_search(self, p: FloatArray) -> FloatArray:
        """Nearest on-boundary candidate among all leaves' projections, else Newton."""
        on = tol.ON_BOUNDARY * self.diameter
        best = Domain.project(self, p)  # generic Newton, the fallback
        best_dist = np.where(np.abs(self.sdf(best)) < on, np.hypot(*(best - p).T), np.inf)
        for leaf in self.leaves():
            c = leaf.project(p)
            dist = np.where(np.abs(self.sdf(c)) < on, np.hypot(*(c - p).T), np.inf)
            better = dist < best_dist
            best[better] = c[better]
            best_dist[better] = dist[better]
        return best

    def corners(self) -> FloatArray:
        leaves = self.leaves()
        cands = [leaf.corners() for leaf in leaves]
        for i in range(len(leaves)):
            for j in range(i + 1, len(leaves)):
                cands.append(_crossings(leaves[i], leaves[j]))
                cands.append(_crossings(leaves[j], leaves[i]))
        c = np.concatenate(cands) if cands else np.empty((0, 2))
        if len(c) == 0:
            return c
        return _dedupe(c[self.on_boundary(c)], 1e-9 * self.diameter)


class Union(_Combination):
    """Points in ``a`` or ``b``."""

    symbol = "|"

    def sdf(self, p: FloatArray) -> FloatArray:
        return np.minimum(self.a.sdf(p), self.b.sdf(p))

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        return np.minimum(da, db), da <= db

    @property
    def bbox(self) -> BBox:
        a, b = self.a.bbox, self.b.bbox
        return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


class Intersection(_Combination):
    """Points in both ``a`` and ``b``."""

    symbol = "&"

    def sdf(self, p: FloatArray) -> FloatArray:
        return np.maximum(self.a.sdf(p), self.b.sdf(p))

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        return np.maximum(da, db), da >= db

    @property
    def bbox(self) -> BBox:
        a, b = self.a.bbox, self.b.bbox
        return (max(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), min(a[3], b[3]))


class Difference(_Combination):
    """Points in ``a`` but not in ``b``."""

    symbol = "-"

    def sdf(self, p: FloatArray) -> FloatArray:
        return np.maximum(self.a.sdf(p), -self.b.sdf(p))

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        return np.maximum(da, -db), da >= -db

    @property
    def bbox(self) -> BBox:
        return self.a.bbox


def _dedupe(p: FloatArray, eps: float) -> FloatArray:
    """Drop points within ``eps`` of an earlier one (order kept)."""
    from scipy.spatial import cKDTree

    if len(p) < 2:
        return p
    pairs = cKDTree(p).query_pairs(eps, output_type="ndarray")
    drop = np.zeros(len(p), dtype=bool)
    drop[pairs.max(axis=1)] = True
    return p[~drop]


def densify(loop: FloatArray, spacing: float) -> FloatArray:
    """Insert vertices on the segments of a closed polyline so none is longer than ``spacing``."""
    nxt = np.roll(loop, -1, axis=0)
    pieces = np.maximum(1, np.ceil(np.hypot(*(nxt - loop).T) / spacing)).astype(int)
    seg = np.repeat(np.arange(len(loop)), pieces)
    t = np.arange(len(seg)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    t = t / pieces[seg]
    return loop[seg] + t[:, None] * (nxt[seg] - loop[seg])


def _crossings(a: Domain, b: Domain) -> FloatArray:
    """Points where the boundaries of ``a`` and ``b`` cross.

    Sign changes of ``d_b`` along a fine polyline of ``a``'s boundary bracket each crossing;
    Newton's method on ``(d_a, d_b) = 0`` then makes it exact.  Tangencies, where no sign
    changes, are not crossings: the boundary is smooth there.
    """
    diam = max(a.diameter, b.diameter)
    spacing = diam / 2000
    out = []
    for loop in a.boundary_loops(spacing):
        loop = densify(loop, spacing)
        db = b.sdf(loop)
        nxt = np.roll(np.arange(len(loop)), -1)
        s = np.sign(db)
        k = np.flatnonzero((s != s[nxt]) & (s != 0) & (s[nxt] != 0))
        exact = loop[s == 0]
        if len(k):
            t = db[k] / (db[k] - db[nxt[k]])
            out.append(loop[k] + t[:, None] * (loop[nxt[k]] - loop[k]))
        if len(exact):
            out.append(exact)
    if not out:
        return np.empty((0, 2))
    p = np.concatenate(out)
    for _ in range(tol.PROJECTION_ITERATIONS):
        f = np.stack([a.sdf(p), b.sdf(p)], axis=1)
        ga, gb = a.gradient(p), b.gradient(p)
        det = ga[:, 0] * gb[:, 1] - ga[:, 1] * gb[:, 0]
        ok = np.abs(det) > 1e-8
        safe = np.where(ok, det, 1.0)
        dx = (f[:, 0] * gb[:, 1] - f[:, 1] * ga[:, 1]) / safe
        dy = (ga[:, 0] * f[:, 1] - gb[:, 0] * f[:, 0]) / safe
        p = p - np.where(ok[:, None], np.stack([dx, dy], axis=1), 0.0)
    res = np.abs(a.sdf(p)) + np.abs(b.sdf(p))
    return p[res < tol.ON_BOUNDARY * diam]
