"""A flat boundary representation: closed loops of line segments and circular arcs.

Polygons, rectangles, circles and set operations on them all become a :class:`BRep`: the pieces
of the boundary in flat arrays, in coordinates local to the geometry (a reference point is
subtracted, so areas, orientations and distances keep their precision however far the domain
lies from the origin), and a bounding-volume hierarchy over them.  Compiled kernels
(:mod:`injmesh.kernels.brep`) then give the exact signed distance (the paper's d in Eq. 2.1),
the exact projection onto the boundary (Eq. 3.2) and the gradient of d without Python loops.

Every loop has the domain on its left: outer boundaries run counter-clockwise, holes
clockwise.  Corners are the junctions of consecutive pieces where the direction of travel turns
by more than ``CORNER_ANGLE`` degrees.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol
from .base import BBox, Domain, FloatArray, KernelBoundary, as_points

IntArray = NDArray[np.intp]


def _kernels() -> Any:
    from ..kernels import brep

    return brep


def _sliver_width(start: FloatArray, centre: FloatArray, sweep: FloatArray, arc_steps: int = 16) -> float:
    """Twice the area over the perimeter of a loop of pieces (each from ``start[i]`` to the next
    start, an arc of ``sweep[i]`` about ``centre[i]`` or a segment when 0): the width of a
    strip; arcs sampled at ``arc_steps`` points."""
    pts = []
    for i in range(len(start)):
        if sweep[i] == 0:
            pts.append(start[i:i + 1])
            continue
        r = float(np.hypot(*(start[i] - centre[i])))
        a0 = math.atan2(start[i, 1] - centre[i, 1], start[i, 0] - centre[i, 0])
        t = a0 + sweep[i] * np.arange(arc_steps) / arc_steps
        pts.append(centre[i] + r * np.stack([np.cos(t), np.sin(t)], axis=1))
    from .primitives import _perimeter, _shoelace

    loop = np.concatenate(pts)
    perimeter = _perimeter(loop)
    return 2.0 * abs(_shoelace(loop)) / perimeter if perimeter > 0 else 0.0


class BRep(Domain):
    """A domain bounded by closed loops of segments and circular arcs (the domain on the left).

    Built by :class:`Polygon`, :class:`Circle` and by set operations whose operands are all
    B-reps; not usually constructed directly.

    Parameters
    ----------
    p0, p1 : (m, 2) arrays
        Start and end point of each piece, in global coordinates.
    center : (m, 2) array
        Centre of each arc (ignored for segments).
    sweep : (m,) array
        Signed angle an arc turns through (positive counter-clockwise); 0 for a segment.
    loop_start : (L + 1,) int array
        Pieces ``loop_start[k]:loop_start[k + 1]`` form loop k, in order.
    origin : (2,) array, optional
        The reference point subtracted from all coordinates (default: the centre of the pieces'
        box).

    Examples
    --------
    >>> from injmesh import Circle, Rectangle
    >>> b = (Rectangle((0, 0), (2, 2)) - Circle((2, 2), 1)).exact_brep()
    >>> b
    BRep(<1 loops, 4 segments, 1 arcs>)
    >>> b.sdf([[1.0, 0.5]]), b.corners().round(3).tolist()
    (array([-0.5]), [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 2.0], [0.0, 2.0]])
    """

    exact_distance = True

    def __init__(
        self,
        p0: FloatArray,
        p1: FloatArray,
        center: FloatArray,
        sweep: FloatArray,
        loop_start: IntArray,
        origin: FloatArray | None = None,
    ) -> None:
        self._set_pieces(p0, p1, center, sweep, loop_start, origin)

    def _set_pieces(
        self,
        p0: FloatArray,
        p1: FloatArray,
        center: FloatArray,
        sweep: FloatArray,
        loop_start: IntArray,
        origin: FloatArray | None = None,
    ) -> None:
        """Store pieces given in global coordinates."""
        p0 = np.asarray(p0, dtype=float).reshape(-1, 2)
        p1 = np.asarray(p1, dtype=float).reshape(-1, 2)
        if origin is None:
            allp = np.concatenate([p0, p1])
            origin = 0.5 * (allp.min(axis=0) + allp.max(axis=0))
        o = np.asarray(origin, dtype=float)
        c = np.asarray(center, dtype=float).reshape(-1, 2) - o
        self._set_local(p0 - o, p1 - o, c, sweep, loop_start, o)

    def _set_local(
        self,
        p0: FloatArray,
        p1: FloatArray,
        center: FloatArray,
        sweep: FloatArray,
        loop_start: IntArray,
        origin: FloatArray,
    ) -> None:
        """Store pieces given in coordinates local to ``origin``."""
        self._origin = np.asarray(origin, dtype=float).copy()
        self._p0 = np.ascontiguousarray(p0, dtype=float)
        self._p1 = np.ascontiguousarray(p1, dtype=float)
        self._sw = np.ascontiguousarray(np.asarray(sweep, dtype=float))
        arc = self._sw != 0
        self._c = np.ascontiguousarray(np.where(arc[:, None], center, 0.0))
        self._r = np.where(arc, np.hypot(*(self._p0 - self._c).T), 0.0)
        rel = self._p0 - self._c
        self._a0 = np.where(arc, np.arctan2(rel[:, 1], rel[:, 0]), 0.0)
        self._loop_start = np.asarray(loop_start, dtype=np.int64)
        m = len(self._p0)
        idx = np.arange(m)
        loop = np.repeat(np.arange(len(self._loop_start) - 1), np.diff(self._loop_start))
        first, last = self._loop_start[loop], self._loop_start[loop + 1] - 1
        self._loop = loop
        self._nxt = np.where(idx == last, first, idx + 1).astype(np.int64)
        self._prv = np.where(idx == first, last, idx - 1).astype(np.int64)
        self._index: tuple[Any, ...] | None = None
        self._box: BBox | None = None
        self._corners_cache: FloatArray | None = None

    # --- construction helpers ---------------------------------------------------------------

    @property
    def n_pieces(self) -> int:
        """Number of pieces (segments and arcs)."""
        return len(self._p0)

    @property
    def loop_start(self) -> IntArray:
        """Pieces ``loop_start[k]:loop_start[k + 1]`` form loop k (a copy)."""
        return np.asarray(self._loop_start, dtype=np.intp).copy()

    @property
    def n_loops(self) -> int:
        """Number of closed loops."""
        return len(self._loop_start) - 1

    def __repr__(self) -> str:
        arcs = int(np.count_nonzero(self._sw))
        return f"BRep(<{self.n_loops} loops, {self.n_pieces - arcs} segments, {arcs} arcs>)"

    def _global_pieces(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, IntArray]:
        o = self._origin
        return self._p0 + o, self._p1 + o, self._c + o, self._sw.copy(), self._loop_start.copy()

    # --- the index and the queries ----------------------------------------------------------

    def _bvh(self) -> tuple[Any, ...]:
        if self._index is None:
            k = _kernels()
            lo, hi = k.piece_boxes(self._p0, self._p1, self._c, self._r, self._a0, self._sw)
            tree = k.build_bvh(lo, hi, k.QUERY_LEAF)
            order = tree[-1]
            leaf = tuple(np.ascontiguousarray(a[order]) for a in (self._p0, self._p1, self._c, self._r,
                                                                  self._a0, self._sw))
            table = k.leaf_table(*leaf[:4], leaf[5])
            boxes = np.ascontiguousarray(np.concatenate([tree[0], tree[1]], axis=1))
            links = k.tree_links(tree[2], tree[3], tree[4], len(order))
            side = k.side_table(self._p0, self._p1, self._c, self._sw, self._prv, self._nxt, order)
            self._index = (lo, hi, *tree, leaf, table, boxes, *links, side)
        return self._index

    def kernel_data(self) -> tuple[FloatArray, tuple[Any, ...]]:
        """``(origin, g)``: the reference point and the flat arrays (pieces and hierarchy) that
        :func:`injmesh.kernels.brep.nearest_point` takes, for compiled callers that query the
        boundary from inside their own loops (coordinates minus ``origin``).

        ``g`` holds the pieces (0-7: start, end, centre, radius, start angle, sweep, previous,
        next), the hierarchy (8-13: node boxes' low and high corners, first child, leaf start
        and count, leaf order), the pieces in leaf order (14-19, as 0-5), the packed leaf
        table (20, :func:`~injmesh.kernels.brep.leaf_table`) and the node boxes as one
        ``(k, 4)`` table (21), every node's parent and sibling (22), every leaf slot's leaf (23) and the
        side table the inside test reads (24, :func:`~injmesh.kernels.brep.side_table`)."""
        _, _, node_lo, node_hi, child, start, count, order, leaf, *search = self._bvh()
        g = (self._p0, self._p1, self._c, self._r, self._a0, self._sw, self._prv, self._nxt,
             node_lo, node_hi, child, start, count, order, *leaf, *search)
        return self._origin, g

    def kernel_boundary(self) -> KernelBoundary | None:
        """Kind 0 (see :meth:`Domain.kernel_boundary`) while :meth:`sdf` and :meth:`project`
        are this class's, which ask the same kernel."""
        if type(self).sdf is not BRep.sdf or type(self).project is not BRep.project:
            return None
        origin, g = self.kernel_data()
        return 0, np.zeros(0), origin, g

    def _query(self, p: FloatArray) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
        """Signed distance, foot point (global) and piece of each point."""
        q = np.ascontiguousarray(as_points(p) - self._origin)
        origin, g = self.kernel_data()
        d, foot, piece = _kernels().nearest(q, g)
        return d, foot + origin, piece

    def sdf(self, p: FloatArray) -> FloatArray:
        """Exact signed distance (Eq. 2.1): negative inside."""
        q = np.ascontiguousarray(as_points(p) - self._origin)
        _, g = self.kernel_data()
        out: FloatArray = _kernels().signed_distance(q, g)
        return out

    def project(self, p: FloatArray) -> FloatArray:
        """The nearest boundary point of each point (Eq. 3.2, exact)."""
        return self._query(p)[1]

    def gradient(self, p: FloatArray) -> FloatArray:
        """Exact gradient of d: the unit vector from the foot, or the outward normal on the
        boundary."""
        p = as_points(p)
        d, foot, piece = self._query(p)
        v = (p - foot) * np.where(d < 0, -1.0, 1.0)[:, None]
        n = np.hypot(v[:, 0], v[:, 1])
        on = n <= tol.PROJECTION_TOL * self.diameter
        out = v / np.where(on, 1.0, n)[:, None]
        if on.any():
            out[on] = self._outward_normal(piece[on], foot[on] - self._origin)
        return out

    def _outward_normal(self, piece: NDArray[np.int64], foot: FloatArray) -> FloatArray:
        arc = self._sw[piece] != 0
        t = self._p1[piece] - self._p0[piece]
        n = np.stack([t[:, 1], -t[:, 0]], axis=1)  # right of travel: outward
        radial = (foot - self._c[piece]) * np.sign(self._sw[piece])[:, None]
        n = np.where(arc[:, None], radial, n)
        return n / np.maximum(np.hypot(n[:, 0], n[:, 1]), 1e-300)[:, None]

    @property
    def bbox(self) -> BBox:
        # Asked a few dozen times per mesh (every background grid, every relative tolerance):
        # computed once, like the index it is read from.
        if self._box is None:
            lo, hi = self._bvh()[:2]
            o = self._origin
            self._box = (
                float(lo[:, 0].min() + o[0]),
                float(lo[:, 1].min() + o[1]),
                float(hi[:, 0].max() + o[0]),
                float(hi[:, 1].max() + o[1]),
            )
        return self._box

    @property
    def area(self) -> float:
        """Enclosed area (holes subtracted)."""
        p0, p1, r, sw = self._p0, self._p1, self._r, self._sw
        chord = 0.5 * (p0[:, 0] * p1[:, 1] - p0[:, 1] * p1[:, 0])
        # An arc adds the circular segment between its chord and itself.
        segment = 0.5 * r * r * (sw - np.sin(sw))
        return float(np.sum(chord) + np.sum(segment))

    # --- tangents, corners, loops -----------------------------------------------------------

    def _tangents(self, at_end: bool) -> FloatArray:
        """Unit direction of travel of every piece at its start or end."""
        q = self._p1 if at_end else self._p0
        v = q - self._c
        arc_t = np.stack([-v[:, 1], v[:, 0]], axis=1) * np.sign(self._sw)[:, None]
        t = np.where((self._sw != 0)[:, None], arc_t, self._p1 - self._p0)
        return t / np.maximum(np.hypot(t[:, 0], t[:, 1]), 1e-300)[:, None]

    def _turns(self) -> FloatArray:
        """Turning angle (degrees, signed: left positive) at the end of each piece."""
        u = self._tangents(True)
        w = self._tangents(False)[self._nxt]
        return np.degrees(np.arctan2(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0], np.sum(u * w, axis=1)))

    def junctions(self) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Every point where two pieces meet.

        Returns
        -------
        points : (k, 2) array
            The junction, in global coordinates (the end of piece i, the start of the next).
        turn : (k,) array
            The turn there, degrees, left positive.
        before, after : (k,) arrays
            Lengths of the pieces that end and start there.

        Examples
        --------
        >>> from injmesh import Rectangle
        >>> p, turn, before, after = Rectangle((0, 0), (2, 1)).junctions()
        >>> turn.round(1).tolist(), sorted(before.tolist())
        ([90.0, 90.0, 90.0, 90.0], [1.0, 1.0, 2.0, 2.0])
        """
        length = np.where(self._sw != 0, self._r * np.abs(self._sw), np.hypot(*(self._p1 - self._p0).T))
        return self._p1 + self._origin, self._turns(), length, length[self._nxt]

    def corners(self) -> FloatArray:
        """Junctions where the boundary turns by more than ``CORNER_ANGLE`` degrees, and the
        junctions of two arcs bending opposite ways (an S-bend, where the curvature jumps
        across zero: two tangent circles, one added and one removed)."""
        if self._corners_cache is None:
            sharp = np.abs(self._turns()) > tol.CORNER_ANGLE  # at the end of each piece
            nxt = self._nxt
            sharp |= (self._sw != 0) & (self._sw[nxt] != 0) & (np.sign(self._sw) != np.sign(self._sw[nxt]))
            c = self._p0[sharp[self._prv]]
            # Loops that touch at a point list it once each: keep the first.
            _, first = np.unique(c, axis=0, return_index=True)
            self._corners_cache = c[np.sort(first)] + self._origin
        return self._corners_cache.copy()

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        """Each loop's junction points, with arcs sampled at most ``spacing`` apart (at least
        16 points per full turn); domain on the left.

        With several loops, segments are subdivided too: Step 1 attaches a corner to a loop
        that passes within two of its segment lengths, so long segments would let a loop claim
        the corners of a hole near it.  (Counts are rounded so a scaled domain gets the same
        subdivision.)
        """
        if not (spacing > 0):
            raise ValueError(f"spacing must be positive, got {spacing!r}")
        split = self.n_loops > 1
        sw, r = self._sw, self._r
        arc = sw != 0
        chord = np.hypot(*(self._p1 - self._p0).T)
        n_seg = np.maximum(1, np.ceil(chord / spacing * (1 - 1e-9))) if split else np.ones(len(sw))
        n_arc = np.maximum(np.maximum(np.ceil(np.abs(sw) * r / spacing * (1 - 1e-9)),
                                      np.ceil(16 * np.abs(sw) / (2 * math.pi) * (1 - 1e-9))), 1)
        count = np.where(arc, n_arc, n_seg).astype(np.intp)
        # Sample j of piece i at fraction j / count[i] of the piece, all pieces at once.
        piece = np.repeat(np.arange(len(sw)), count)
        j = np.arange(len(piece)) - np.repeat(np.cumsum(count) - count, count)
        frac = j / count[piece]
        pts = self._p0[piece] + frac[:, None] * (self._p1 - self._p0)[piece]
        on_arc = arc[piece] & (j > 0)  # an arc's first sample is its exact start point
        if on_arc.any():
            pa = piece[on_arc]
            t = self._a0[pa] + sw[pa] * j[on_arc] / count[pa]
            pts[on_arc] = self._c[pa] + r[pa][:, None] * np.stack([np.cos(t), np.sin(t)], axis=1)
        pts += self._origin
        bounds = np.searchsorted(piece, self._loop_start)
        return [pts[bounds[k]:bounds[k + 1]] for k in range(self.n_loops)]

    def cleaned(
        self, tolerance: float, *, min_feature: float | None = None, max_area: float | None = None
    ) -> tuple[Domain, dict[str, int]]:
        """A boundary made of segments only is cleaned as a polygon (merged vertices, spikes,
        parts beyond pinches narrower than ``min_feature``: :meth:`Polygon.cleaned`) when its
        loops do not touch each other.  Otherwise the cusps where it touches itself
        tangentially are bridged (:meth:`_bridge_cusps`, about ``CUSP_WIDTH * tolerance`` wide;
        counted as ``"cusps"``), and pieces shorter than ``tolerance`` are removed (their
        neighbours meet at the removed piece's start); a loop left with fewer than two pieces,
        or narrower than ``tolerance`` (twice its area over its perimeter), is dropped.  A
        boundary with nothing to clean comes back itself (the stages then reuse what they
        computed on it: the node estimate, 2-3 ms on the paper's L-shape)."""
        if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance >= 0):
            raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
        if not np.any(self._sw):
            from .base import GeometryError
            from .primitives import Polygon

            rings = [self._p0[self._loop_start[k]:self._loop_start[k + 1]] + self._origin
                     for k in range(self.n_loops)]
            try:
                poly = Polygon.from_rings(rings)
            except GeometryError:
                pass  # loops that touch (operands meeting at a point): remove short pieces only
            else:
                cleaned, report = poly.cleaned(tolerance, min_feature=min_feature, max_area=max_area)
                if any(report.values()):
                    return cleaned, report
                # Nothing to clean: this boundary itself, which a union, difference or
                # intersection answers with (so the node estimate made on it is theirs too).
                return self, report
        bridged, cusps = self._bridge_cusps(CUSP_WIDTH * tolerance)
        if cusps:
            out, report = bridged.cleaned(tolerance, min_feature=min_feature, max_area=max_area)
            return out, {**report, "cusps": cusps}
        length = np.where(self._sw != 0, np.abs(self._sw) * self._r, np.hypot(*(self._p1 - self._p0).T))
        short = length < tolerance
        report = {"short_pieces": 0, "dropped_loops": 0}
        if not short.any():
            return self, report
        p0, p1, c, sw, starts = [], [], [], [], [0]
        for k in range(self.n_loops):
            idx = np.arange(self._loop_start[k], self._loop_start[k + 1])
            kept = idx[~short[idx]]
            if len(kept) < 2 and not (len(kept) == 1 and self._sw[kept[0]] != 0):
                report["dropped_loops"] += 1
                report["short_pieces"] += int(short[idx].sum())
                continue
            report["short_pieces"] += int(short[idx].sum())
            start = self._p0[kept].copy()
            # A kept piece after removed ones starts where the first removed one started.
            pos = np.searchsorted(idx, kept)
            prev_kept = np.roll(pos, 1)
            for j in range(len(kept)):
                gap_start = prev_kept[j] + 1 if j > 0 else prev_kept[j] + 1 - len(idx)
                if pos[j] - gap_start > 0:
                    start[j] = self._p0[idx[gap_start % len(idx)]]
            end = np.roll(start, -1, axis=0)
            sweep = self._moved_sweeps(kept, start, end)
            if _sliver_width(start, self._c[kept], sweep) < tolerance:
                # What is left is a sliver narrower than the tolerance (an island 0.0002 wide
                # where a polygon's corner pokes out of a circle, found by fuzzing): kept, its
                # moved arc went the long way round, and the boundary ran off the domain.
                report["dropped_loops"] += 1
                continue
            p0.append(start)
            p1.append(end)
            c.append(self._c[kept])
            sw.append(sweep)
            starts.append(starts[-1] + len(kept))
        if not p0:
            from .base import GeometryError

            raise GeometryError(f"every boundary loop collapses when cleaned at tolerance {tolerance:g}")
        out = BRep.__new__(BRep)
        out._set_local(np.concatenate(p0), np.concatenate(p1), np.concatenate(c), np.concatenate(sw),
                       np.array(starts), self._origin)
        return out, report

    def _moved_sweeps(self, pieces: IntArray, start: FloatArray, end: FloatArray) -> FloatArray:
        """The sweeps of ``pieces`` once their ends are moved to ``start`` and ``end`` (points
        on their circles): each arc keeps its circle, its sweep corrected by how far each end
        moved round it (0 for segments)."""
        sweep = self._sw[pieces].copy()
        arc = sweep != 0
        if arc.any():
            cc = self._c[pieces][arc]
            ka = pieces[arc]
            a_s = np.arctan2(start[arc, 1] - cc[:, 1], start[arc, 0] - cc[:, 0])
            a_e = np.arctan2(end[arc, 1] - cc[:, 1], end[arc, 0] - cc[:, 0])
            e_old = self._p1[ka]
            b_e = np.arctan2(e_old[:, 1] - cc[:, 1], e_old[:, 0] - cc[:, 0])

            def wrap(t: FloatArray) -> FloatArray:
                return (t + math.pi) % (2 * math.pi) - math.pi

            sweep[arc] = sweep[arc] - wrap(a_s - self._a0[ka]) + wrap(a_e - b_e)
        return sweep

    def _bridge_cusps(self, width: float) -> tuple[BRep, int]:
        """The boundary with each cusp bridged where its two sides are ``width`` apart.

        A cusp is where the boundary leaves a point it passes twice in the direction it came
        from: operands tangent to each other (a hole tangent to the outer boundary makes a
        spike of angle 0 inside, a disc touching a square from outside a sliver of angle 0
        outside).  Its sides part like s^2 / 2r, so boundary nodes on both came within 1e-7 of
        each other: zero-area triangles, or segments Delaunay could not keep.  A segment now
        joins the sides where they are ``width`` apart: inside, the spike's tip is cut off;
        outside, the sliver's tip joins the domain.  The sides then meet it at corners of
        about 90 degrees.  Returns the new boundary and the number of cusps bridged.
        """
        if not width > 0:
            return self, 0
        # A cusp the boundary passes once: an arc arriving tangent to the next piece and
        # turning back along it (a disc cutting a rectangle tangent to its side at a corner).
        back = np.flatnonzero(np.abs(self._turns()) > 180.0 - CUSP_TURN)
        # A point passed twice, found by sorting (np.unique on rows cost 0.2 ms per mesh).
        p0 = self._p0
        srt = p0[np.lexsort((p0[:, 1], p0[:, 0]))]
        twice = len(p0) > 1 and bool(np.any(np.all(srt[1:] == srt[:-1], axis=1)))
        if not (twice or len(back)):
            return self, 0
        uniq, inv, count = np.unique(self._p0, axis=0, return_inverse=True, return_counts=True)
        inv = inv.ravel()
        t_start, t_end = self._tangents(False), self._tangents(True)
        end_id = np.full(len(self._p1), -1)
        hit = {tuple(p): k for k, p in enumerate(uniq.tolist())}
        for i, q in enumerate(self._p1.tolist()):
            end_id[i] = hit.get(tuple(q), -1)
        length = np.where(self._sw != 0, np.abs(self._sw) * self._r, np.hypot(*(self._p1 - self._p0).T))
        cos_cusp = math.cos(math.radians(CUSP_TURN))
        bridges: list[tuple[int, int, FloatArray, FloatArray]] = []
        taken_out: set[int] = set()
        for i in back.tolist():
            o = int(self._nxt[i])
            if o != i:
                cut = _bridge(self, i, o, width, float(min(length[i], length[o])))
                if cut is not None:
                    bridges.append((i, o, *cut))
                    taken_out.add(o)
        for v in np.flatnonzero(count > 1).tolist():
            outs = np.flatnonzero(inv == v).tolist()
            for i in np.flatnonzero(end_id == v).tolist():
                if any(i == j for j, _, _, _ in bridges):
                    continue
                for o in outs:
                    # i arrives at v and o leaves it back the way i came: a cusp.
                    if o in taken_out or o == i or float(np.dot(-t_end[i], t_start[o])) < cos_cusp:
                        continue
                    cut = _bridge(self, i, o, width, float(min(length[i], length[o])))
                    if cut is not None:
                        bridges.append((i, o, *cut))
                        taken_out.add(o)
                    break
        if not bridges:
            return self, 0
        p0, p1 = self._p0.copy(), self._p1.copy()
        for i, o, a, b in bridges:
            p1[i], p0[o] = a, b
        sweep = self._moved_sweeps(np.arange(len(p0)), p0, p1)
        s0 = np.concatenate([p0, [a for _, _, a, _ in bridges]])
        s1 = np.concatenate([p1, [b for _, _, _, b in bridges]])
        sc = np.concatenate([self._c, np.zeros((len(bridges), 2))])
        ssw = np.concatenate([sweep, np.zeros(len(bridges))])
        _, vid = np.unique(np.concatenate([s0, s1]), axis=0, return_inverse=True)
        vid = vid.ravel()
        from .boolean import _chain

        loops = _chain(s0, s1, sc, ssw, vid[:len(s0)], vid[len(s0):])
        if loops is None:
            return self, 0
        order = np.concatenate(loops)
        starts = np.r_[0, np.cumsum([len(lp) for lp in loops])]
        out = BRep.__new__(BRep)
        out._set_local(s0[order], s1[order], sc[order], ssw[order], starts, self._origin)
        import warnings

        at = np.unique([self._p0[o] + self._origin for _, o, _, _ in bridges], axis=0)
        where = ", ".join(f"({x:.6g}, {y:.6g})" for x, y in at[:4].tolist())
        # stacklevel: here, cleaned, the set operation's cleaned, the pipeline, generate.
        warnings.warn(f"{len(bridges)} cusp(s) where the boundary touches itself tangentially, at "
                      f"{where}: bridged where {width:.3g} wide (no triangle fits in a cusp)",
                      stacklevel=6)
        return out, len(bridges)


#: A point the boundary passes twice is a cusp when it leaves in the direction it came from
#: within this many degrees (tangent operands; see BRep._bridge_cusps).
CUSP_TURN = 0.5
#: Cusps are bridged where their sides are this many cleaning tolerances apart (the pipeline
#: cleans at 0.01 h_min: a quarter of h_min), or this share of how far they part along the
#: shorter piece if less.  On five tangent shapes at h = 0.09 and 0.02, widths of 0.01, 0.05
#: and 0.25 h_min gave q_min 0.24-0.89, 0.71-0.90 and 0.77-0.89: the narrowest bridge needs
#: the finest elements at the tip, and the quality pass cannot shape them all.
CUSP_WIDTH = 25.0
CUSP_SHARE = 0.1


def _bridge(b: BRep, i: int, o: int, width: float, reach: float) -> tuple[FloatArray, FloatArray] | None:
    """Where to bridge the cusp between piece i (ending at it) and o (leaving it): the point a
    of i whose distance to o's curve is ``width`` (bisection: near a cusp the gap grows with
    the distance from it), and its foot on o; None when the foot is off o.

    A sliver that is thin all along (its sides part by less than ``width / CUSP_SHARE`` over
    ``reach``, the shorter piece) is bridged where it is ``CUSP_SHARE`` of its widest, so the
    bridge does not take most of it: a sliver 0.03 thick meshed with h = 0.09 lost 56 % of its
    area at h/4, 3-5 % so.
    """
    def gap(s: float) -> float:
        q = _point_back(b, i, s)
        return float(np.hypot(*(q - _foot_on_curve(q, b, o))))

    lo, hi = 0.0, reach
    width = min(width, CUSP_SHARE * gap(hi))
    if not width > 0:
        return None
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(mid) < width else (lo, mid)
    a = _point_back(b, i, hi)
    foot = _foot_on_curve(a, b, o)
    return (a, foot) if _on_piece(foot, b, o) else None


def _point_back(b: BRep, i: int, s: float) -> FloatArray:
    """The point of piece i at length s back from its end (local coordinates)."""
    if b._sw[i] == 0:
        d = b._p1[i] - b._p0[i]
        return np.asarray(b._p1[i] - s * d / max(float(np.hypot(*d)), 1e-300))
    t = b._a0[i] + b._sw[i] - math.copysign(s / b._r[i], b._sw[i])
    return np.asarray(b._c[i] + b._r[i] * np.array([math.cos(t), math.sin(t)]))


def _foot_on_curve(q: FloatArray, b: BRep, j: int) -> FloatArray:
    """The nearest point to q on piece j's line or circle."""
    if b._sw[j] == 0:
        a, d = b._p0[j], b._p1[j] - b._p0[j]
        t = float(np.dot(q - a, d) / max(float(np.dot(d, d)), 1e-300))
        return np.asarray(a + t * d)
    v = q - b._c[j]
    norm = float(np.hypot(*v))
    if norm == 0.0:
        # The centre itself: every point of the circle is nearest, r away.  (As 0 / tiny it
        # was the centre, a gap of 0, and a hole tangent inside a disc, whose far side passes
        # through the disc's centre, was not bridged there when the coordinates put that point
        # exactly on it; found by fuzzing.)
        return np.asarray(b._c[j] + np.array([b._r[j], 0.0]))
    return np.asarray(b._c[j] + b._r[j] * v / norm)


def _on_piece(q: FloatArray, b: BRep, j: int) -> bool:
    """Whether q (on piece j's line or circle) lies within the piece."""
    if b._sw[j] == 0:
        a, d = b._p0[j], b._p1[j] - b._p0[j]
        t = float(np.dot(q - a, d) / max(float(np.dot(d, d)), 1e-300))
        return 0.0 <= t <= 1.0
    ang = math.atan2(q[1] - b._c[j][1], q[0] - b._c[j][0])
    turned = ((ang - b._a0[j]) * math.copysign(1.0, b._sw[j])) % (2 * math.pi)
    return turned <= abs(b._sw[j])
