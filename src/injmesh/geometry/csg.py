"""Set operations on domains: ``a | b``, ``a & b``, ``a - b``.

When every operand is a boundary representation (Polygon, Rectangle, Circle, or a combination
of them), the combination computes the exact boundary of the result once (see
:mod:`.boolean`: shared edges, touching and tangent operands included) and its signed distance,
projection, corners and boundary loops are those of that exact boundary.

Otherwise (an :class:`~.implicit.Implicit` operand) the signed distance is the usual min/max
bound (exact inside for unions, outside for intersections).  Corners are then the operands'
corners that remain on the combined boundary plus the points where the operands' boundaries
cross; projection uses the operands' exact projections and keeps the nearest candidate that
lies on the combined boundary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol
from .base import BBox, Domain, FloatArray, KernelBoundary, as_points, dedupe_points
from .brep import BRep

IntArray = NDArray[np.intp]
_UNSET = object()


class _Combination(Domain):
    symbol = "?"

    def __init__(self, a: Domain, b: Domain) -> None:
        self.a = a
        self.b = b
        self._corners: FloatArray | None = None
        self._exact: object = _UNSET
        self._empty = False

    def __repr__(self) -> str:
        return f"({self.a!r} {self.symbol} {self.b!r})"

    def leaves(self) -> list[Domain]:
        """The primitive operands, left to right."""
        out: list[Domain] = []
        for child in (self.a, self.b):
            out.extend(child.leaves() if isinstance(child, _Combination) else [child])
        return out

    def exact_brep(self) -> BRep | None:
        """The exact boundary of the result when every operand is a B-rep (computed once),
        else None.

        Examples
        --------
        >>> from injmesh import Rectangle
        >>> ell = Rectangle((-1, -1), (1, 1)) - Rectangle((0, -1), (1, 0))
        >>> ell.exact_brep(), len(ell.corners())
        (BRep(<1 loops, 6 segments, 0 arcs>), 6)
        """
        if self._exact is _UNSET:
            from .boolean import EmptyResult, boolean_brep

            leaves = self.leaves()
            try:
                self._exact = boolean_brep(self) if all(isinstance(leaf, BRep) for leaf in leaves) else None
            except EmptyResult:
                self._exact, self._empty = None, True
        return self._exact  # type: ignore[return-value]

    @property
    def is_empty(self) -> bool:
        """True when the operands are B-reps and the result is known to be empty (no piece of
        any operand bounds it); False otherwise, including when that cannot be decided."""
        self.exact_brep()
        return self._empty

    @property
    def exact_distance(self) -> bool:  # type: ignore[override]
        """True when the operands are B-reps: d is then the exact distance to the result."""
        return self.exact_brep() is not None

    def sdf(self, p: FloatArray) -> FloatArray:
        exact = self.exact_brep()
        if exact is not None:
            return exact.sdf(p)
        return self._minmax(as_points(p))

    def _minmax(self, p: FloatArray) -> FloatArray:
        raise NotImplementedError

    def kernel_boundary(self) -> KernelBoundary | None:
        """That of the exact result when the operands are B-reps (:meth:`sdf` and
        :meth:`project` are its own then)."""
        exact = self.exact_brep()
        own = type(self).sdf is _Combination.sdf and type(self).project is _Combination.project
        if exact is None or not own:
            return None
        return exact.kernel_boundary()

    def gradient(self, p: FloatArray) -> FloatArray:
        exact = self.exact_brep()
        return exact.gradient(p) if exact is not None else super().gradient(p)

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        exact = self.exact_brep()
        return exact.boundary_loops(spacing) if exact is not None else super().boundary_loops(spacing)

    def cleaned(
        self, tolerance: float, *, min_feature: float | None = None, max_area: float | None = None
    ) -> tuple[Domain, dict[str, int]]:
        exact = self.exact_brep()
        if exact is None:
            return super().cleaned(tolerance)
        return exact.cleaned(tolerance, min_feature=min_feature, max_area=max_area)

    def _active(self, p: FloatArray) -> tuple[FloatArray, IntArray, FloatArray]:
        """d, the index (in :meth:`leaves`) of the leaf that attains it, and the margin: how far
        the chosen operand leads the other one at every min/max on the way down."""
        d_a, i_a, m_a = _active_of(self.a, p)
        d_b, i_b, m_b = _active_of(self.b, p)
        na = len(self.a.leaves()) if isinstance(self.a, _Combination) else 1
        d, take_a = self._combine(d_a, d_b)
        va, vb = self._values(d_a, d_b)
        lead = np.abs(va - vb)
        margin = np.minimum(np.where(take_a, m_a, m_b), lead)
        return d, np.where(take_a, i_a, na + i_b), margin

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        raise NotImplementedError

    def _values(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The two values the min or max compares."""
        return da, db

    def project(self, p: FloatArray) -> FloatArray:
        """Project onto the leaf whose distance is active at each point.

        Near the boundary the active leaf's boundary is the nearest; where its projection is
        not on the combined boundary (close to a corner) every leaf is tried, then Newton.  With
        exact distances (1-Lipschitz leaves) a point whose active operand leads by more than
        2|d| everywhere keeps that leaf active over the whole move to its foot, so the foot is
        on the combined boundary without checking.
        """
        exact = self.exact_brep()
        if exact is not None:
            return exact.project(p)
        p = as_points(p)
        on = tol.ON_BOUNDARY * self.diameter
        leaves = self.leaves()
        d, idx, margin = self._active(p)
        out = np.empty_like(p)
        for k, leaf in enumerate(leaves):
            sel = idx == k
            if sel.any():
                out[sel] = leaf.project(p[sel])
        check = np.ones(len(p), dtype=bool)
        if all(leaf.exact_distance for leaf in leaves):
            check = margin <= 2.0 * np.abs(d) + on
        if check.any():
            sub = np.flatnonzero(check)
            miss = sub[np.abs(self.sdf(out[sub])) >= on]
            if len(miss):
                out[miss] = self._project_search(p[miss])
        return out

    def _project_search(self, p: FloatArray) -> FloatArray:
        """Nearest on-boundary candidate among all leaves' projections and the corners (the
        foot of a point beyond a convex corner), else Newton."""
        on = tol.ON_BOUNDARY * self.diameter
        best = Domain.project(self, p)  # generic Newton, the fallback
        best_dist = np.where(np.abs(self.sdf(best)) < on, np.hypot(*(best - p).T), np.inf)
        for leaf in self.leaves():
            c = leaf.project(p)
            dist = np.where(np.abs(self.sdf(c)) < on, np.hypot(*(c - p).T), np.inf)
            better = dist < best_dist
            best[better] = c[better]
            best_dist[better] = dist[better]
        corners = self.corners()
        if len(corners):
            gap = np.hypot(*(p[:, None, :] - corners[None, :, :]).transpose(2, 0, 1))
            k = np.argmin(gap, axis=1)
            dist = gap[np.arange(len(p)), k]
            better = dist < best_dist
            best[better] = corners[k[better]]
        return best

    def corners(self) -> FloatArray:
        exact = self.exact_brep()
        if exact is not None:
            return exact.corners()
        if self._corners is None:
            self._corners = self._find_corners()
        return self._corners.copy()

    def _find_corners(self) -> FloatArray:
        leaves = self.leaves()
        cands = [leaf.corners() for leaf in leaves]
        for i in range(len(leaves)):
            for j in range(i + 1, len(leaves)):
                cands.append(_crossings(leaves[i], leaves[j]))
                cands.append(_crossings(leaves[j], leaves[i]))
        c = np.concatenate(cands) if cands else np.empty((0, 2))
        if len(c) == 0:
            return c
        return dedupe_points(c[self.on_boundary(c)], 1e-9 * self.diameter)


class Union(_Combination):
    """Points in ``a`` or ``b``."""

    symbol = "|"

    def _minmax(self, p: FloatArray) -> FloatArray:
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

    def _minmax(self, p: FloatArray) -> FloatArray:
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

    def _minmax(self, p: FloatArray) -> FloatArray:
        return np.maximum(self.a.sdf(p), -self.b.sdf(p))

    def _combine(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, NDArray[np.bool_]]:
        return np.maximum(da, -db), da >= -db

    def _values(self, da: FloatArray, db: FloatArray) -> tuple[FloatArray, FloatArray]:
        return da, -db

    @property
    def bbox(self) -> BBox:
        return self.a.bbox


def _active_of(domain: Domain, p: FloatArray) -> tuple[FloatArray, IntArray, FloatArray]:
    if isinstance(domain, _Combination):
        return domain._active(p)
    return domain.sdf(p), np.zeros(len(p), dtype=np.intp), np.full(len(p), np.inf)


def densify(loop: FloatArray, spacing: float) -> FloatArray:
    """Insert vertices on the segments of a closed polyline so none is longer than ``spacing``
    (:func:`injmesh.kernels.raster.densify`, the compiled form the background grids use)."""
    from ..kernels.raster import densify as dense

    out: FloatArray = dense(np.ascontiguousarray(loop, dtype=np.float64).reshape(-1, 2), float(spacing))
    return out


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
