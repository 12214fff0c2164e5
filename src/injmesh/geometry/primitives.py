"""Primitives with exact signed distances, projections, corners and boundary loops."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _tolerances as tol
from .base import BBox, FloatArray, GeometryError, KernelBoundary, as_points, ring_next, ring_prev
from .brep import BRep


class Circle(BRep):
    """The disc of radius ``r`` centred at ``center``.

    Examples
    --------
    >>> Circle((0, 0), 1).sdf([[0, 0], [2, 0]])
    array([-1.,  1.])
    """

    def __init__(self, center: Sequence[float], r: float) -> None:
        c = np.asarray(center, dtype=float).reshape(-1)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise GeometryError(f"Circle center must be two finite numbers, got {center!r}")
        if not (math.isfinite(r) and r > 0):
            raise GeometryError(f"Circle radius must be positive, got {r!r}")
        self.center = c
        self.r = float(r)
        # Two half circles (distinct end points) as the B-rep used by set operations.
        east, west = c + [self.r, 0.0], c - [self.r, 0.0]
        self._set_pieces(np.stack([east, west]), np.stack([west, east]), np.stack([c, c]),
                         np.array([math.pi, math.pi]), np.array([0, 2]), origin=c)

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

    def kernel_boundary(self) -> KernelBoundary | None:
        """Kind 1, the closed formulas of :meth:`sdf` and :meth:`project` (see
        :meth:`~injmesh.geometry.base.Domain.kernel_boundary`)."""
        if type(self).sdf is not Circle.sdf or type(self).project is not Circle.project:
            return None
        origin, g = self.kernel_data()
        return 1, np.array([self.center[0], self.center[1], self.r]), origin, g

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        n = max(16, math.ceil(2 * math.pi * self.r / spacing))
        t = np.linspace(0, 2 * math.pi, n, endpoint=False)
        return [self.center + self.r * np.stack([np.cos(t), np.sin(t)], axis=1)]


class Polygon(BRep):
    """A polygon with holes: one outer ring (the shell) and any number of inner rings.

    The rings may be given in either orientation; the shell is stored counter-clockwise and the
    holes clockwise.  No two edges may cross or touch (except consecutive edges of a ring at
    their common vertex), every hole must lie inside the shell and outside the other holes.
    The signed distance and the projection are exact (nearest edge through a bounding-volume
    hierarchy); vertices where the boundary turns by more than ``CORNER_ANGLE`` degrees are
    corners.

    Parameters
    ----------
    shell : (k, 2) array_like
        At least three vertices; a closing vertex equal to the first is dropped, as are
        repeated consecutive vertices.
    holes : sequence of (k, 2) array_like, optional
        The inner rings.

    Raises
    ------
    GeometryError
        Fewer than three distinct vertices, non-finite coordinates, zero area, edges that cross
        or touch (naming both edges and their coordinates), a hole outside the shell or inside
        another hole.

    Examples
    --------
    >>> tri = Polygon([(0, 0), (1, 0), (0, 1)])
    >>> float(tri.sdf([[0.25, 0.25]])[0])
    -0.25
    >>> frame = Polygon([(0, 0), (3, 0), (3, 3), (0, 3)], holes=[[(1, 1), (2, 1), (2, 2), (1, 2)]])
    >>> frame.area
    8.0
    """

    def __init__(self, shell: ArrayLike, holes: Sequence[ArrayLike] | None = None) -> None:
        read = [_read_ring(shell, "shell")]
        read += [_read_ring(h, f"hole {k}") for k, h in enumerate(holes or [])]
        names = ["shell"] + [f"hole {k}" for k in range(len(read) - 1)]
        self._build([r for r, _ in read], names, depth=None, dropped=sum(n for _, n in read))

    @classmethod
    def from_rings(cls, rings: Sequence[ArrayLike]) -> Polygon:
        """A set of polygons from rings in any orientation: a ring inside an odd number of
        others is a hole, inside an even number an outer boundary (islands in lakes).

        Examples
        --------
        >>> two = Polygon.from_rings([[(0, 0), (1, 0), (1, 1)], [(2, 0), (3, 0), (3, 1)]])
        >>> two.area
        1.0
        """
        read = [_read_ring(r, f"ring {k}") for k, r in enumerate(rings)]
        if not read:
            raise GeometryError("a polygon needs at least one ring")
        obj = cls.__new__(cls)
        obj._build([r for r, _ in read], [f"ring {k}" for k in range(len(read))], depth="nesting",
                   dropped=sum(n for _, n in read))
        return obj

    def _build(
        self, raw: list[FloatArray], names: list[str], depth: str | None, dropped: int, check: bool = True
    ) -> None:
        """Validate the rings, orient them, and store them as the pieces of a B-rep."""
        allv = np.concatenate(raw)
        origin = 0.5 * (allv.min(axis=0) + allv.max(axis=0))
        local = [r - origin for r in raw]
        for ring, name in zip(local, names, strict=True):
            area = _shoelace(ring)
            extent = float(np.ptp(ring, axis=0).max())
            if not abs(area) > tol.ZERO_AREA * extent * extent:
                raise GeometryError(f"Polygon {name} has zero area")
        n = len(local)
        inside = np.zeros((n, n), dtype=bool)
        if check:  # a Rectangle is known to be simple
            _check_rings(local, names, origin)
            inside = _containment(local)
        if depth is None and check:
            for k in range(1, n):
                if not inside[k, 0]:
                    raise GeometryError(f"Polygon {names[k]} lies outside the shell")
                for j in range(1, n):
                    if j != k and inside[k, j]:
                        raise GeometryError(f"Polygon {names[k]} lies inside {names[j]}")
            levels = np.r_[0, np.ones(n - 1, dtype=int)]
        else:
            levels = inside.sum(axis=1)
        reoriented = 0
        for k in range(n):
            ccw = _shoelace(local[k]) > 0
            if ccw != (levels[k] % 2 == 0):
                local[k] = local[k][::-1].copy()
                reoriented += 1
        self._rings_local = local
        self._mode = depth
        self._names = names
        self._report = {"reoriented_rings": reoriented, "zero_length_edges": dropped}
        p0 = np.concatenate(local)
        p1 = np.concatenate([ring_next(r) for r in local])
        loop_start = np.r_[0, np.cumsum([len(r) for r in local])]
        self._set_local(p0, p1, np.zeros_like(p0), np.zeros(len(p0)), loop_start, origin)

    def __repr__(self) -> str:
        holes = f", {len(self._rings_local) - 1} holes" if len(self._rings_local) > 1 else ""
        return f"Polygon(<{len(self._rings_local[0])} vertices{holes}>)"

    @property
    def rings(self) -> list[FloatArray]:
        """Every ring with the domain on its left (outer rings counter-clockwise)."""
        return [r + self._origin for r in self._rings_local]

    @property
    def vertices(self) -> FloatArray:
        """The first ring (the shell), counter-clockwise."""
        return self._rings_local[0] + self._origin

    @property
    def holes(self) -> list[FloatArray]:
        """The rings after the first, clockwise for the holes of a single polygon."""
        return [r + self._origin for r in self._rings_local[1:]]

    def cleaned(
        self, tolerance: float, *, min_feature: float | None = None, max_area: float | None = None
    ) -> tuple[Polygon, dict[str, int]]:
        """This polygon with its defects below ``tolerance`` removed, and what changed.

        Consecutive vertices closer than ``tolerance`` are merged (the first of a run is kept),
        vertices where the boundary doubles back within ``tolerance`` (collinear spikes) are
        dropped, and a hole that collapses is dropped.  The counts also include the repeated
        vertices dropped and the rings reoriented when the polygon was built.

        Then, with ``min_feature``, the *pinches*: wherever the outline comes within
        ``min_feature`` of itself -- a neck of the domain narrower than that,
        or a gap of its outside (an inlet's mouth, an island or a hole almost touching another
        ring) -- the outline is cut there and the smaller part beyond (by area) is dropped: a
        lobe or an island removed, a pocket or a hole filled.  On one ring the cut joins the
        two sides at the midpoint of the pinch, one vertex.  A pinch on one ring counts only
        when the part beyond it is not a wedge (see ``PINCH_DETOUR``, ``PINCH_WIDENS``): the
        tip of a sharp corner is kept.  Each dropped part is listed in
        :attr:`dropped_parts` of the result and counted as ``pinched_parts``.

        Parameters
        ----------
        tolerance : float
            Vertices closer than this merge; spikes thinner than this are dropped.
        min_feature : float, optional
            Pinches narrower than this are cut (default: none is; 0 likewise).
        max_area : float, optional
            A part larger than this is not dropped: :class:`GeometryError` (default: no limit).

        Raises
        ------
        GeometryError
            The cleaned polygon would be invalid (its edges would cross, or its shell
            collapses): cleaning never changes the topology silently; or the part beyond a
            pinch is larger than ``max_area``.

        Examples
        --------
        >>> p = Polygon([(0, 0), (1, 0), (1.0000005, 0.0000006), (0.6, 1), (0, 1)])
        >>> q, report = p.cleaned(1e-5)
        >>> len(q.vertices), report["merged_vertices"]
        (4, 1)

        A square lobe joined to the unit square by a neck 1e-4 wide is dropped:

        >>> lobe = Polygon([(0, 0), (1, 0), (1, 0.5), (1.1, 0.5), (1.1, 0.4), (1.2, 0.4), (1.2, 0.6),
        ...                 (1.1, 0.6), (1.1, 0.5001), (1, 0.5001), (1, 1), (0, 1)])
        >>> q, report = lobe.cleaned(1e-5, min_feature=1e-3)
        >>> report["pinched_parts"], round(q.area, 6), q.dropped_parts[0][:2]
        (1, 1.0, (1.0, 0.50005))
        """
        if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance >= 0):
            raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
        width = 0.0 if min_feature is None else min_feature
        if not (isinstance(width, (int, float)) and math.isfinite(width) and width >= 0):
            raise ValueError(f"min_feature must be a finite number >= 0, got {min_feature!r}")
        limit = math.inf if max_area is None else float(max_area)
        report = dict(self._report)
        report.update(merged_vertices=0, spikes=0, dropped_rings=0, pinched_parts=0)
        rings, names = self._clean_rings(self._rings_local, self._names, tolerance, report)
        dropped: list[tuple[float, float, float, float]] = []
        if width > 0 and rings:
            pinched, dropped, too_large = _pinch_rings(rings, width, limit)
            if too_large:
                x, y, gap, area = min(too_large, key=lambda w: w[2])
                raise GeometryError(
                    f"the outline comes within {gap:.3g} of itself at ({x + self._origin[0]:.9g}, "
                    f"{y + self._origin[1]:.9g}), narrower than min_feature={width:.3g}, and the part "
                    f"beyond it (area {area:.3g}) is larger than max_area={limit:.3g}: pass a "
                    f"min_feature below {gap:.3g} to mesh it, or a larger max_area to drop it"
                    + (f" ({len(too_large)} such places)" if len(too_large) > 1 else "")
                )
            if dropped:
                report["pinched_parts"] = len(dropped)
                # The cut leaves a vertex at each pinch: merge and drop spikes round it again.
                rings, names = self._clean_rings(pinched, [f"ring {k}" for k in range(len(pinched))],
                                                 tolerance, report)
        changed = ("merged_vertices", "spikes", "dropped_rings", "pinched_parts")
        if not any(report[k] for k in changed):
            self.dropped_parts = ()
            return self, report
        if not rings:
            raise GeometryError(f"every ring of the Polygon collapses at tolerance {tolerance:g}")
        obj = Polygon.__new__(Polygon)
        mode = self._mode if not dropped else "nesting"
        try:
            obj._build([r + self._origin for r in rings], names, depth=mode, dropped=0)
        except GeometryError as exc:
            raise GeometryError(
                f"cleaning the Polygon at tolerance {tolerance:g} would make it invalid: {exc}"
            ) from exc
        obj._report = report
        obj.dropped_parts = tuple((x + float(self._origin[0]), y + float(self._origin[1]), g, a)
                                  for x, y, g, a in dropped)
        return obj, report

    #: Parts dropped at pinches by :meth:`cleaned`: ``(x, y, gap, area)`` each, the pinch's
    #: midpoint, its width and the area of the part.
    dropped_parts: tuple[tuple[float, float, float, float], ...] = ()

    def _clean_rings(
        self, local: list[FloatArray], names: list[str], tolerance: float, report: dict[str, int]
    ) -> tuple[list[FloatArray], list[str]]:
        rings, kept = [], []
        for k, ring in enumerate(local):
            out, merged, spikes = _clean_ring(ring, tolerance)
            report["merged_vertices"] += merged
            report["spikes"] += spikes
            if len(out) < 3 or abs(_shoelace(out)) <= tolerance * _perimeter(out):
                if k == 0 and self._mode is None:
                    raise GeometryError(
                        f"the Polygon's shell collapses when cleaned at tolerance {tolerance:g}"
                    )
                report["dropped_rings"] += 1
                continue
            rings.append(out)
            kept.append(names[k])
        return rings, kept


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
        self._build([np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])], ["shell"], None, 0, check=False)
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

    def kernel_boundary(self) -> KernelBoundary | None:
        """Kind 2, the closed formulas of :meth:`sdf` and :meth:`project` (see
        :meth:`~injmesh.geometry.base.Domain.kernel_boundary`)."""
        if type(self).sdf is not Rectangle.sdf or type(self).project is not Rectangle.project:
            return None
        origin, g = self.kernel_data()
        return 2, np.concatenate([self.lo, self.hi]), origin, g

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
    v = v - v[0]  # relative to a vertex of its own: no cancellation far from the origin
    x, y = v[:, 0], v[:, 1]
    # Sums, not np.dot: BLAS splits a long dot product among its threads (the result then
    # depends on their number) and waits for them (milliseconds on a busy machine).
    return 0.5 * float(np.sum(x * ring_next(y)) - np.sum(y * ring_next(x)))


def _read_ring(vertices: ArrayLike, name: str) -> tuple[FloatArray, int]:
    """A ring as a ``(k, 2)`` array: closing vertex and repeated consecutive vertices dropped
    (only exact repeats; near-repeats are for :meth:`Domain.cleaned`)."""
    v = np.asarray(vertices, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2:
        raise GeometryError(f"Polygon {name}: vertices must have shape (k, 2), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise GeometryError(f"Polygon {name}: vertices must be finite")
    keep = np.any(v != ring_next(v), axis=1) if len(v) > 1 else np.ones(len(v), dtype=bool)
    if len(v) and not keep.any():
        keep[0] = True
    out = v[keep]
    if len(out) < 3:
        raise GeometryError(f"a Polygon needs at least 3 distinct vertices, got {len(out)} in its {name}")
    closing = len(v) > 1 and bool(np.all(v[0] == v[-1]))  # the usual closed-ring notation
    return out, len(v) - len(out) - int(closing)


def _perimeter(v: FloatArray) -> float:
    return float(np.sum(np.hypot(*(ring_next(v) - v).T)))


def _clean_ring(ring: FloatArray, tolerance: float) -> tuple[FloatArray, int, int]:
    """Merge consecutive vertices closer than ``tolerance`` and drop spikes, until neither
    applies.  Returns the ring and the counts of merged vertices and spikes."""
    from ..kernels.outline import merge_close

    merged = spikes = 0
    v = ring
    for _ in range(len(ring) + 1):
        # Merge runs of close vertices into their first vertex (compiled: a sequential walk).
        keep = merge_close(np.ascontiguousarray(v), float(tolerance))
        merged += len(v) - len(keep)
        v = v[keep]
        if len(v) < 3:
            break
        # Spikes: the nearer neighbour lies within tolerance of the other edge, on the same side.
        u, w = ring_prev(v) - v, ring_next(v) - v
        lu, lw = np.hypot(*u.T), np.hypot(*w.T)
        near = np.where((lu <= lw)[:, None], u, w)
        far = np.where((lu <= lw)[:, None], w, u)
        lfar = np.maximum(np.maximum(lu, lw), 1e-300)
        t = np.clip(np.einsum("ij,ij->i", near, far) / (lfar * lfar), 0.0, 1.0)
        gap = np.hypot(*(near - t[:, None] * far).T)
        spike = (np.einsum("ij,ij->i", u, w) > 0) & (gap < tolerance)
        # Remove no two neighbours at once: the second may not be a spike afterwards.
        spike &= ~ring_prev(spike) | (np.arange(len(v)) == 0)
        if spike[0] and spike[-1]:
            spike[-1] = False
        if not spike.any():
            break
        spikes += int(spike.sum())
        v = v[~spike]
        if len(v) < 3:
            break
    return v, merged, spikes


def _ring_edges(
    local: list[FloatArray],
) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.int64]]:
    a = np.ascontiguousarray(np.concatenate(local))
    b = np.ascontiguousarray(np.concatenate([ring_next(r) for r in local]))
    start = np.r_[0, np.cumsum([len(r) for r in local])]
    ring = np.repeat(np.arange(len(local)), np.diff(start)).astype(np.int64)
    idx = np.arange(len(a))
    nxt = np.where(idx == start[ring + 1] - 1, start[ring], idx + 1).astype(np.int64)
    return a, b, ring, nxt


def _check_rings(local: list[FloatArray], names: list[str], origin: FloatArray) -> None:
    """Raise if two edges of the rings cross, touch or overlap (an O(n log n) sweep)."""
    from ..kernels.brep import first_crossing

    a, b, ring, nxt = _ring_edges(local)
    i, j = first_crossing(a, b, nxt)
    if i < 0:
        return
    start = np.r_[0, np.cumsum([len(r) for r in local])]

    def edge(k: int) -> str:
        p, q = a[k] + origin, b[k] + origin
        return (f"edge {k - start[ring[k]]} of the {names[ring[k]]} ({p[0]:.17g}, {p[1]:.17g}) to "
                f"({q[0]:.17g}, {q[1]:.17g})")

    i, j = sorted((int(i), int(j)))
    raise GeometryError(f"Polygon is not simple: {edge(i)} meets {edge(j)}")


def _containment(local: list[FloatArray]) -> NDArray[np.bool_]:
    """``inside[i, j]``: ring i lies inside ring j (rings known not to meet)."""
    from ..kernels.brep import containment

    a, b, ring, _ = _ring_edges(local)
    first = np.ascontiguousarray(np.stack([r[0] for r in local]))
    inside = containment(first, a, b, ring, len(local))
    np.fill_diagonal(inside, False)
    return inside


#: A place where the outline comes within ``min_feature`` of itself is a *pinch* when the part
#: beyond it is not a wedge: the boundary round that part is at least PINCH_DETOUR times the
#: gap (as :data:`injmesh.sizing.features.GAP_DETOUR`), and the part is on average at least
#: PINCH_WIDENS times as wide as the gap (2 area / boundary length; a sharp wedge, narrowing
#: steadily to its tip, is half as wide as its base on average).
PINCH_DETOUR = 20.0
PINCH_WIDENS = 1.0
#: Rounds of pinching (pinches inside a part cut off in the same round wait for the next).
PINCH_ROUNDS = 32

_Place = tuple[float, float, float, float]


def _segment_gaps(
    a: FloatArray, b: FloatArray, i: NDArray[np.int64], j: NDArray[np.int64]
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Distance between segments ``a[i] b[i]`` and ``a[j] b[j]`` (which do not cross), the
    nearest points on each, and their parameters along each segment."""
    pi, qi, pj, qj = a[i], b[i], a[j], b[j]

    def foot(p: FloatArray, s0: FloatArray, s1: FloatArray) -> tuple[FloatArray, FloatArray]:
        d = s1 - s0
        t = np.einsum("kj,kj->k", p - s0, d) / np.maximum(np.einsum("kj,kj->k", d, d), 1e-300)
        t = np.clip(t, 0.0, 1.0)
        return t, s0 + t[:, None] * d

    # Non-crossing segments: the nearest pair has an end point of one of them.
    cands = []
    for p, s0, s1, on_i in ((pi, pj, qj, True), (qi, pj, qj, True), (pj, pi, qi, False), (qj, pi, qi, False)):
        t, f = foot(p, s0, s1)
        dist = np.hypot(*(p - f).T)
        cands.append((dist, p, f, t, on_i))
    dist = np.stack([c[0] for c in cands])
    best = np.argmin(dist, axis=0)
    rows = np.arange(len(i))
    gap = dist[best, rows]
    x_i = np.empty((len(i), 2))
    x_j = np.empty((len(i), 2))
    t_i = np.empty(len(i))
    t_j = np.empty(len(i))
    ends = (0.0, 1.0, 0.0, 1.0)
    for k, (_, p, f, t, on_i) in enumerate(cands):
        sel = best == k
        if on_i:  # the end point is on segment i, the foot on segment j
            x_i[sel], x_j[sel], t_i[sel], t_j[sel] = p[sel], f[sel], ends[k], t[sel]
        else:
            x_i[sel], x_j[sel], t_i[sel], t_j[sel] = f[sel], p[sel], t[sel], ends[k]
    return gap, x_i, x_j, t_i, t_j


def _pinch_rings(
    local: list[FloatArray], width: float, max_area: float
) -> tuple[list[FloatArray], list[_Place], list[_Place]]:
    """Cut the rings where they come within ``width`` of themselves or of each other, and drop
    the smaller part beyond each such pinch (see :meth:`Polygon.cleaned`).

    Returns the rings, the parts dropped as ``(x, y, gap, area)`` (the pinch's midpoint, local
    coordinates) and the pinches whose smaller part is larger than ``max_area`` (not cut).
    """
    from ..kernels.brep import LEAF, box_pairs, build_bvh

    rings = [r.copy() for r in local]
    dropped: list[tuple[float, float, float, float]] = []
    too_large: list[tuple[float, float, float, float]] = []
    for _ in range(PINCH_ROUNDS):
        a, b, ring, nxt = _ring_edges(rings)
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        tree = build_bvh(lo, hi, LEAF)
        pairs = box_pairs(lo, hi, *tree, float(width))  # type: ignore[call-arg]
        i, j = pairs[:, 0], pairs[:, 1]
        keep = (i < j) & (nxt[i] != j) & (nxt[j] != i)
        i, j = i[keep], j[keep]
        if not len(i):
            break
        gap, x_i, x_j, t_i, t_j = _segment_gaps(a, b, i, j)
        close = gap < width
        i, j, gap, x_i, x_j = i[close], j[close], gap[close], x_i[close], x_j[close]
        t_i, t_j = t_i[close], t_j[close]
        if not len(i):
            break
        start = np.r_[0, np.cumsum([len(r) for r in rings])]
        # Per ring: prefix sums of the shoelace terms and of the edge lengths.
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        length = np.hypot(*(b - a).T)
        ccum = np.r_[0.0, np.cumsum(cross)]
        lcum = np.r_[0.0, np.cumsum(length)]
        ring_area = np.array([0.5 * (ccum[start[k + 1]] - ccum[start[k]]) for k in range(len(rings))])
        ring_len = np.array([lcum[start[k + 1]] - lcum[start[k]] for k in range(len(rings))])
        same = ring[i] == ring[j]
        # The part between the two pinch points along the ring (from x_i through vertex i+1 to
        # vertex j, then x_j): its shoelace area and boundary length.
        between = (ccum[j] - ccum[i + 1]) * 0.5
        c_i = 0.5 * (x_i[:, 0] * b[i, 1] - x_i[:, 1] * b[i, 0])
        c_j = 0.5 * (a[j, 0] * x_j[:, 1] - a[j, 1] * x_j[:, 0])
        chord = 0.5 * (x_j[:, 0] * x_i[:, 1] - x_j[:, 1] * x_i[:, 0])
        area_in = np.where(same, c_i + between + c_j + chord, 0.0)
        arc_in = (lcum[j] - lcum[i + 1]) + (1.0 - t_i) * length[i] + t_j * length[j]
        area_out = ring_area[ring[i]] - area_in
        arc_out = ring_len[ring[i]] - arc_in
        inner = np.abs(area_in) <= np.abs(area_out)  # drop the part between i and j
        part_area = np.where(inner, np.abs(area_in), np.abs(area_out))
        part_arc = np.where(inner, arc_in, arc_out)
        # Two rings: the smaller ring is the part.
        small_j = np.abs(ring_area[ring[j]]) <= np.abs(ring_area[ring[i]])
        other = np.where(small_j, ring[j], ring[i])
        part_area = np.where(same, part_area, np.abs(ring_area[other]))
        part_arc = np.where(same, part_arc, ring_len[other])
        fat = 2.0 * part_area >= PINCH_WIDENS * gap * part_arc
        pinch = ~same | ((part_arc >= PINCH_DETOUR * gap) & fat)
        if not pinch.any():
            break
        sel = np.flatnonzero(pinch)
        sel = sel[np.lexsort((j[sel], i[sel], gap[sel]))]
        taken = np.zeros(len(a), dtype=bool)  # edges changed this round
        gone = np.zeros(len(rings), dtype=bool)
        cuts: dict[int, list[tuple[int, int, FloatArray, bool]]] = {}
        for s in sel.tolist():
            ii, jj = int(i[s]), int(j[s])
            mid = 0.5 * (x_i[s] + x_j[s])
            where = (float(mid[0]), float(mid[1]), float(gap[s]), float(part_area[s]))
            if part_area[s] > max_area:
                too_large.append(where)
                continue
            if not same[s]:
                k = int(other[s])
                if gone[ring[ii]] or gone[ring[jj]] or taken[ii] or taken[jj] or k in cuts:
                    continue
                gone[k] = True
                taken[start[k]:start[k + 1]] = True
                dropped.append(where)
                continue
            k = int(ring[ii])
            if gone[k]:
                continue
            if inner[s]:
                span = np.arange(ii, jj + 1)
            else:
                span = np.r_[np.arange(jj, start[k + 1]), np.arange(start[k], ii + 1)]
            if taken[span].any():
                continue
            taken[span] = True
            cuts.setdefault(k, []).append((ii - int(start[k]), jj - int(start[k]), mid, bool(inner[s])))
            dropped.append(where)
        if not cuts and not gone.any():
            break
        new = []
        for k, r in enumerate(rings):
            if gone[k]:
                continue
            if k in cuts:
                # One vertex at each pinch replaces the dropped part (and the pinch's sides).
                keep = np.ones(len(r), dtype=bool)
                at, mids = [], []
                for li, lj, mid, inner_part in cuts[k]:
                    if inner_part:
                        keep[li + 1: lj + 1] = False
                    else:
                        keep[lj + 1:] = False
                        keep[: li + 1] = False
                    at.append(lj + 0.5 if not inner_part else li + 0.5)
                    mids.append(mid)
                key = np.r_[np.flatnonzero(keep).astype(float), at]
                r = np.concatenate([r[keep], np.array(mids)])[np.argsort(key, kind="stable")]
            new.append(r)
        rings = new
    return rings, dropped, too_large
