"""Local feature size: how thick the domain is at each point, and the effective size it implies.

The medial axis of a domain is the set of points with two or more nearest boundary points; there
the gradient of the signed distance d is discontinuous.  On a background grid, two neighbouring
nodes (8-neighbourhood) whose nearest boundary points lie on *roughly opposite walls* -- the unit
vectors n = (x - b(x)) / |x - b(x)| from their nearest boundary points b make an angle of more
than ``180 - corner_angle`` degrees -- straddle the medial axis, and both are marked as
medial-axis nodes.  Branches of the medial axis that run into a corner wider than
``corner_angle`` (the diagonals of a square) join walls that are not opposite and are not
marked, so convex corners of a thick region do not make it "thin"; a spike or a neck, whose
walls are nearly parallel, is.

The feature size is then Persson's local feature size (Persson 2006, Section 2.2), doubled so
that it is a *width*:

    feature_size(x) = 2 (|d(x)| + d_MA(x)),

with |d(x)| the distance to the boundary and d_MA(x) the distance to the nearest marked
medial-axis node.  Across a channel of width w it is w everywhere (|d| + d_MA = w / 2 from wall to
centre line); at the centre of a disc of radius R it is 2R.  It is floored at ``min_size`` and
capped at twice the domain's diameter (the value where no medial axis is marked).  Nearest
boundary points are computed exactly on the boundary polylines (primitives' own outlines, or the
curves traced on the background grid and projected onto the boundary).  Features thinner than
about two grid spacings would hold no grid node: unless a spacing is given, gaps between facing
walls are also measured on the boundary polylines themselves (:func:`thinnest_gap`: necks,
straits, slits, a hole near the rim, not the tip of a wedge), and a gap narrower than three
spacings refines the grid to a third of it (at most 16 times finer, within ``max_cells``).
Thinner features are missed.  An isolated medial-axis
point (the centre of a square, where four walls are equidistant) may be seen or not depending on
how the grid falls; missing one only raises the feature size, and only where the region is thick.

:func:`effective_size` first asks :func:`thick_everywhere` (the exact boundary alone, no
grid) whether any two walls face each other within a few h; where none do, the grid below is
not needed.

Cost: one signed-distance call on the grid, exact nearest boundary points (a k-d tree over the
boundary polylines) for the nodes next to the boundary and for the medial-axis candidates, two
Euclidean distance transforms (scipy.ndimage); the other nodes take the nearest point of their
nearest boundary node.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Circle, Domain, GeometryError, Polygon, as_domain
from ._core import SizeError, SizeFunction, SizeLike, as_size_function
from .background import (
    CELLS_PER_H,
    DEFAULT_MAX_CELLS,
    Background,
    check_grid_options,
    densify,
    exact_boundary,
    fit_spacing,
    make_background,
    probe_range,
    resolving_background,
    sample_size,
    sampled_grid,
)
from .fields import GriddedSize
from .gradation import check_rate, limit_grid

FloatArray = NDArray[np.float64]

#: Default background spacing of :func:`feature_size`, as a fraction of the domain's diameter.
FEATURE_CELLS = 256
#: Nearest boundary vertices examined per node (with their two segments each).
NEAREST_VERTICES = 3
#: :func:`_nearest_on_boundary`'s compiled search gives up beyond this many rings of cells
#: (a k-d tree answers those points), and leaves to the default k-d tree the points where two
#: of the nearest squared distances are this close (relative): their order may hinge on
#: rounding.
NEAREST_RINGS = 6
NEAREST_TIE = 1e-12
#: Boundary vertices examined around each vertex when looking for a facing wall across a gap,
#: gaps narrower than GAP_WIDTHS grid spacings that refine the grid, and the largest refinement.
GAP_NEIGHBOURS = 24
GAP_WIDTHS = 3.0
GAP_REFINE = 16.0
#: :func:`thinnest_gap` tries every vertex pair within the gap width first (a quick "no gap"
#: on a smooth domain) only up to this many boundary vertices.
GAP_FIRST_PASS_MAX = 8192
#: A gap counts when the boundary between its two sides is this many times longer than the gap
#: (so the two walls of a sharp wedge, joined at its tip, do not count).
GAP_DETOUR = 20.0
#: Neighbouring nodes whose approximate nearest boundary points are more than this many grid
#: spacings apart straddle the medial axis, perhaps: their nearest points are computed exactly.
CANDIDATE_JUMP = 2.0
#: :func:`thick_everywhere` is asked for walls closer than ``THICK_MARGIN * layers * h``, h
#: evaluated along the chord between them, and for walls back to back closer than
#: ``THICK_PAD`` background grid spacings (the grid would see both sides of such a gap).  The
#: pairs are searched within ``THICK_MARGIN * layers * h_max + THICK_PAD`` spacings.  Walls
#: exactly ``layers * h`` apart count as thick (to ``THICK_TIE``, relative): there the feature
#: size is exactly ``layers * h`` and changes nothing (the paper's four-hole square, whose
#: holes are 0.3 from the sides where h = 0.15, is such a case: no grid is needed to find
#: that nothing changes).
THICK_MARGIN = 1.0
THICK_PAD = 2.0
THICK_TIE = 1e-9
#: Walls face each other when the direction between them is within this many degrees more
#: than ``corner_angle`` of both inward normals (slack for curved walls sampled by chords).
FACING_SLACK = 10.0
#: The sizes a coarse probe finds are trusted up to this factor (checked on the grid after).
PROBE_SLACK = 1.5
#: Boundary vertices per tested width, and the most vertices the test may use.
THICK_STEPS = 4
THICK_MAX_VERTICES = 1_000_000
#: With a ``needed`` width, :func:`thick_everywhere` first looks for facing walls closer than
#: its width divided by each of these in turn (a sixteenth of it looks at about 1/200 of the
#: vertex pairs, a quarter at about 1/16), while the cell grid has at most four cells per vertex
#: plus THICK_QUICK_CELLS, and asks ``needed`` at the closest pairs first, THICK_BATCH at a
#: time (then four times more, and so on).
THICK_QUICK = (16.0, 4.0)
THICK_QUICK_CELLS = 1 << 20
THICK_BATCH = 256


def _positive(name: str, value: float | None) -> float | None:
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise SizeError(f"{name} must be a positive number, got {value!r}")
    if not (math.isfinite(float(value)) and value > 0):
        raise SizeError(f"{name} must be positive and finite, got {value!r}")
    return float(value)


Segments = tuple[FloatArray, FloatArray, NDArray[np.intp]]


def _loops(domain: Domain, grid: Background) -> list[FloatArray]:
    """The boundary loops :func:`_boundary` joins: a polygon's or a circle's own at half a grid
    spacing, else the curves traced on the grid (inside on the left) projected onto the
    boundary."""
    if isinstance(domain, (Polygon, Circle)):
        return list(domain.boundary_loops(0.5 * grid.spacing))
    from ..geometry.tracing import loops_from_grid

    # Tracing interpolates d between nodes: a grid of signs alone is sampled again.
    d = make_background(domain, grid.spacing, grid.capped, check=False).d if grid.signs_only else grid.d
    return [domain.project(loop) for loop in loops_from_grid(grid.x, grid.y, d)]


def _boundary(domain: Domain, grid: Background, loops: list[FloatArray] | None = None) -> Segments:
    """Boundary segments no longer than half a grid spacing.

    Returns the start ``(m, 2)`` and end ``(m, 2)`` of each segment and, for each segment, the
    index of the one before it on its loop.  ``loops``: :func:`_loops` of this grid, when the
    caller has them.
    """
    step = 0.5 * grid.spacing
    if loops is None:
        loops = _loops(domain, grid)
    a, b, prev = [], [], []
    offset = 0
    for loop in loops:
        if len(loop) < 2:
            continue
        dense = densify(np.asarray(loop, dtype=np.float64), step)
        a.append(dense)
        b.append(np.roll(dense, -1, axis=0))
        prev.append(offset + (np.arange(len(dense)) - 1) % len(dense))
        offset += len(dense)
    if not a:
        raise GeometryError("the domain has no boundary curve at the background grid's resolution")
    return np.concatenate(a), np.concatenate(b), np.concatenate(prev)


def _arc_positions(seg_a: FloatArray, seg_b: FloatArray, prev: NDArray[np.intp]) -> tuple[
        NDArray[np.intp], FloatArray, FloatArray]:
    """Loop number, arc length from the loop's first vertex, and loop length, per vertex."""
    first = prev > np.arange(len(prev))  # a loop's first vertex follows its last
    loop = np.cumsum(first) - 1
    length = np.hypot(*(seg_b - seg_a).T)
    total = np.bincount(loop, weights=length)
    start = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    return loop, start - start[np.flatnonzero(first)][loop], total[loop]


class _Trees:
    """The k-d trees :func:`_nearest_on_boundary` may ask over one set of boundary vertices,
    each built on first use and kept for the next call on the same vertices (the feature grid
    asks twice: its seeds, then its medial-axis candidates).  A tree's answer to a point does
    not depend on what else it was asked."""

    def __init__(self, seg_a: FloatArray) -> None:
        self.seg_a = seg_a
        self._default: Any = None
        self._loose: Any = None

    def default(self) -> Any:
        """The default tree (balanced, compact), the one the nearest points were first defined by."""
        if self._default is None:
            from scipy.spatial import cKDTree

            self._default = cKDTree(self.seg_a)
        return self._default

    def loose(self) -> Any:
        """A tree whose cells are left as the splits make them (see :func:`_nearest_on_boundary`)."""
        if self._loose is None:
            from scipy.spatial import cKDTree

            self._loose = cKDTree(self.seg_a, balanced_tree=False, compact_nodes=False)
        return self._loose


def _nearest_on_boundary(
    p: FloatArray, seg_a: FloatArray, seg_b: FloatArray, prev: NDArray[np.intp],
    trees: _Trees | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Distance from each point to the boundary polylines and the nearest boundary point.

    Segment ``k`` runs from vertex ``k`` (``seg_a[k]``) to the next one; the candidates are the
    two segments at each of the ``NEAREST_VERTICES`` nearest vertices.  ``trees``: the k-d
    trees of ``seg_a`` from an earlier call, when the caller keeps them.
    """
    from ..kernels.feature import nearest_feet
    from ..kernels.outline import nearest_of_segments

    k = min(NEAREST_VERTICES, len(seg_a))
    # The k nearest vertices, exactly, from a compiled search over a grid of cells about two
    # vertices' share of the box wide (the 7,000 medial-axis candidates of the paper's
    # four-hole square: 4 ms, where a k-d tree took 9), and the nearest point on their
    # segments in the same call.  Where two of the k + 1 nearest distances are (nearly)
    # equal, equidistant vertices (grid-aligned walls) come in an order that depends on the
    # search: those points ask the default k-d tree, as they always have (where the distances
    # differ, every exact search gives the same vertices in the same order, so these get the
    # same nearest points either way), unless the order cannot change the answer
    # (:func:`~injmesh.kernels.feature.nearest_feet`: most such points on the paper's
    # four-hole square, 1,300 of 1,600).
    extent = np.ptp(seg_a, axis=0) if len(seg_a) else np.zeros(2)
    size = max(2.0 * math.sqrt(float(extent[0] * extent[1]) / max(len(seg_a), 1)),
               float(extent.max()) / max(len(seg_a), 1))
    p = np.ascontiguousarray(p, dtype=np.float64)
    dist = np.zeros(len(p))
    foot = np.zeros((len(p), 2))
    status = np.full(len(p), 2, dtype=np.int8)
    if k and size > 0:
        dist, foot, status = nearest_feet(p, np.ascontiguousarray(seg_a, dtype=np.float64),
                                          np.ascontiguousarray(seg_b, dtype=np.float64),
                                          np.ascontiguousarray(prev, dtype=np.int64), k, size,
                                          NEAREST_TIE, NEAREST_RINGS)
    rest = np.flatnonzero(status != 0)
    if len(rest):
        trees = _Trees(seg_a) if trees is None else trees
        q, st = p[rest], status[rest]
        near = np.zeros((len(rest), k), dtype=np.int64)
        far = st == 2
        if far.any():
            # Points farther than NEAREST_RINGS cells from their vertices (deep inside a
            # detailed outline).  A tree whose cells are left as the splits make them (not
            # shrunk to their points) answers such queries 5-8 times faster than the default
            # one (1.3 -> 0.2 s for the 80,000 medial-axis candidates of a 20,000-vertex
            # outline); the points it finds ties for join those of the search.
            kq = min(k + 1, len(seg_a))
            dist_k, near_q = trees.loose().query(q[far], k=kq)
            dist_k, near_q = dist_k.reshape(-1, kq), near_q.reshape(-1, kq)[:, :k]
            near[far] = near_q
            st[np.flatnonzero(far)[np.any(dist_k[:, 1:] == dist_k[:, :-1], axis=1)]] = 1
        tied = st == 1
        if tied.any():
            near[tied] = trees.default().query(q[tied], k=k)[1].reshape(-1, k)
        near = np.ascontiguousarray(near, dtype=np.int64)
        cand = np.ascontiguousarray(np.concatenate([near, prev[near]], axis=1), dtype=np.int64)
        dist[rest], foot[rest] = nearest_of_segments(q, cand, seg_a, seg_b)
    return dist, foot


def thinnest_gap(domain: Domain, grid: Background, corner_angle: float,
                 boundary: Segments | None = None) -> float:
    """The narrowest gap between facing walls, measured on the boundary itself (inf if none).

    For every boundary vertex v (polylines at half the grid spacing) the nearest
    ``GAP_NEIGHBOURS`` vertices are examined: a vertex u across the domain (the midpoint of uv
    inside) whose wall faces v's within ``corner_angle`` (uv within that angle of both inward
    normals) bounds a gap of width |uv|.  This sees necks, straits and slits too thin to hold a
    grid node, which the medial-axis test on the grid cannot.  ``boundary``: :func:`_boundary`
    of this grid, when the caller has it.
    """
    from scipy.spatial import cKDTree

    seg_a, seg_b, prev = _boundary(domain, grid) if boundary is None else boundary
    if len(seg_a) < 4:
        return np.inf
    tangent = seg_b - seg_a[prev]
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    normal /= np.maximum(np.hypot(*normal.T), np.finfo(float).tiny)[:, None]
    # Orient each normal into the domain (loops from any source, whatever their direction).
    probe = 0.25 * grid.spacing * normal
    flip = domain.sdf(seg_a + probe) > domain.sdf(seg_a - probe)
    normal[flip] *= -1
    width = GAP_WIDTHS * grid.spacing
    cos = math.cos(math.radians(corner_angle))
    arcs = _arc_positions(seg_a, seg_b, prev)
    # First every pair of vertices closer than the width, with a little slack in each test: a
    # superset of the nearest neighbours' pairs below (each test is symmetric in v and u, so
    # one order of each pair is enough).  Where none of them is a gap (a domain thin only at a
    # few h, such as the paper's four-hole square), neither is any of those, and the answer
    # costs a fraction of the neighbour search.  A detailed outline (more than
    # GAP_FIRST_PASS_MAX vertices) is thin somewhere nearly always, and there the first pass
    # only added its own cost (0.23 s on the 20,000-vertex fixture): it goes straight to the
    # search.  The answer is the same either way: the slack (1e-9, relative) is far above the
    # rounding in which the compiled pass and the search may differ.
    slack = 1e-9
    if len(seg_a) <= GAP_FIRST_PASS_MAX and not _any_gap(domain, seg_a, normal, arcs, width, cos, slack):
        return np.inf
    k = min(GAP_NEIGHBOURS, len(seg_a))
    dist, idx = cKDTree(seg_a).query(seg_a, k=k)
    v = np.repeat(np.arange(len(seg_a)), k)
    gap = _gaps(domain, seg_a, normal, arcs, v, idx.ravel(), dist.ravel(), width, cos, 0.0)
    return float(gap.min()) if len(gap) else np.inf


def _any_gap(domain: Domain, seg_a: FloatArray, normal: FloatArray,
             arcs: tuple[NDArray[np.intp], FloatArray, FloatArray], width: float, cos: float,
             slack: float) -> bool:
    """Whether some pair of vertices closer than ``width`` passes :func:`_gaps`'s tests, each
    loosened by ``slack`` (relative): the pairs and their tests in one compiled pass
    (:func:`~injmesh.kernels.feature.gap_pairs`; 1 ms on the paper's four-hole square, where
    a k-d tree's pairs and the NumPy tests on them took 5), then the domain's d at the
    midpoints of the few that pass."""
    from ..kernels.feature import gap_pairs

    loop, along, total = arcs
    v, u = gap_pairs(np.ascontiguousarray(seg_a, dtype=np.float64),
                     np.ascontiguousarray(normal, dtype=np.float64), np.ascontiguousarray(loop),
                     np.ascontiguousarray(along, dtype=np.float64),
                     np.ascontiguousarray(total, dtype=np.float64), float(width), float(cos), float(slack),
                     float(GAP_DETOUR))
    return bool(len(v)) and bool(np.any(domain.sdf(0.5 * (seg_a[u] + seg_a[v])) < 0))


def _gaps(domain: Domain, seg_a: FloatArray, normal: FloatArray,
          arcs: tuple[NDArray[np.intp], FloatArray, FloatArray], v: NDArray[np.intp], u: NDArray[np.intp],
          dist: FloatArray, width: float, cos: float, slack: float) -> FloatArray:
    """The widths of the gaps :func:`thinnest_gap` counts among the vertex pairs ``(v, u)``
    ``dist`` apart (each test loosened by ``slack``, relative)."""
    keep = (dist > 0) & (dist < width * (1.0 + slack))
    v, u, dist = v[keep], u[keep], dist[keep]
    e = (seg_a[u] - seg_a[v]) / dist[:, None]
    facing = ((np.einsum("kj,kj->k", e, normal[v]) > cos - slack)
              & (-np.einsum("kj,kj->k", e, normal[u]) > cos - slack))
    v, u, dist = v[facing], u[facing], dist[facing]
    # Walls meeting at a nearby sharp corner are a wedge, not a gap: the boundary between v and
    # u must be long compared with the gap (around a lobe, a hole or a deep notch).
    loop, along, total = arcs
    arc = np.abs(along[u] - along[v])
    arc = np.where(loop[u] == loop[v], np.minimum(arc, total[v] - arc), np.inf)
    around = arc > GAP_DETOUR * dist * (1.0 - slack)
    v, u, dist = v[around], u[around], dist[around]
    if not len(v):
        return dist
    out: FloatArray = dist[domain.sdf(0.5 * (seg_a[u] + seg_a[v])) < 0]
    return out


def _outline() -> Any:
    from ..kernels import outline

    return outline


def loop_frames(
    loops: list[FloatArray],
) -> tuple[FloatArray, NDArray[np.intp], NDArray[np.intp], FloatArray, FloatArray, FloatArray, FloatArray]:
    """Closed loops of vertices joined end to end, with each vertex's successor and
    predecessor on its own loop and :func:`wall_frames`: ``v, nxt, prv, seg, seg_len, v_n,
    seg_n``."""
    sizes = np.array([len(lp) for lp in loops])
    v = np.concatenate(loops)
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)
    local = np.arange(len(v)) - first
    nxt = first + (local + 1) % np.repeat(sizes, sizes)
    prv = first + (local - 1) % np.repeat(sizes, sizes)
    return (v, nxt, prv, *wall_frames(v, nxt, prv))


def wall_frames(
    v: FloatArray, nxt: NDArray[np.intp], prv: NDArray[np.intp]
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """What :func:`injmesh.kernels.outline.facing_walls` needs of closed loops of vertices
    ``v`` (``nxt``/``prv``: each vertex's successor and predecessor on its loop): the segments
    ``v -> nxt`` and their lengths, each vertex's inward normal and each segment's.

    Segment k runs from vertex k to nxt[k]; its inward normal is the left one (domain on the
    left); a vertex's normal is that of the chord from its predecessor to its successor.
    """
    seg = v[nxt] - v
    seg_len = np.hypot(*seg.T)
    seg_n = np.stack([-seg[:, 1], seg[:, 0]], axis=1) / np.maximum(seg_len, np.finfo(float).tiny)[:, None]
    chord = v[nxt] - v[prv]
    v_n = np.stack([-chord[:, 1], chord[:, 0]], axis=1)
    v_n /= np.maximum(np.hypot(*v_n.T), np.finfo(float).tiny)[:, None]
    return seg, seg_len, v_n, seg_n


def thick_everywhere(domain: Domain, width: float, corner_angle: float,
                     needed: Callable[[FloatArray], FloatArray] | None = None,
                     back_to_back: float = 0.0, loops: list[FloatArray] | None = None) -> bool:
    """True when no two walls of the domain face each other closer than ``width``.

    Then the medial axis between roughly opposite walls (the one :func:`feature_grid` marks) is
    nowhere nearer than ``width / 2`` to the boundary, so the feature size is at least about
    ``width`` everywhere.  Measured on the exact boundary, without a grid: the loops are sampled
    every ``width / THICK_STEPS``; for every vertex v and every segment s with an end point
    within ``width`` of it, the foot f of v on s is found, and v and s *face each other* when
    the direction from v to f is within ``corner_angle + FACING_SLACK`` degrees of v's inward
    normal and of the reverse of s's (parallel walls across a channel, the two sides of a sharp
    wedge; not the neighbouring points of one wall, not walls across a notch outside).

    With ``needed``, a function of points giving the width wanted there (at most ``width``),
    two facing walls count only when they are closer than the largest ``needed`` at five points
    evenly spaced from v to f: every point whose feature size comes from these walls lies near
    such a chord.

    Walls back to back closer than ``back_to_back`` count too (the two sides of a thin hole or
    slit, of a narrow notch): grid nodes on either side of such a gap see opposite walls, and
    :func:`feature_grid` marks them.

    ``loops`` (closed polylines, the domain on their left) stand for the boundary when given:
    a plain signed distance's curves traced on a background grid, those :func:`feature_grid`
    measures from.  Without them, False when the domain has no exact boundary (a plain signed
    distance); False also when the test would need more than ``THICK_MAX_VERTICES`` vertices:
    the caller then computes the feature size.

    The vertex pairs and the facing test are compiled (:mod:`injmesh.kernels.outline`): a
    detailed outline has hundreds of vertex pairs per vertex within ``width``.  With
    ``needed``, searches at a fraction of the width come first (``THICK_QUICK``): any pair they
    find is one of the full search's, so one that counts settles the answer (False) at a small
    part of the cost, and ``needed`` is asked at the closest pairs first, in batches.  The
    answer is the full search's either way.
    """
    if not (width > 0 and math.isfinite(width)):
        return False
    step = width / THICK_STEPS
    if loops is None:
        brep = exact_boundary(domain)
        if brep is None:
            return False
        loops = [np.asarray(loop, dtype=np.float64) for loop in brep.boundary_loops(step)]
    else:
        loops = [_thinned(np.asarray(loop, dtype=np.float64), step) for loop in loops]
    loops = [loop for loop in loops if len(loop) >= 2]
    if not loops:
        return False
    perimeter = sum(float(np.hypot(*(np.roll(lp, -1, axis=0) - lp).T).sum()) for lp in loops)
    if perimeter / step + sum(len(lp) for lp in loops) > THICK_MAX_VERTICES:
        return False
    v, _, prv, seg, seg_len, v_n, seg_n = loop_frames([densify(loop, step) for loop in loops])
    cos = math.cos(math.radians(min(corner_angle + FACING_SLACK, 89.0)))
    walls = _outline()

    reach = _pair_reach(v, seg_len, step, width)
    extent = np.ptp(v, axis=0)

    def search(w: float, back: float) -> tuple[bool, NDArray[np.intp], FloatArray, FloatArray]:
        return walls.facing_walls(v, prv, seg, seg_len, v_n, seg_n, max(w, back) + reach,
                                  w, back, cos, needed is None)

    if needed is not None:
        # The answer is False as soon as one back-to-back pair or one facing pair closer than
        # ``needed`` is found, and the pairs a narrower search finds (on the same vertices,
        # back to back within the narrower width too) are among those of the full one: on a
        # thin domain a narrow search usually settles it, at a small fraction of the vertex
        # pairs.  Else the full search decides, as it would have alone.  (A narrow search whose
        # cell grid, cells as wide as its radius, would be much larger than the outline is
        # left out.)
        for divisor in THICK_QUICK:
            w = width / divisor
            if np.prod(extent / (w + reach) + 1.0) > 4 * len(v) + THICK_QUICK_CELLS:
                continue
            behind, a, foot, dist = search(w, min(back_to_back, w))
            if behind or _closer_than_needed(v[a], foot, dist, needed):
                return False
    behind, a, foot, dist = search(width, back_to_back)
    if behind or not len(a):
        return not behind
    if needed is None:
        return False
    return not _closer_than_needed(v[a], foot, dist, needed)


#: :func:`_thinned` keeps every vertex where a polyline turns by more than this many degrees.
THIN_TURN = 15.0


def _thinned(loop: FloatArray, step: float) -> FloatArray:
    """A closed polyline's vertices about ``step`` apart along it, and every vertex where it
    turns by more than ``THIN_TURN`` degrees.

    A loop traced on a fine grid has vertices a fraction of a grid spacing apart, many times
    more than :func:`thick_everywhere` samples an exact boundary with (``width /
    THICK_STEPS``), and the test's cost grows with the square of the vertices per width.  The
    kept vertices lie on the boundary as the traced ones do, so the chords between them are
    those an exact boundary would give (their sagitta is the exact test's too); the corners,
    where the direction changes quickly, keep their vertices.
    """
    if len(loop) < 4:
        return loop
    seg = np.roll(loop, -1, axis=0) - loop
    seg_len = np.hypot(*seg.T)
    along = np.concatenate([[0.0], np.cumsum(seg_len)[:-1]])
    _, first = np.unique(np.floor(along / step), return_index=True)
    keep = np.zeros(len(loop), dtype=bool)
    keep[first] = True
    tiny = np.finfo(float).tiny
    unit = seg / np.maximum(seg_len, tiny)[:, None]
    turn = np.einsum("kj,kj->k", np.roll(unit, 1, axis=0), unit)  # cosine at each vertex
    keep |= turn < math.cos(math.radians(THIN_TURN))
    out: FloatArray = loop[keep]
    return out


def _pair_reach(v: FloatArray, seg_len: FloatArray, step: float, width: float) -> float:
    """How far beyond a width ``w`` :func:`thick_everywhere` looks for the partner vertex.

    A facing or back-to-back pair is a vertex and a segment closer than w, so one end of the
    segment is within w plus the longest segment of the vertex: the longest of ``seg_len``
    (with a margin for rounding), on a detailed outline much shorter than ``step`` (which
    bounds it after densifying).  The same pairs as with ``step``, fewer vertex pairs to look
    at.
    """
    scale = float(np.abs(v).max()) + width
    return min(step, float(seg_len.max()) * (1.0 + 1e-9) + 1e-9 * scale)


def _closer_than_needed(start: FloatArray, foot: FloatArray, dist: FloatArray,
                        needed: Callable[[FloatArray], FloatArray]) -> bool:
    """Whether some pair of facing walls (``start`` to ``foot``, ``dist`` apart) is closer than
    the largest ``needed`` at five points evenly spaced from one to the other.

    The closest pairs are asked first, in batches growing fourfold from ``THICK_BATCH``: a thin
    domain usually answers in the first batch, without evaluating ``needed`` (h, often the
    larger part of the cost) at the hundreds of thousands of pairs of a detailed outline.
    """
    order = np.argsort(dist, kind="stable")
    frac = np.linspace(0.0, 1.0, 5)
    lo, batch = 0, THICK_BATCH
    while lo < len(order):
        pick = order[lo:lo + batch]
        a, f = start[pick], foot[pick]
        along = (a[None, :, :] + frac[:, None, None] * (f - a)[None, :, :]).reshape(-1, 2)
        want = np.max(needed(along).reshape(len(frac), -1), axis=0)
        if np.any(dist[pick] < want * (1.0 - THICK_TIE)):
            return True
        lo, batch = lo + batch, 4 * batch
    return False


def refine_for_gaps(domain: Domain, grid: Background, corner_angle: float, max_cells: int,
                    boundary: Segments | None = None) -> Background:
    """A finer grid when a gap between facing walls is under GAP_WIDTHS spacings wide.

    The spacing becomes a third of the narrowest gap (at most GAP_REFINE times finer, within
    ``max_cells``) so the gap holds grid nodes and its medial axis is resolved.  ``boundary``:
    :func:`_boundary` of ``grid``, when the caller has it.
    """
    gap = thinnest_gap(domain, grid, corner_angle, boundary)
    if not gap < GAP_WIDTHS * grid.spacing:
        return grid
    wanted = max(gap / 3.0, grid.spacing / GAP_REFINE)
    finer, capped = fit_spacing(domain, wanted, max_cells, explicit=False)
    if finer >= grid.spacing:
        return grid
    return make_background(domain, finer, capped)


def feature_grid(domain: Domain, grid: Background, min_size: float, corner_angle: float,
                 boundary: Segments | None = None) -> FloatArray:
    """The feature size at the grid nodes inside the domain and next to it; ``inf`` elsewhere.

    ``boundary``: :func:`_boundary` of this grid, when the caller has it."""
    from scipy import ndimage

    from ..kernels.feature import feature_values, gather_feet, medial_candidates, medial_marks

    inside = grid.inside
    band = grid.band
    near = inside | band
    shape = grid.d.shape
    # Exact nearest boundary points for the nodes next to the boundary (the seeds); every other
    # node takes the nearest point of its nearest seed (a Euclidean distance transform), off by
    # about a spacing along the wall: its distance r is then accurate to about a spacing, but
    # its direction to the wall is not reliable near the medial axis.  So the medial axis is
    # found in two passes: candidates first, then the exact test on exact nearest points.
    seeds = band.copy()
    seeds[:-1, :] |= band[1:, :] & inside[:-1, :]
    seeds[1:, :] |= band[:-1, :] & inside[1:, :]
    seeds[:, :-1] |= band[:, 1:] & inside[:, :-1]
    seeds[:, 1:] |= band[:, :-1] & inside[:, 1:]
    seg_a, seg_b, prev = _boundary(domain, grid) if boundary is None else boundary
    exact = seeds.copy()
    feet = np.zeros(shape + (2,))
    trees = _Trees(seg_a)
    feet[seeds] = _nearest_on_boundary(grid.nodes(seeds), seg_a, seg_b, prev, trees)[1]
    _, (jj, ii) = ndimage.distance_transform_edt(~seeds, return_indices=True)
    feet = gather_feet(feet, jj, ii)
    x, y = grid.x, grid.y
    # Candidates: where the approximate nearest point jumps between neighbours (near the medial
    # axis the nearest seed may lie on any of the walls at about the same distance, so the
    # approximate direction is not to be trusted there), grown by one node.
    # The jump that counts grows with the distance to the wall (half of it): inside a convex
    # wall the nearest points of neighbours spread out by spacing * R / (R - r) anyway, while
    # across the medial axis they jump from one wall to the other, about 2 r apart.
    todo = medial_candidates(x, y, feet, inside, exact, float(grid.spacing), float(CANDIDATE_JUMP))
    if todo.any():
        feet[todo] = _nearest_on_boundary(grid.nodes(todo), seg_a, seg_b, prev, trees)[1]
    # Neighbours (8-neighbourhood) whose directions from their nearest points are roughly
    # opposite straddle the medial axis; both are marked, with the point where the axis crosses
    # their pair: where the distances to the two walls (planes through the nearest points,
    # normals n_a and n_b) are equal.  Nodes closer to the boundary than half a spacing are
    # left out: on the boundary itself the direction to the polyline's nearest point is
    # arbitrary (a node on a circle lies outside its chords), and no medial axis the grid
    # resolves passes that close to a wall.  (Both compiled: the NumPy form's slices of the
    # grid cost 7 ms on the paper's four-hole square.)
    medial, r, axis_point = medial_marks(x, y, feet, inside, float(grid.spacing),
                                         -math.cos(math.radians(corner_angle)))
    if medial.any():
        # d_MA: distance to the crossing recorded at the nearest marked node.  Outside (the
        # band) r counts negatively: the formula continues linearly through the wall instead
        # of folding back up, so interpolation at the wall gives the width.
        _, (mj, mi) = ndimage.distance_transform_edt(~medial, return_indices=True)
        fs: FloatArray = feature_values(x, y, r, axis_point, mj, mi, inside, near, float(min_size),
                                        float(2.0 * domain.diameter))
        return fs
    fs = np.full(shape, np.inf)
    fs[near] = np.clip(fs[near], min_size, 2.0 * domain.diameter)
    return fs


def _fill_outside(values: FloatArray) -> FloatArray:
    """Nodes that impose nothing (``inf``) take the value of the nearest node that does."""
    from scipy import ndimage

    known = np.isfinite(values)
    if known.all():
        return values
    _, (jj, ii) = ndimage.distance_transform_edt(~known, return_indices=True)
    out: FloatArray = values[jj, ii]
    return out


def feature_size(
    domain: Domain | Callable[[FloatArray], FloatArray],
    *,
    spacing: float | None = None,
    min_size: float | None = None,
    corner_angle: float = 30.0,
    max_cells: int = DEFAULT_MAX_CELLS,
    bbox: ArrayLike | None = None,
) -> GriddedSize:
    """The local thickness of the domain: about w across a channel of width w.

    See the module docstring for the formula, ``2 (|d| + d_MA)`` with d_MA the distance to the
    medial axis between roughly opposite walls.

    Parameters
    ----------
    domain : Domain or callable
        The domain (a plain signed distance needs ``bbox``).
    spacing : float, optional
        Background grid spacing (default: the domain's diameter / 256, or ``min_size / 2`` when
        that is smaller, enlarged to keep at most ``max_cells`` nodes).  Features thinner than
        about two spacings may be missed.
    min_size : float, optional
        Floor of the result (default: two grid spacings), so it never vanishes at the tip of a
        spike or in a neck that pinches to zero width.
    corner_angle : float
        Degrees.  Medial-axis branches into corners at least this wide (a square's diagonals)
        are ignored; sharper wedges count as thin parts.
    max_cells : int
        Cap on the background grid's nodes.
    bbox : (xmin, ymin, xmax, ymax), optional
        Required for a callable ``domain``.

    Returns
    -------
    GriddedSize
        Feature sizes on the background grid, in ``[min_size, 2 * diameter]``; nodes outside
        the domain take the value of the nearest node inside.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Rectangle
    >>> fs = feature_size(Rectangle((0, 0), (4, 0.2)), spacing=0.01)
    >>> bool(np.all(np.abs(fs(np.array([[2.0, 0.0], [2.0, 0.1], [1.0, 0.05]])) - 0.2) < 0.02))
    True
    """
    check_grid_options(spacing, max_cells)
    floor = _positive("min_size", min_size)
    angle = _positive("corner_angle", corner_angle)
    assert angle is not None
    if not angle < 180:
        raise SizeError(f"corner_angle must be below 180 degrees, got {corner_angle!r}")
    dom = as_domain(domain, bbox=bbox)
    if spacing is None:
        wanted = dom.diameter / FEATURE_CELLS
        if floor is not None:
            wanted = min(wanted, floor / 2)
        grid = resolving_background(dom, wanted, int(max_cells), explicit=False)
    else:
        grid = resolving_background(dom, float(spacing), int(max_cells), explicit=True)
    boundary = _boundary(dom, grid)
    if spacing is None:
        finer = refine_for_gaps(dom, grid, angle, int(max_cells), boundary)
        if finer is not grid:
            grid, boundary = finer, _boundary(dom, finer)
    fs = feature_grid(dom, grid, 2.0 * grid.spacing if floor is None else floor, angle, boundary)
    return GriddedSize._trusted(grid.x, grid.y, _fill_outside(fs))


def thin_feature_size(
    domain: Domain, size: SizeLike, layers: float, corner_angle: float = 30.0
) -> GriddedSize | None:
    """:func:`feature_size` of ``domain`` if some part of it is thinner than ``layers`` times h,
    None when no two of its walls face each other that close (:func:`thick_everywhere`).

    The test needs no grid, so a region that is thick everywhere (a circular inclusion several h
    across) costs a few milliseconds instead of a feature grid.  For a variable h the bound is
    the largest h of :func:`probe_range`'s sample with the slack :func:`effective_size` uses.
    """
    h = as_size_function(size)
    if exact_boundary(domain) is not None:
        if h.constant is not None:
            if _thick_uniform(domain, h.constant, layers, corner_angle):
                return None
        else:
            lo, hi = probe_range(h, domain)
            fine = min(lo / CELLS_PER_H, domain.diameter / FEATURE_CELLS)
            if _thick(domain, PROBE_SLACK * hi, layers, corner_angle, fine, h.restricted(domain)):
                return None
    return feature_size(domain, corner_angle=corner_angle)


class _Lower:
    """``min(a(p), b(p))`` of two size functions (used when the grid is coarser than h)."""

    def __init__(self, a: Callable[[FloatArray], FloatArray], b: Callable[[FloatArray], FloatArray]):
        self.a, self.b = a, b

    def __call__(self, p: FloatArray) -> FloatArray:
        return np.minimum(self.a(p), self.b(p))


def unrestricted(size: SizeFunction, h: SizeFunction) -> SizeFunction:
    """``size``, as :func:`effective_size` returned it for h, for a caller that evaluates it only
    inside the domain and on its boundary, or just outside (the mesher's stages: midpoints of
    boundary edges where the boundary is concave).

    Where the grid was too coarse for h (``min(grid, h restricted to the domain)``) and h is
    defined everywhere (a uniform size, or a function object with a true ``everywhere``
    attribute, such as the corner cones of :func:`injmesh.boundary.corner_size` over a uniform
    size), h is called as it is: the restriction's signed-distance call, the larger part of an
    evaluation on a detailed outline, is left out.  The values differ only at points outside
    the domain (h there rather than at their projection onto the boundary).  Otherwise
    ``size`` itself.
    """
    f = size.function
    safe = h.constant is not None or getattr(h.function, "everywhere", False) is True
    if safe and isinstance(f, _Lower) and isinstance(f.b, SizeFunction) and f.b.function is h.function:
        return SizeFunction(_Lower(f.a, h))
    return size


def effective_size(
    size: SizeLike,
    domain: Domain | Callable[[FloatArray], FloatArray],
    *,
    layers: float | None = 2,
    rate: float | None = 0.2,
    min_size: float | None = None,
    corner_angle: float = 30.0,
    spacing: float | None = None,
    max_cells: int = DEFAULT_MAX_CELLS,
    bbox: ArrayLike | None = None,
) -> SizeFunction:
    """The size the mesher should follow: ``min(h, feature_size / layers)``, gradation-limited.

    Parameters
    ----------
    size : float, callable or size field
        The user's h; evaluated only inside the domain and on its boundary.
    domain : Domain or callable
        The domain (a plain signed distance needs ``bbox``).
    layers : float or None
        Elements across the thinnest parts: the size is at most ``feature_size / layers``.
        None leaves the feature size out (gradation only).
    rate : float or None
        Gradation limit |grad h| <= rate (:func:`limit_gradation`); None to skip it.
    min_size : float, optional
        Floor of the feature size (default: two background grid spacings).
    corner_angle : float
        See :func:`feature_size`.
    spacing, max_cells :
        Background grid, as in :func:`limit_gradation`; the default spacing is the smaller of
        h_min / 4 and the domain's diameter / 256, so that features thinner than h are seen.
    bbox : (xmin, ymin, xmax, ymax), optional
        Required for a callable ``domain``.

    Returns
    -------
    SizeFunction
        When neither the feature size nor the gradation limit changes h at any grid node, h
        itself restricted to the domain (:meth:`SizeFunction.restricted`), so a size that needs
        no correction is followed exactly.  (A domain with an exact boundary on which no two
        walls face each other within about ``layers * h``, :func:`thick_everywhere`, skips the
        feature-size grid; with a uniform size it needs no grid at all.)  Otherwise the
        corrected sizes on the background grid
        (a :class:`GriddedSize`); if the grid had to be coarser than h_min / 4 (``max_cells``),
        the minimum of that and the restricted h, so no detail of h is lost.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Rectangle
    >>> channel = Rectangle((0, 0), (2, 0.1))
    >>> h = effective_size(0.2, channel)
    >>> bool(h(np.array([[1.0, 0.05]]))[0] < 0.06)
    True
    """
    n_layers = _positive("layers", layers)
    g = None if rate is None else check_rate(rate)
    floor = _positive("min_size", min_size)
    angle = _positive("corner_angle", corner_angle)
    assert angle is not None
    check_grid_options(spacing, max_cells)
    dom = as_domain(domain, bbox=bbox)
    h = as_size_function(size)
    if n_layers is None and g is None:
        return h.restricted(dom)
    if h.constant is not None and (n_layers is None or _thick_uniform(dom, h.constant, n_layers, angle)):
        # A uniform size has no gradient to limit, and where no two walls are closer than a
        # few h the feature size is above it everywhere: h itself, with no grid at all.
        return h.restricted(dom)
    rate_ = 0.0 if g is None else g
    grid: Background | None = None
    thick = False
    lo: float | None = None  # the probe's h_min, once asked
    if spacing is None and n_layers is not None and exact_boundary(dom) is not None:
        # Thick everywhere by the probe's sizes (the bound checked on the grid below): then
        # the grid only has to resolve h (h_min / 4), not thin parts (diameter / 256).
        lo, hi = probe_range(h, dom)
        bound = PROBE_SLACK * hi
        # The margin is that of the grid the feature size would be computed on.
        fine = min(lo / CELLS_PER_H, dom.diameter / FEATURE_CELLS)
        if _thick(dom, bound, n_layers, angle, fine, _probe_h(h, dom)):
            # Kept only if thick (then only its signs, spacing and h are read: no feature
            # grid, no traced loops), so d's magnitudes need not be sampled.
            grid, h0 = sampled_grid(h, dom, None, int(max_cells), rate_, h_min=lo, signs_only=True)
            # A grid refined below the probe's h_min / 4 (smaller sizes, a thin domain) is
            # a case for the full computation.
            thick = float(h0[grid.inside].max()) <= bound and grid.spacing >= lo / CELLS_PER_H
            grid = grid if thick else None
    if grid is None:
        grid, h0 = sampled_grid(h, dom, spacing, int(max_cells), rate_, dom.diameter / FEATURE_CELLS,
                                h_min=lo)
    inside = grid.inside
    h_max = float(h0[inside].max()) if inside.any() else np.inf
    loops = None
    if not thick and n_layers is not None and exact_boundary(dom) is None and inside.any():
        # Without an exact boundary (a plain signed distance) the test below looks at the
        # curves traced on this grid, the boundary the feature size would be measured from.
        loops = _loops(dom, grid)
    if thick or n_layers is None or _thick(dom, h_max, n_layers, angle, grid.spacing, _probe_h(h, dom),
                                           loops):
        # No wall faces another within a few of the largest h: the feature size changes nothing.
        target = h0
    else:
        boundary = _boundary(dom, grid, loops)
        if spacing is None:
            finer = refine_for_gaps(dom, grid, angle, int(max_cells), boundary)
            if finer is not grid:
                grid, h0 = finer, sample_size(h, dom, finer, rate_)
                boundary = _boundary(dom, grid)
        fs = feature_grid(dom, grid, 2.0 * grid.spacing if floor is None else floor, angle, boundary)
        target = np.minimum(h0, fs / n_layers)
    out = target if g is None else limit_grid(target, grid, g)
    # Changes outside (band nodes lowered to the limited extension) do not count, nor rounding:
    # a cone of slope exactly ``rate`` comes back lower by an ulp here and there.
    inside = grid.inside
    field = GriddedSize._trusted(grid.x, grid.y, np.minimum(_fill_outside(out), dom.diameter))
    if (np.all(out[inside] >= h0[inside] * (1.0 - 1e-12))
            and not _jumps_on_boundary(h, dom, field, grid.spacing, rate_, loops)):
        return h.restricted(dom)
    if grid.capped:
        return SizeFunction(_Lower(field, h.restricted(dom)))
    return SizeFunction(field)


#: :func:`_jumps_on_boundary`: h on the boundary this much above what the grid allows there.
BOUNDARY_JUMP = 1.25


def _jumps_on_boundary(h: SizeFunction, domain: Domain, field: GriddedSize, spacing: float,
                       rate: float, loops: list[FloatArray] | None) -> bool:
    """Whether h on the boundary is well above the grid's sizes there (``BOUNDARY_JUMP`` times
    them plus the growth ``rate`` allows over two spacings).

    The grid nodes inside the domain can all agree with h while h jumps exactly on the
    boundary (``h = where(x < 0.5, 0.02, 0.08)`` on a domain whose side is x = 0.5): no node
    lies on the line, so h came back unchanged and the boundary was meshed at 0.08 against
    0.02 inside, a triangle of q = 0.01 (found by fuzzing).  The boundary is sampled about
    ``CELLS_PER_H`` spacings apart, about h_min (every so many points of its traced loops for
    a plain signed distance, when the caller has them): 0.1-0.4 ms on the paper's cases.
    """
    try:
        if loops is not None:
            pts = [lp[::int(CELLS_PER_H)] for lp in loops]
        else:
            pts = domain.boundary_loops(CELLS_PER_H * spacing)
    except GeometryError:
        return False
    if not pts:
        return False
    b = np.concatenate(pts)
    allowed = BOUNDARY_JUMP * (field(b) + 2.0 * rate * spacing)
    return bool(np.any(h.restricted(domain)(b) > allowed))


def _probe_h(h: SizeFunction, domain: Domain) -> Callable[[FloatArray], FloatArray]:
    """h for :func:`_thick`'s probes along chords between walls: h itself where it is defined
    everywhere (as :func:`unrestricted` decides), which saves the restriction's sdf call on
    every probe (4 s of the 20,000-vertex outline's 7 s here), else h restricted."""
    if h.constant is not None or getattr(h.function, "everywhere", False) is True:
        return h
    return h.restricted(domain)


def _thick(domain: Domain, h_max: float, layers: float, corner_angle: float, spacing: float,
           h: Callable[[FloatArray], FloatArray] | None = None,
           loops: list[FloatArray] | None = None) -> bool:
    """Whether the feature size is at least ``layers * h`` everywhere (:func:`thick_everywhere`,
    on ``loops`` when given), h bounded by ``h_max`` (uniform when ``h`` is None), walls back
    to back counted within a margin of a background grid of ``spacing``; a variable h is
    evaluated where two walls face each other."""
    factor, pad = THICK_MARGIN * layers, THICK_PAD * spacing

    def needed(p: FloatArray) -> FloatArray:
        if h is None:
            return np.full(len(p), factor * h_max)
        return np.asarray(factor * np.minimum(h(p), h_max), dtype=np.float64)

    return thick_everywhere(domain, factor * h_max + pad, corner_angle, needed, back_to_back=pad,
                            loops=loops)


def _thick_uniform(domain: Domain, size: float, layers: float, corner_angle: float) -> bool:
    """:func:`_thick` for a uniform size, with the spacing the background grid would have."""
    h = min(size, domain.diameter)
    return _thick(domain, h, layers, corner_angle, min(h / CELLS_PER_H, domain.diameter / FEATURE_CELLS))
