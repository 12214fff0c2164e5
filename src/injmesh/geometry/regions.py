"""Regions and interior curves: the constraint network the mesh must follow (issue 9).

A *region* is a sub-domain of the domain (a :class:`~injmesh.geometry.Domain`, or a plain
``d(p)`` with its bbox); regions may touch each other and the outer boundary but not overlap.
A *curve* is an open or closed polyline ``(k, 2)`` inside the domain (an interface, a crack, a
fault, a sensor line).  Both become *pieces*: polylines between *junctions*, where

* a piece is the part of a region's boundary inside the domain that no earlier region already
  has (a boundary shared by two regions is one piece, meshed once), or a user curve;
* junctions are the points where pieces end, cross or meet the outer boundary, plus the
  regions' corners and the curves' end points.  They become fixed nodes.

Every piece carries its own exact projection (the region's, or the polyline's), so Step 1 and
the smoothing keep its nodes on it.  Crossings closer than ``JUNCTION_MERGE * h_min`` are one
junction, and curves that meet at less than ``NARROW_ANGLE`` degrees there are reported with a
warning: no triangle in such an angle can be well shaped.  A region tangent to the outer
boundary or to an earlier region (a *wall*) follows the wall where it runs within
``BOUNDARY_MERGE * h_min`` of it, near parallel, and meets it where it leaves that band: the
cusps beside the contact, which no triangle fills, are bridged.  A piece that leaves a wall at
less than ``WALL_ANGLE`` degrees, or ends within the band, projects onto itself, never onto
the wall beside the junction (:class:`_OffTheWall`); an end put on a wall within
``BOUNDARY_MERGE * h_min`` of one of its corners is that corner.  A region's corner within the
band of a wall is moved onto it, its sides running to it from ``CORNER_REACH`` band widths
away, and its pieces project onto those two segments there (:class:`_MovedCorners`).  The
corners of the domain and of earlier regions on a region's boundary are vertices of it.  A user
curve passing a fixed vertex (a region's corner, a corner of the boundary) within
``JUNCTION_MERGE * h_min`` is made to pass through it, and then slides on the polyline so bent;
one whose end misses its start by that little is closed.  Inputs are checked here, once: a
region that leaves the domain, two regions that overlap, a curve that leaves the domain or
crosses itself each raise :class:`RegionError` or :class:`CurveError` naming the region or
curve and a point.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import _tolerances as tol
from .base import Domain, GeometryError
from .brep import BRep
from .implicit import as_domain
from .tracing import grid_spacing

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]
Projector = Callable[[FloatArray], FloatArray]

#: Alternating projections that place a crossing of two curved pieces on both.
CROSSING_ITERATIONS = 20
#: Crossings closer than this fraction of h_min are one junction.  Where two curves touch
#: (tangent circles) the crossings of their polylines are ill-conditioned and scatter around
#: the contact by ~1e-3 h: kept apart, they became two nodes 4e-5 apart and a triangle with
#: q = 0.001.  Two junctions this close could not be resolved by elements of size h anyway.
JUNCTION_MERGE = 0.05
#: A region's boundary within this fraction of h_min of the outer boundary, over a stretch,
#: is taken to run along it (a region tangent to the boundary, or hugging it closer than any
#: element could resolve): the stretch is the boundary's, and the region's curve meets the
#: boundary where it leaves that band.
BOUNDARY_MERGE = JUNCTION_MERGE
#: ... and within ``MERGE_ANGLE`` degrees of parallel to it.  A region that crosses the
#: boundary at an angle (a disc clipped by the domain: a lens) meets it at that angle whatever
#: is merged, and a stretch merged next to the crossing (its first vertex within the band for a
#: fine sampling) only moved the junction along the boundary, past the region's true corner:
#: the curve's nodes there then slid onto the region's side that is the boundary (a lost
#: boundary segment, found by fuzzing).
MERGE_ANGLE = 15.0
#: Curves meeting at a smaller angle (degrees) at a junction get a warning: no triangle in
#: that angle can be well shaped.
NARROW_ANGLE = 10.0
#: A curve turning back on itself with its two sides closer than this angle (degrees) is
#: refused: one h_min from the vertex they are less than ``JUNCTION_MERGE * h_min`` apart, and
#: at 0.3-1 degrees (h = 0.05, found by fuzzing) the triangles between them had zero area.
FOLD_ANGLE = math.degrees(JUNCTION_MERGE)


class RegionError(GeometryError):
    """A region is invalid: empty, partly outside the domain, or overlapping another region."""


class CurveError(GeometryError):
    """An interior curve is invalid: too few points, not finite, leaving the domain, or crossing
    itself."""


@dataclass(frozen=True)
class Piece:
    """One stretch of interior constraint curve.

    Attributes
    ----------
    points : (k, 2) array
        A polyline on the curve (for a closed piece the first vertex is not repeated).
    fixed : (k,) bool array
        Vertices that must be nodes: junctions, end points, corners.
    closed : bool
        Whether the last vertex joins the first.
    project : callable
        Nearest point on the piece's curve of each of ``(n, 2)`` points.
    owner : int
        Region number (1-based) of a region's boundary, or ``-1 - c`` for user curve c.
    """

    points: FloatArray
    fixed: BoolArray
    closed: bool
    project: Projector
    owner: int


@dataclass(frozen=True)
class Constraints:
    """Regions and curves made ready for meshing.

    Attributes
    ----------
    pieces : tuple of Piece
    regions : tuple of Domain
        The regions, numbered from 1 (tag 0 is the rest of the domain).
    region_names : tuple of str
        ``region_names[0] == "domain"``, then the regions' names in the order given.
    curve_names : tuple of str
        The user curves' names in the order given.
    boundary_junctions : (j, 2) array
        Junctions on the domain's boundary: Step 1 must have nodes there.
    """

    pieces: tuple[Piece, ...]
    regions: tuple[Domain, ...]
    region_names: tuple[str, ...]
    curve_names: tuple[str, ...]
    boundary_junctions: FloatArray

    def region_of(self, q: FloatArray) -> NDArray[np.intp]:
        """Region number of each point (0 when in none): the region with the most negative d."""
        tags = np.zeros(len(q), dtype=np.intp)
        best = np.zeros(len(q))
        for k, r in enumerate(self.regions, start=1):
            d = r.sdf(q)
            inside = d < best
            tags[inside] = k
            best[inside] = d[inside]
        return tags


RegionsLike = Mapping[str, "Domain | Callable[[FloatArray], FloatArray] | object"]
CurvesLike = Mapping[str, ArrayLike] | Sequence[ArrayLike]


def build_constraints(
    domain: Domain,
    regions: RegionsLike | None,
    curves: CurvesLike | None,
    h_min: float,
) -> Constraints:
    """Check regions and curves against the domain and split them into pieces.

    Parameters
    ----------
    domain : Domain
        The (cleaned) domain.
    regions : mapping name -> Domain or callable, optional
        Sub-regions; a plain callable uses the domain's bbox.
    curves : mapping name -> (k, 2) array_like, or a sequence of them, optional
        Polylines; a sequence names them ``"curve 1"``, ``"curve 2"``, ...  A polyline whose
        last point equals its first, or misses it by less than ``JUNCTION_MERGE * h_min``
        (with a warning), is closed.
    h_min : float
        Smallest target size: the resolution of traced region boundaries.

    Raises
    ------
    RegionError, CurveError
        What is wrong, with the region's or curve's name and a point.

    Examples
    --------
    >>> from injmesh import Circle, Rectangle
    >>> c = build_constraints(Rectangle((0, 0), (1, 1)), {"disc": Circle((0.5, 0.5), 0.2)},
    ...                       [[(0.1, 0.1), (0.2, 0.3)]], 0.05)
    >>> c.region_names, c.curve_names, [p.closed for p in c.pieces]
    (('domain', 'disc'), ('curve 1',), [True, False])
    """
    diam = domain.diameter
    eps = tol.ON_BOUNDARY * diam
    names, doms = _regions(domain, regions)
    curve_names, lines = _curves(curves)
    pieces: list[Piece] = []
    for k, (name, r) in enumerate(zip(names, doms, strict=True), start=1):
        pieces += _region_pieces(domain, name, r, dict(zip(names[: k - 1], doms[: k - 1], strict=True)),
                                 k, h_min, eps)
    _check_overlaps(names, doms, h_min, eps)
    for c, (name, line) in enumerate(zip(curve_names, lines, strict=True)):
        pieces.append(_curve_piece(domain, name, line, c, h_min, eps))
    pieces = _join(pieces, eps, max(10 * eps, JUNCTION_MERGE * h_min))
    _warn_narrow_angles(pieces, names, curve_names)
    junctions = [p.points[p.fixed] for p in pieces]
    allj = np.concatenate(junctions) if junctions else np.empty((0, 2))
    on = np.abs(domain.sdf(allj)) <= eps if len(allj) else np.zeros(0, dtype=bool)
    bj = _unique_points(allj[on], eps)
    return Constraints(tuple(pieces), tuple(doms), ("domain", *names), tuple(curve_names), bj)


# --- input ------------------------------------------------------------------------------------


def _regions(domain: Domain, regions: RegionsLike | None) -> tuple[list[str], list[Domain]]:
    if regions is None:
        return [], []
    if not isinstance(regions, Mapping):
        raise TypeError(f"regions must be a mapping name -> Domain, got {type(regions).__name__}")
    names, doms = [], []
    for name, r in regions.items():
        if not isinstance(name, str) or not name.strip():
            raise RegionError(f"region names must be non-empty strings, got {name!r}")
        if name == "domain":
            raise RegionError("'domain' names the rest of the domain; choose another region name")
        try:
            d = as_domain(r, bbox=domain.bbox if callable(r) and not isinstance(r, Domain) else None)
        except (TypeError, ValueError) as exc:
            raise RegionError(f"region {name!r}: {exc}") from None
        names.append(name)
        doms.append(d)
    return names, doms


def _curves(curves: CurvesLike | None) -> tuple[list[str], list[FloatArray]]:
    if curves is None:
        return [], []
    if isinstance(curves, Mapping):
        items = list(curves.items())
    else:
        items = [(f"curve {k}", c) for k, c in enumerate(curves, start=1)]
    names, lines = [], []
    for name, c in items:
        if not isinstance(name, str) or not name.strip():
            raise CurveError(f"curve names must be non-empty strings, got {name!r}")
        try:
            a = np.asarray(c, dtype=float)
        except (TypeError, ValueError):
            raise CurveError(f"curve {name!r} is not an (k, 2) array of numbers") from None
        if a.ndim != 2 or a.shape[1] != 2 or len(a) < 2:
            raise CurveError(f"curve {name!r} must have shape (k, 2) with k >= 2, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise CurveError(f"curve {name!r} has a coordinate that is not finite")
        # Repeated consecutive points carry nothing.
        keep = np.r_[True, np.any(a[1:] != a[:-1], axis=1)]
        a = a[keep]
        if len(a) < 2:
            raise CurveError(f"curve {name!r} has fewer than two distinct points")
        names.append(name)
        lines.append(a)
    return names, lines


# --- pieces -----------------------------------------------------------------------------------


def _region_pieces(
    domain: Domain, name: str, region: Domain, earlier: Mapping[str, Domain], k: int, h_min: float,
    eps: float
) -> list[Piece]:
    """The stretches of a region's boundary inside the domain and on no earlier region.

    "On" the outer boundary or an earlier region (a *wall*) means on it to ``eps``, or running
    along it within ``BOUNDARY_MERGE * h_min`` and ``MERGE_ANGLE`` degrees of parallel: a region
    tangent to a wall follows the wall over the stretch where no element could fit between
    them, and its curve meets the wall where it leaves that band.
    """
    try:
        loops = region.boundary_loops(grid_spacing(region.bbox, h_min))
    except GeometryError as exc:
        raise RegionError(f"region {name!r}: {exc}") from None
    if not loops:
        raise RegionError(f"region {name!r} is empty")
    merge = max(eps, BOUNDARY_MERGE * h_min)
    allv = np.concatenate(loops)
    out = domain.sdf(allv) > max(eps, tol.ON_BOUNDARY * region.diameter)
    if out.any():
        x, y = allv[np.argmax(out)]
        raise RegionError(f"region {name!r} extends outside the domain near ({x:.6g}, {y:.6g})")
    _check_region_edges(domain, name, region, loops, h_min, eps)
    corners = region.corners()
    # The domain's corners on the region's boundary are where it leaves the outer boundary or
    # joins it: vertices of the loop, so each edge is wholly on the boundary or off it.  (A
    # region's side from (0.875, 0.375) to (0.875, 0.875), on the boundary at both ends but not
    # in the middle, where another operand bulged out, was kept whole as an interface lying on
    # the boundary: 17 lost segments, found by fuzzing.)  So are an earlier region's corners:
    # a box's side along another box's for half its length was kept whole, lying on the other's
    # side (a duplicate node and 17 lost segments, found by fuzzing).
    outer = np.concatenate([np.asarray(w.corners(), dtype=np.float64).reshape(-1, 2)
                            for w in (domain, *earlier.values())])
    if len(outer):
        outer = outer[np.abs(region.sdf(outer)) <= eps]
    if len(outer):
        near = max(10 * eps, 1e-3 * h_min)
        loops = [_insert(Piece(lp, np.zeros(len(lp), dtype=bool), True, region.project, k), on, eps).points
                 if len(on := outer[_polyline_distance(outer, lp) <= near]) else lp for lp in loops]
        corners = np.concatenate([corners.reshape(-1, 2), outer])
    walls = [domain, *earlier.values()]
    wall_names = ["the boundary", *(f"region {nm!r}" for nm in earlier)]
    for wall in walls:
        loops = [_tangent_exits(wall, region, _touch_points(wall, region, lp, h_min, merge, eps), merge, eps)
                 for lp in loops]
    loops, moved_corners = _corners_onto_walls(loops, corners, walls, merge, eps)
    if moved_corners:
        corners = np.concatenate([corners.reshape(-1, 2), *(c.now[None, :] for c in moved_corners)])
    pieces = []
    for loop in loops:
        nxt = np.roll(loop, -1, axis=0)
        mid = region.project(0.5 * (loop + nxt))
        if np.any(domain.sdf(mid) > eps):
            x, y = mid[np.argmax(domain.sdf(mid) > eps)]
            raise RegionError(f"region {name!r} extends outside the domain near ({x:.6g}, {y:.6g})")
        # An edge along the outer boundary or along an earlier region is not a new curve.
        # "Along" means on it, or within BOUNDARY_MERGE * h_min of it, ends included, and near
        # parallel: a region tangent to a wall comes within 1e-6 of it near the contact, and its
        # nodes there made triangles of zero area with the wall's.
        drop = np.zeros(len(loop), dtype=bool)
        near_any = np.zeros(len(loop), dtype=bool)
        wall_of = np.full(len(loop), -1)
        edge_len = np.hypot(*(nxt - loop).T)
        hugs = np.zeros((len(walls), len(loop)), dtype=bool)
        mids_in = np.zeros((len(walls), len(loop)), dtype=bool)
        for w, (wall, wall_name) in enumerate(zip(walls, wall_names, strict=True)):
            d_loop = wall.sdf(loop)
            hug = hugs[w] = np.abs(d_loop) <= merge
            dm = np.abs(wall.sdf(mid))
            mids_in[w] = dm <= merge
            along = np.abs(np.roll(d_loop, -1) - d_loop) <= math.sin(math.radians(MERGE_ANGLE)) * edge_len
            # An edge on the wall has its ends near it too: a midpoint alone touching it (a
            # hole tangent to a box's side at the side's middle) dropped the whole side, and
            # the region vanished from the tags.
            ends = hug & np.roll(hug, -1)
            near = (dm <= merge) & ends & along
            new = (((dm <= eps) & ends) | near) & ~drop
            wall_of[new] = w
            drop |= new
            merged = new & (dm > eps)
            near_any |= merged
            if merged.any():
                import warnings

                x, y = mid[np.argmax(merged)]
                warnings.warn(
                    f"region {name!r} runs within {BOUNDARY_MERGE:g} h of {wall_name} near "
                    f"({x:.6g}, {y:.6g}) (tangent to it?): it follows {wall_name} there, and the "
                    "triangles in the narrow angle where it leaves cannot be well shaped",
                    stacklevel=4,
                )
        _drop_slivers(drop, wall_of, hugs, mids_in)
        if drop.all() and near_any.any() and _mean_width(loop) < merge:
            # (A region filling the domain but for a sliver along its side is the domain, and
            # the sliver vanishes; a region that is the sliver cannot be meshed.)
            x, y = loop.mean(axis=0)
            raise RegionError(f"region {name!r} near ({x:.6g}, {y:.6g}) lies within {BOUNDARY_MERGE:g} h "
                              f"({merge:.3g}) of the boundary or of other regions all round: a sliver "
                              f"{_mean_width(loop):.2g} wide on average, which no element fits in")
        fixed = np.zeros(len(loop), dtype=bool)
        if len(corners):
            from scipy.spatial import cKDTree

            dist, _ = cKDTree(corners).query(loop)
            fixed = dist <= eps
        if not drop.any():
            pieces.append(Piece(loop, fixed, True, _with_moved(region.project, loop, moved_corners, eps), k))
            continue
        # Runs of kept edges, each from a vertex after a dropped edge to one before the next.
        start = int(np.argmax(drop)) + 1
        order = (np.arange(len(loop)) + start) % len(loop)
        d = drop[order]
        run = 0
        while run < len(d):
            if d[run]:
                run += 1
                continue
            end = run
            while end < len(d) and not d[end]:
                end += 1
            idx = order[np.arange(run, end + 1) % len(loop)]  # end edge's far vertex included
            f = fixed[idx].copy()
            f[[0, -1]] = True
            pts = loop[idx].copy()
            # An end within the merge distance of the wall along which the edge beyond it was
            # dropped (a tangent stretch) is put on that wall: the junction joins it.
            narrow: list[Domain] = []
            curve = pts.copy()  # the region's own curve: the ends before they are put on a wall
            for e, beyond in ((0, order[(run - 1) % len(loop)]), (len(pts) - 1, order[end % len(loop)])):
                wall = walls[wall_of[beyond]]
                gap = abs(float(wall.sdf(pts[e:e + 1])[0]))
                moved = eps < gap <= merge
                if moved:
                    pts[e] = wall.project(pts[e:e + 1])[0]
                    # Within the merge distance of one of the wall's corners, it is that
                    # corner: two junctions that close are one (a disc tangent to a box's
                    # side at the box's corner ended 0.03 h from it, and the triangles
                    # between the two had no area; found by fuzzing).
                    wc = np.asarray(wall.corners(), dtype=np.float64).reshape(-1, 2)
                    if len(wc):
                        dc = np.hypot(*(wc - pts[e]).T)
                        if dc.min() <= merge:
                            pts[e] = wc[int(np.argmin(dc))]
                # An end put on the wall, or leaving it narrowly: the region's boundary beside
                # the junction lies within the band of the wall, off the piece.
                if (moved or _leaves_narrowly(wall, pts, e, 0.5 * h_min)) \
                        and all(w is not wall for w in narrow):
                    narrow.append(wall)
            if narrow:
                # Each end moved onto its wall, then the region's curve from where it was: the
                # piece's polyline, and the one its projection falls back on.  (From the moved
                # end straight to the next vertex, a box's side ran slanted, up to the band off
                # the side; points put on it by the fallback crowded beside the junction.)
                line = np.concatenate([pts[:1], curve, pts[-1:]])
                f = np.concatenate([f[:1], np.zeros(1, dtype=bool), f[1:-1], np.zeros(1, dtype=bool), f[-1:]])
                keep = np.r_[True, np.hypot(*np.diff(line, axis=0).T) > eps]
                if not keep[-1]:  # an end not moved: its twin before it goes, not the end
                    keep[-1], keep[-2] = True, False
                pts, f = line[keep], f[keep]
                project: Projector = _OffTheWall(region.project, pts, narrow, merge,
                                                 max(10 * eps, 0.01 * merge))
            else:
                project = region.project
            pieces.append(Piece(pts, f, False, _with_moved(project, pts, moved_corners, eps), k))
            run = end
    return pieces


def _corners_onto_walls(loops: list[FloatArray], corners: FloatArray, walls: list[Domain], merge: float,
                        eps: float) -> tuple[list[FloatArray], list[_MovedCorner]]:
    """The loops with each of the region's corners that lies within ``merge`` of a wall, but
    not on it, moved onto the wall, and the corners so moved.

    No element resolves a gap that narrow: a box's corner 7e-5 inside a circular part of the
    boundary (0.002 h) was a node 7e-5 from the boundary's, and the triangle between them had
    no area (found by fuzzing).  The corner touches the wall now, a junction on it.  (Edges
    running along a wall within the band are merged into it by :func:`_region_pieces`; this
    takes the corners whose edges leave it.)  The loop gets a vertex on each of the corner's
    sides ``CORNER_REACH * merge`` from it (or halfway to the next vertex), where it runs
    from the side to the moved corner: the rest of the loop is the region's boundary still
    (:class:`_MovedCorners`).
    """
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if not len(corners):
        return loops, []
    from scipy.spatial import cKDTree

    tree = cKDTree(corners)
    records: list[_MovedCorner] = []
    out = []
    for lp in loops:
        lp = np.array(lp, dtype=np.float64)
        at_corner = tree.query(lp)[0] <= eps
        onto = np.full(len(lp), -1)
        for w, wall in enumerate(walls):
            if not at_corner.any():
                break
            idx = np.flatnonzero(at_corner)
            gap = np.abs(wall.sdf(lp[idx]))
            near = idx[(gap > eps) & (gap <= merge)]
            if len(near):
                # A lone corner: its neighbours along the loop are off the band (a corner of a
                # sliver along the wall is the sliver's, which is refused by name below).
                far = np.abs(wall.sdf(np.concatenate([lp[(near - 1) % len(lp)], lp[(near + 1) % len(lp)]])))
                near = near[(far[:len(near)] > merge) & (far[len(near):] > merge)]
            if len(near):
                onto[near] = w
                at_corner[near] = False
        rows: list[FloatArray] = []
        for i in range(len(lp)):
            if onto[i] < 0:
                rows.append(lp[i:i + 1])
                continue
            c, a, b = lp[i], lp[i - 1], lp[(i + 1) % len(lp)]
            reach = min(CORNER_REACH * merge, 0.5 * float(np.hypot(*(a - c))),
                        0.5 * float(np.hypot(*(b - c))))
            before = c + reach * (a - c) / np.hypot(*(a - c))
            after = c + reach * (b - c) / np.hypot(*(b - c))
            moved = walls[int(onto[i])].project(c[None, :])[0]
            records.append(_MovedCorner(c.copy(), moved, before, after, reach))
            rows.append(np.stack([before, moved, after]))
        out.append(np.concatenate(rows) if rows else lp)
    return out, records


#: :func:`_corners_onto_walls`: a moved corner's sides run to it from this many merge
#: distances away (a slant of at most atan(1 / CORNER_REACH), 14 degrees).
CORNER_REACH = 4.0


@dataclass(frozen=True)
class _MovedCorner:
    """A region's corner moved onto a wall (:func:`_corners_onto_walls`): where it was, where
    it is, and the loop's vertices ``reach`` from it on its two sides."""

    was: FloatArray
    now: FloatArray
    before: FloatArray
    after: FloatArray
    reach: float


class _MovedCorners:
    """A region's projection with its corners moved onto walls: a point the region projects
    within a corner's reach of where the corner was goes to the nearest point of the two
    segments from the corner's side vertices to where it is now.

    The region's own projection still has the corner where it was: points beside the moved
    corner went back to it, up to the merge band off the wall, and the piece ran from the old
    corner to the new and back (a box's corner h/25 inside a circle: lost segments, found by
    fuzzing).  At the reach the two agree (the side vertices are the region's boundary there),
    so the projection stays continuous.  Pieces that use it are projected in Python in the
    smoothing, not in its compiled steps; they are rare.
    """

    def __init__(self, project: Projector, corners: list[_MovedCorner]) -> None:
        self.project, self.corners = project, corners

    def __call__(self, q: FloatArray) -> FloatArray:
        out = np.array(self.project(q), dtype=np.float64)
        q = np.asarray(q, dtype=np.float64)
        for c in self.corners:
            near = np.flatnonzero(np.hypot(*(out - c.was).T) < c.reach)
            if not len(near):
                continue
            a = np.stack([c.before, c.now])
            b = np.stack([c.now, c.after])
            s2, t2, _ = _nearest_segment(q[near], a, b)
            out[near] = a[s2] + t2[:, None] * (b[s2] - a[s2])
        return out


def _with_moved(project: Projector, pts: FloatArray, corners: list[_MovedCorner], eps: float) -> Projector:
    """``project``, through :class:`_MovedCorners` for the moved corners that are vertices of
    the piece ``pts``."""
    mine = [c for c in corners if np.min(np.hypot(*(pts - c.now).T)) <= eps]
    return _MovedCorners(project, mine) if mine else project


#: A region's piece that leaves a wall (the boundary, an earlier region) at less than this many
#: degrees, or whose end was put on the wall from within the merge band, projects through
#: :class:`_OffTheWall`: the merge test's near-parallel angle.  The failures it mends were at
#: 0-9 degrees; such a piece is projected in Python in the smoothing, which made a lens region
#: 20 degrees off a side 30 % slower at 72,000 nodes (the same mesh).
WALL_ANGLE = MERGE_ANGLE


def _leaves_narrowly(wall: Domain, pts: FloatArray, e: int, reach: float) -> bool:
    """Whether the open polyline ``pts`` leaves ``wall`` at its end ``e`` (0 or the last) at
    less than ``WALL_ANGLE`` degrees: the chord from that end to its first vertex ``reach`` or
    more away (or the other end) against the wall's tangent there.  (Its first segment alone
    can be steep: an end within the merge band is put on the wall.)"""
    if len(pts) < 2:
        return False
    run = pts if e == 0 else pts[::-1]
    far = np.flatnonzero(np.hypot(*(run - run[0]).T) >= reach)
    step = run[far[0] if len(far) else -1] - run[0]
    normal = wall.gradient(pts[e:e + 1])[0]
    size = float(np.hypot(*step)) * float(np.hypot(*normal))
    if not size > 0.0 or not np.all(np.isfinite(normal)):
        return False
    return abs(float(step @ normal)) / size < math.sin(math.radians(WALL_ANGLE))


class _OffTheWall:
    """A region's projection for one of its pieces that leaves a wall at a narrow angle (or
    whose end was put on the wall from within the merge band).

    Beside such a junction the region's boundary runs on (or within the merge band of) the
    wall, a fraction of h from the piece: the region's own projection sent points near the
    junction (the midpoints Step 1 projects, a node the smoothing moves) onto the wall, where
    they became nodes on the domain's boundary that are not boundary nodes (a lost boundary
    segment; a disc's arc 9 degrees off a rectangle's side, found by fuzzing; a box's side
    tangent to a hole at the box's corner).  A point the region projects within ``band`` of
    one of those walls and off the piece (farther than ``tol`` from its polyline) goes to the
    nearest point of the polyline instead: the junction on the wall, the chord to where the
    region's curve left the band, then the curve sampled at the tracing resolution (a chord's
    sagitta from it at most).

    Pieces that use it are projected in Python in the smoothing, not in its compiled steps (a
    region's compiled boundary is the whole region's); they are rare.
    """

    def __init__(self, project: Projector, points: FloatArray, walls: list[Domain], band: float,
                 tol: float) -> None:
        self.project, self.walls, self.band, self.tol = project, walls, band, tol
        self.a, self.b = points[:-1].copy(), points[1:].copy()

    def __call__(self, q: FloatArray) -> FloatArray:
        out = np.array(self.project(q), dtype=np.float64)
        if len(q) == 0 or len(self.a) == 0:
            return out
        near = np.zeros(len(out), dtype=bool)
        for wall in self.walls:
            near |= np.abs(wall.sdf(out)) <= self.band
        if not near.any():
            return out
        idx = np.flatnonzero(near)
        _, _, dist = _nearest_segment(out[idx], self.a, self.b)
        off = idx[dist > self.tol]
        if len(off):
            s2, t2, _ = _nearest_segment(np.asarray(q, dtype=np.float64)[off], self.a, self.b)
            out[off] = self.a[s2] + t2[:, None] * (self.b[s2] - self.a[s2])
        return out


#: Bisections that find where an edge leaving the boundary tangentially leaves the merge band.
EXIT_BISECTIONS = 50
#: ... an edge that leaves within this many degrees of the wall's tangent at the vertex.
EXIT_ANGLE = 2.0


def _mean_width(loop: FloatArray) -> float:
    """Twice the area of a closed polyline over its length: the width of a strip."""
    from .primitives import _perimeter, _shoelace

    return 2.0 * abs(_shoelace(loop)) / max(_perimeter(loop), 1e-300)


def _drop_slivers(drop: BoolArray, wall_of: NDArray[np.intp], hugs: BoolArray, mids_in: BoolArray) -> None:
    """Drop (in place) each run of kept edges between two dropped ones whose vertices and
    edge midpoints all lie within the merge band of the wall the run leaves (``hugs[w]``,
    ``mids_in[w]``: the vertices, the edges' midpoints within the band of wall w), and which
    returns to that wall.

    Such a run bounds a sliver narrower than the band, between the region and the wall (an arc
    cutting a corner of the domain 0.0016 from it; a region 0.0024 thick along the boundary):
    its edges turn with the wall's corner or the sliver's end, so the near-parallel test kept
    some of them, and the pieces left inside the sliver were lost segments (found by fuzzing).
    The region follows the wall there instead.
    """
    n = len(drop)
    if not drop.any() or drop.all():
        return
    start = int(np.argmax(drop)) + 1
    k = 0
    while k < n:
        e = (start + k) % n
        if drop[e]:
            k += 1
            continue
        run = []
        while k < n and not drop[(start + k) % n]:
            run.append((start + k) % n)
            k += 1
        before, after = wall_of[(run[0] - 1) % n], wall_of[(run[-1] + 1) % n]
        verts = np.array(run + [(run[-1] + 1) % n])
        if before == after and before >= 0 and hugs[before][verts].all() and mids_in[before][run].all():
            drop[run] = True
            wall_of[run] = before


#: Ternary-search steps that find where an edge touches a wall between its vertices.
TOUCH_STEPS = 60


def _touch_points(wall: Domain, region: Domain, loop: FloatArray, h_min: float, merge: float, eps: float
                  ) -> FloatArray:
    """The region's loop with a vertex added where an edge touches ``wall`` (to ``eps``)
    between its vertices: a circular hole of the domain tangent to a box's side in its middle,
    a disc touching a box's side (found by fuzzing: degenerate triangles in the cusps on both
    sides of the contact).  :func:`_tangent_exits` then bridges the cusps from that vertex.

    Each edge is sampled every h_min / 4; a sample within ``merge`` of the wall, no farther
    than its neighbours and not between two on it (an edge along the wall is the merge test's)
    is refined by ternary search between its neighbours.
    """
    nxt = np.roll(loop, -1, axis=0)
    n = len(loop)
    count = np.minimum(np.ceil(np.hypot(*(nxt - loop).T) / (0.25 * h_min)).astype(int) + 1, 10_000)
    edge = np.repeat(np.arange(n), count + 1)
    first = np.repeat(np.cumsum(count + 1) - (count + 1), count + 1)
    t = (np.arange(len(edge)) - first) / np.repeat(count, count + 1)
    q = region.project(loop[edge] + t[:, None] * (nxt[edge] - loop[edge]))
    g = np.abs(wall.sdf(q))
    same_prev = np.r_[False, edge[1:] == edge[:-1]]
    same_next = np.r_[edge[:-1] == edge[1:], False]
    inner = same_prev & same_next  # samples strictly between an edge's ends
    low = np.zeros(len(g), dtype=bool)
    low[1:-1] = inner[1:-1] & (g[1:-1] <= merge) & (g[1:-1] <= g[:-2]) & (g[1:-1] <= g[2:]) & (
        (g[:-2] > eps) | (g[2:] > eps))
    keys: list[float] = []
    points: list[FloatArray] = []
    for k in np.flatnonzero(low).tolist():
        e = int(edge[k])
        v, w = loop[e], nxt[e]

        def gap(tt: float, v: FloatArray = v, w: FloatArray = w) -> tuple[FloatArray, float]:
            p = region.project((v + tt * (w - v))[None, :])
            return p[0], float(np.abs(wall.sdf(p))[0])

        lo, hi = float(t[k - 1]), float(t[k + 1])
        for _ in range(TOUCH_STEPS):
            m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
            if gap(m1)[1] <= gap(m2)[1]:
                hi = m2
            else:
                lo = m1
        p, dist = gap(0.5 * (lo + hi))
        if dist <= eps and min(np.hypot(*(p - v)), np.hypot(*(p - w))) > 10 * eps:
            points.append(p)
            keys.append(e + 0.5 * (lo + hi))
    return _with_vertices(loop, keys, points)


def _tangent_exits(wall: Domain, region: Domain, loop: FloatArray, merge: float, eps: float
                   ) -> FloatArray:
    """The region's loop with a vertex added on each edge that leaves ``wall`` (the outer
    boundary or an earlier region) at one of its vertices within ``EXIT_ANGLE`` of tangent,
    where the edge leaves the band of width ``merge`` along the wall.

    A rectangle's corner touching a circular part of the boundary, its side tangent to the
    circle there, leaves a cusp of zero angle between side and circle, which no triangle fills:
    63 segments of the side were lost (found by fuzzing).  The side's vertices are far from the
    boundary, so no edge lay within the band, to be merged into the boundary as a tangent
    stretch is.  With the band's exit a vertex, the stretch before it is such an edge: the
    region follows the boundary up to the exit, and its side meets the boundary there.
    """
    d = wall.sdf(loop)
    on = np.flatnonzero(np.abs(d) <= eps)
    if not len(on):
        return loop
    n = len(loop)
    sin_a = math.sin(math.radians(MERGE_ANGLE))
    # Points along an edge from its vertex on the boundary: geometric steps (a tangent side
    # leaves the band at ~sqrt(2 R merge), a fraction of the edge), then bisection.
    steps = np.geomspace(1e-9, 1.0, 64)
    keys: list[float] = []
    points: list[FloatArray] = []
    for i in on.tolist():
        for far, edge in (((i + 1) % n, i), ((i - 1) % n, (i - 1) % n)):
            v, w = loop[i], loop[far]

            def gap(t: FloatArray, v: FloatArray = v, w: FloatArray = w) -> tuple[FloatArray, FloatArray]:
                q = region.project(v + t[:, None] * (w - v))
                return q, np.abs(wall.sdf(q))

            q, g = gap(steps)
            out = np.flatnonzero(g > merge)
            if not len(out) or out[0] == 0:
                continue  # the whole edge in the band (the merge test decides on it), or none
            lo, hi = steps[out[0] - 1], steps[out[0]]
            for _ in range(EXIT_BISECTIONS):
                mid = 0.5 * (lo + hi)
                if gap(np.array([mid]))[1][0] <= merge:
                    lo = mid
                else:
                    hi = mid
            exit_point = gap(np.array([lo]))[0][0]
            if merge > sin_a * float(np.hypot(*(exit_point - v))):
                continue  # the edge leaves at an angle: a junction at the vertex, as it is
            # Tangent at the vertex (the gap grows as the square of the distance), not a
            # crossing at a small angle (as the distance): such a region meets the wall at
            # that angle, and bridging the first merge-wide stretch would leave a sliver of
            # region beyond it narrower still (a polygon's side 8.5 degrees off a circle;
            # found by fuzzing).
            t_near = min(1.0, merge / max(float(np.hypot(*(w - v))), 1e-300))
            if gap(np.array([t_near]))[1][0] > math.sin(math.radians(EXIT_ANGLE)) * merge:
                continue
            points.append(exit_point)
            keys.append(edge + (lo if edge == i else 1.0 - lo))
    return _with_vertices(loop, keys, points)


def _check_region_edges(domain: Domain, name: str, region: Domain, loops: list[FloatArray],
                        h_min: float, eps: float) -> None:
    """A region's edges must stay inside the domain between their vertices too.

    A polygon region's loop is its vertices: an edge that cuts across a reflex corner of the
    domain (a notch, a rectangular hole) with both ends and its midpoint inside went
    unnoticed, and its interface nodes outside made an invalid mesh (found by fuzzing).  The
    edges are sampled every quarter h_min (on the region's boundary), and a corner of the
    domain strictly inside the region within 2 h_min of the region's boundary is an edge
    cutting across it.  (A hole wholly inside a region, far from its boundary, is allowed: the
    region is taken within the domain.)
    """
    for loop in loops:
        nxt = np.roll(loop, -1, axis=0)
        n = np.maximum(1, np.ceil(np.hypot(*(nxt - loop).T) / (0.25 * h_min)).astype(int))
        if np.all(n == 1):
            continue
        k = np.repeat(np.arange(len(loop)), n)
        t = (np.arange(len(k)) - np.repeat(np.cumsum(n) - n, n)) / n[k]
        q = region.project(loop[k] + t[:, None] * (nxt[k] - loop[k]))
        out = domain.sdf(q) > eps
        if out.any():
            x, y = q[np.argmax(out)]
            raise RegionError(f"region {name!r} extends outside the domain near ({x:.6g}, {y:.6g})")
    corners = domain.corners()
    if len(corners):
        d = region.sdf(corners)
        cut = (d < -max(eps, 1e-3 * h_min)) & (d > -2.0 * h_min)
        if cut.any():
            x, y = corners[np.argmax(cut)]
            raise RegionError(f"region {name!r} extends outside the domain: its boundary cuts across "
                              f"the domain's corner at ({x:.6g}, {y:.6g})")


def _check_overlaps(names: list[str], doms: list[Domain], h_min: float, eps: float) -> None:
    """Two regions overlap when a point of one's boundary lies strictly inside the other: its
    vertices and points at most h_min / 2 apart along its edges (two boxes crossing like a
    plus sign have no vertex inside each other; found by fuzzing, meshed with the tags of one
    of them in the overlap)."""
    from ..kernels.raster import densify

    loops = [np.concatenate([densify(np.ascontiguousarray(lp, dtype=np.float64), 0.5 * h_min)
                             for lp in d.boundary_loops(grid_spacing(d.bbox, h_min))]) for d in doms]
    for i in range(len(doms)):
        for j in range(len(doms)):
            if i == j:
                continue
            d = doms[j].sdf(loops[i])
            deep = d < -max(eps, 1e-3 * h_min)
            if deep.any():
                x, y = loops[i][np.argmax(deep)]
                a, b = sorted((names[i], names[j]), key=names.index)
                raise RegionError(f"regions {a!r} and {b!r} overlap near ({x:.6g}, {y:.6g})")


def _curve_piece(domain: Domain, name: str, line: FloatArray, c: int, h_min: float, eps: float
                 ) -> Piece:
    closed = len(line) > 3 and bool(np.all(line[0] == line[-1]))
    gap = float(np.hypot(*(line[-1] - line[0])))
    if not closed and len(line) > 3 and gap <= max(10 * eps, JUNCTION_MERGE * h_min):
        # Ends closer than junctions are told apart: the curve is closed (a digitised ring
        # whose last point misses its first).  Kept open, its two end nodes 0.02 h apart made a
        # triangle of no area (found by fuzzing).
        import warnings

        warnings.warn(f"curve {name!r} ends {gap:.3g} from where it starts ({line[0, 0]:.6g}, "
                      f"{line[0, 1]:.6g}), closer than elements resolve: it is closed there",
                      stacklevel=4)
        closed = True
    if closed:
        line = line[:-1]
    line = _through_corners(domain, line, closed, eps, max(10 * eps, JUNCTION_MERGE * h_min))
    _check_inside(domain, name, line, closed, h_min, eps)
    _check_simple(name, line, closed, eps)
    fixed = np.zeros(len(line), dtype=bool)
    if not closed:
        fixed[[0, -1]] = True
    # Vertices where the polyline turns are nodes (the user drew them); straight runs are not.
    prv = np.roll(line, 1, axis=0) - line
    nxt = np.roll(line, -1, axis=0) - line
    cross = prv[:, 0] * nxt[:, 1] - prv[:, 1] * nxt[:, 0]
    turn = 180.0 - np.degrees(np.abs(np.arctan2(cross, np.einsum("ij,ij->i", prv, nxt))))
    bend = turn > 0.1
    if not closed:
        bend[[0, -1]] = False
    fixed |= bend
    # A vertex on the outer boundary is a junction with it.
    fixed |= np.abs(domain.sdf(line)) <= eps
    return Piece(line, fixed, closed, _polyline_projection(line, closed), -1 - c)


def _polyline_projection(line: FloatArray, closed: bool) -> Projector:
    """The nearest point on a user curve's polyline: an exact boundary representation of it
    (an open one there and back)."""
    loop = line if closed else np.concatenate([line, line[-2:0:-1]])
    b = BRep(loop, np.roll(loop, -1, axis=0), np.zeros_like(loop), np.zeros(len(loop)),
             np.array([0, len(loop)]))
    return b.project


def _through_corners(domain: Domain, line: FloatArray, closed: bool, eps: float, merge: float
                     ) -> FloatArray:
    """The polyline made to pass through the domain's corners within ``merge`` of it (and not
    a vertex of it): its vertex nearest such a corner moves onto it when that close, else the
    corner is inserted as a vertex.  The curve moves by less than ``merge``.

    A fault drawn past a corner of the boundary closer than any element could resolve cuts off
    a sliver no triangle fits: past a reflex corner at h/30 it even left the domain over a
    stretch of h/10, unseen by the inside test's samples, and the boundary segments at the
    corner were lost (found by fuzzing).  Through the corner it meets the boundary there, a
    junction.  As for a region's corner near a curve (:func:`_near_misses`).
    """
    from scipy.spatial import cKDTree

    corners = domain.corners()
    lo, hi = line.min(axis=0) - merge, line.max(axis=0) + merge
    corners = corners[np.all((corners >= lo) & (corners <= hi), axis=1)]
    if not len(corners):
        return line
    a = line
    b = np.roll(line, -1, axis=0)
    if not closed:
        a, b = a[:-1], b[:-1]
    if not len(a):
        return line
    seg, tt, d = _nearest_segment(corners, a, b)
    # A corner the polyline passes within eps of, between its vertices, is a junction too (a
    # fault through a reflex corner 1e-5 off it had no node there, and its segment across
    # the corner was lost; found by fuzzing).
    near = (d <= merge) & (cKDTree(line).query(corners)[0] > eps)
    if not near.any():
        return line
    out = line.copy()
    extra: list[FloatArray] = []
    keys: list[float] = []
    for c, k, t in zip(corners[near], seg[near], tt[near], strict=True):
        # The segment's end nearer the corner: moved onto it when within ``merge`` (a vertex
        # next to the corner would leave a segment no element resolves), else the corner is
        # inserted where its foot is.
        v = k if t <= 0.5 else (k + 1) % len(line)
        if np.hypot(*(out[v] - c)) <= merge:
            out[v] = c
        else:
            extra.append(c)
            keys.append(k + float(np.clip(t, 1e-9, 1 - 1e-9)))
    return _with_vertices(out, keys, extra)


#: The inside test of a curve bisects its samples down to this fraction of h_min (below which
#: an excursion out of the domain is too small for it to find), with at most ``INSIDE_SAMPLES``
#: evaluations of d.
INSIDE_RESOLUTION = 1e-3
INSIDE_SAMPLES = 1_000_000


def _check_inside(domain: Domain, name: str, line: FloatArray, closed: bool, h_min: float, eps: float
                  ) -> None:
    """Vertices and points every quarter h_min along the segments must be inside or on, and
    so must every point in between where d could exceed ``eps``.

    d changes by at most the distance between two points, so between samples ``s`` apart
    with distances d_a and d_b it is at most ``(d_a + d_b + s) / 2``: such intervals are
    bisected until that bound is below ``eps`` or the interval is ``INSIDE_RESOLUTION * h_min``
    short.  A curve clipping a corner by a fraction of h (outside over a stretch shorter than
    the samples' spacing) is then found, and a curve ending on the boundary costs a few
    evaluations per level at its end.
    """
    a = line
    b = np.roll(line, -1, axis=0)
    if not closed:
        a, b = a[:-1], b[:-1]
    n = np.maximum(1, np.ceil(np.hypot(*(b - a).T) / (0.25 * h_min)).astype(int))
    n = np.minimum(n, 10_000)
    seg = np.repeat(np.arange(len(a)), n + 1)
    t = (np.arange(len(seg)) - np.repeat(np.cumsum(n + 1) - (n + 1), n + 1)) / np.repeat(n, n + 1)
    q = a[seg] + t[:, None] * (b - a)[seg]
    d = domain.sdf(q)
    # The intervals between consecutive samples of a segment.
    same = seg[1:] == seg[:-1]
    qa, qb, da, db = q[:-1][same], q[1:][same], d[:-1][same], d[1:][same]
    used = len(q)
    smallest = INSIDE_RESOLUTION * h_min
    while True:
        out = d > eps
        if out.any():
            x, y = q[np.argmax(out)]
            raise CurveError(f"curve {name!r} leaves the domain near ({x:.6g}, {y:.6g})")
        s = np.hypot(*(qb - qa).T)
        suspect = (0.5 * (da + db + s) > eps) & (s > smallest)
        if not suspect.any() or used + int(suspect.sum()) > INSIDE_SAMPLES:
            return
        qa, qb, da, db = qa[suspect], qb[suspect], da[suspect], db[suspect]
        q = 0.5 * (qa + qb)
        d = domain.sdf(q)
        used += len(q)
        qa, qb = np.concatenate([qa, q]), np.concatenate([q, qb])
        da, db = np.concatenate([da, d]), np.concatenate([d, db])


def _check_simple(name: str, line: FloatArray, closed: bool, eps: float) -> None:
    """No two non-adjacent segments of a curve meet (a closed curve's ends are adjacent)."""
    a = line
    b = np.roll(line, -1, axis=0)
    if not closed:
        a, b = a[:-1], b[:-1]
    m = len(a)
    if m < 2:
        return
    step = max(1, 2_000_000 // m)
    for s in range(0, m, step):
        i = np.arange(s, min(m, s + step))[:, None]
        j = np.arange(m)[None, :]
        pts = _segment_hits(a[i[:, 0]], b[i[:, 0]], a, b, eps)
        adjacent = (np.abs(i - j) <= 1) | (closed & (np.abs(i - j) == m - 1))
        hit = pts & ~adjacent & (j > i)
        # Adjacent segments that fold back on each other overlap too.
        if hit.any():
            r, cc = np.argwhere(hit)[0]
            x, y = _intersection(a[i[r, 0]], b[i[r, 0]], a[cc], b[cc])
            raise CurveError(f"curve {name!r} crosses itself near ({x:.6g}, {y:.6g})")
    u = b - a
    w = np.roll(u, -1, axis=0) if closed else u[1:]
    uu = u if closed else u[:-1]
    cross = uu[:, 0] * w[:, 1] - uu[:, 1] * w[:, 0]
    # The angle between the two sides at each vertex (0: the curve goes back along itself).
    gap = np.degrees(np.abs(np.arctan2(cross, -np.einsum("ij,ij->i", uu, w))))
    back = gap < FOLD_ANGLE
    if back.any():
        k = int(np.argmax(back))
        x, y = b[k]
        raise CurveError(f"curve {name!r} crosses itself (turns back on itself) at ({x:.6g}, {y:.6g}): "
                         f"its two sides there are {gap[k]:.2g} degrees apart, too close for any element "
                         f"between them (at least {FOLD_ANGLE:.2g})")


def _segment_hits(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray, eps: float
                  ) -> BoolArray:
    """Whether segment a[i]-b[i] meets segment c[j]-d[j], for all i, j (touching counts)."""

    def orient(p: FloatArray, q: FloatArray, r: FloatArray) -> FloatArray:
        u, v = q - p, r - p
        return np.asarray(u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0])

    A, B = a[:, None, :], b[:, None, :]
    C, D = c[None, :, :], d[None, :, :]
    scale = eps * (np.hypot(*(B - A).transpose(2, 0, 1)) + np.hypot(*(D - C).transpose(2, 0, 1)))
    o1, o2 = orient(A, B, C), orient(A, B, D)
    o3, o4 = orient(C, D, A), orient(C, D, B)
    proper = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    # Collinear segments meet when their boxes overlap.
    lo1, hi1 = np.minimum(A, B), np.maximum(A, B)
    lo2, hi2 = np.minimum(C, D), np.maximum(C, D)
    boxes = np.all((lo1 <= hi2 + eps) & (lo2 <= hi1 + eps), axis=-1)
    collinear = (np.abs(o1) <= scale) & (np.abs(o2) <= scale)
    hit = boxes & (proper | collinear)
    # An end within eps of the other segment touches it, whatever the signs rounding gives: a
    # region's side ending on a circle at a vertex of its polyline 1.4e-17 off (x = 0 against
    # 1.39e-17, found by fuzzing) was no crossing, and the junction no vertex of the circle.
    i, j = np.nonzero(boxes & ~hit)
    if len(i):
        ends = ((a[i], c[j], d[j]), (b[i], c[j], d[j]), (c[j], a[i], b[i]), (d[j], a[i], b[i]))
        touch = np.zeros(len(i), dtype=bool)
        for q, u, v in ends:
            uv = v - u
            t = np.clip(np.einsum("ij,ij->i", q - u, uv)
                        / np.maximum(np.einsum("ij,ij->i", uv, uv), 1e-300), 0.0, 1.0)
            touch |= np.hypot(*(q - u - t[:, None] * uv).T) <= eps
        hit[i[touch], j[touch]] = True
    return np.asarray(hit)


def _intersection(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray) -> FloatArray:
    """The crossing of lines a-b and c-d (a's midpoint if parallel)."""
    r, s = b - a, d - c
    den = r[0] * s[1] - r[1] * s[0]
    if den == 0:
        return 0.5 * (a + b)
    t = ((c[0] - a[0]) * s[1] - (c[1] - a[1]) * s[0]) / den
    return a + t * r


def _meeting_points(a: FloatArray, b: FloatArray, c: FloatArray, d: FloatArray, eps: float
                    ) -> list[FloatArray]:
    """Where segments a-b and c-d (which meet: :func:`_segment_hits`) meet: their crossing, or,
    parallel or touching end to side, the ends of each within ``eps`` of the other (the ends
    of their overlap).

    A box region's side ending on another box's side, collinear with it, was given the other
    side's midpoint as their crossing (the lines' crossing has no answer there), 0.25 off the
    first side: inserted into it, the side doubled back (a duplicate node, 16 lost segments;
    found by fuzzing).
    """
    x = _intersection(a, b, c, d)
    r, s = b - a, d - c
    starts, ends = np.stack([a, c]), np.stack([b, d])
    if r[0] * s[1] - r[1] * s[0] != 0 and np.all(_segment_feet(x[None, :], starts, ends)[1] <= eps):
        return [x]
    # Each segment's ends against the other segment.
    tips = np.stack([a, b, c, d])
    across = _segment_feet(tips, starts, ends)[1][np.arange(4), [1, 1, 0, 0]]
    out: list[FloatArray] = []
    for q, dq in zip(tips, across, strict=True):
        if dq <= eps and all(np.hypot(*(q - o)) > eps for o in out):
            out.append(q)
    return out or [x]


# --- junctions between pieces -----------------------------------------------------------------


def _join(pieces: list[Piece], eps: float, merge: float) -> list[Piece]:
    """Insert as fixed vertices the points where pieces cross or where one ends on another
    (crossings closer than ``merge`` are one, and a crossing within ``merge`` of a piece's
    fixed vertex is that vertex), and into a user curve the other pieces' fixed vertices
    within ``merge`` of it (:func:`_near_misses`)."""
    extra: list[list[FloatArray]] = _near_misses(pieces, eps, merge)
    fixed_pts = np.concatenate([p.points[p.fixed] for p in pieces] + [np.empty((0, 2))])
    # Each crossing once, with its pair of pieces and of segments.
    crossings: list[FloatArray] = []
    tags: list[tuple[int, int, int, int]] = []
    for i, pi in enumerate(pieces):
        ai, bi = _segments(pi)
        for j in range(i + 1, len(pieces)):
            pj = pieces[j]
            aj, bj = _segments(pj)
            lo_i, hi_i = pi.points.min(axis=0), pi.points.max(axis=0)
            lo_j, hj = pj.points.min(axis=0), pj.points.max(axis=0)
            if np.any(lo_i > hj + eps) or np.any(lo_j > hi_i + eps):
                continue
            step = max(1, 2_000_000 // max(len(aj), 1))
            for s in range(0, len(ai), step):
                hit = _segment_hits(ai[s:s + step], bi[s:s + step], aj, bj, eps)
                for r, c in np.argwhere(hit).tolist():
                    for x in _meeting_points(ai[s + r], bi[s + r], aj[c], bj[c], eps):
                        at = fixed_pts[np.hypot(*(fixed_pts - x).T) <= 10 * eps]
                        if len(at):
                            # A piece ending there (a tangent region's junction put on the wall
                            # it left, off its own curve): the crossing is that vertex, not
                            # where alternating projections between the two curves drift to.
                            x = at[0]
                        else:
                            for _ in range(CROSSING_ITERATIONS):
                                x = pj.project(pi.project(x[None, :]))[0]
                        extra[i].append(x)
                        extra[j].append(x)
                        crossings.append(x)
                        # The segments of a user curve (a region's polyline only samples its
                        # curve: two of its chords crossing the same curve near a contact are
                        # one place).
                        tags.append((i, j, s + r if pi.owner < 0 else -1, c if pj.owner < 0 else -1))
    # One list of junctions for every piece, so that pieces meeting there share the point; the
    # pieces' fixed vertices first, so that a crossing next to one becomes it.
    # (The near misses are fixed vertices, and the crossings are listed once: every point of
    # ``extra`` is among these.)
    allx = _merged_junctions(fixed_pts, crossings, tags, merge, 10 * eps, pieces) if any(extra) else None
    out = []
    for p, more in zip(pieces, extra, strict=True):
        if not more or allx is None:
            out.append(p)
            continue
        mine = np.array(more)
        near = np.min(np.hypot(*(allx[:, None, :] - mine[None, :, :]).transpose(2, 0, 1)), axis=1) <= merge
        # A user curve's own fixed vertex that close to a junction is the junction (region
        # boundaries are not bent: their vertices stay on their curves).
        joined = _insert(p, allx[near], eps, merge if p.owner < 0 else 0.0)
        drawn = p.points if p.closed else np.concatenate([p.points, p.points[-2:0:-1]])
        if p.owner < 0 and np.any(_polyline_distance(joined.points, drawn) > 10 * eps):
            # Bent through a junction off it (a near miss, a snapped vertex), the curve's nodes
            # slide on the bent polyline: on the one drawn, those beside a region's corner the
            # curve was bent through (h / 24 off it) crossed the region's side (a lost segment,
            # found by fuzzing).
            joined = replace(joined, project=_polyline_projection(joined.points, joined.closed))
        out.append(joined)
    return out


def _merged_junctions(fixed: FloatArray, crossings: list[FloatArray], tags: list[tuple[int, int, int, int]],
                      merge: float, same: float, pieces: list[Piece]) -> FloatArray:
    """The junction points: the fixed vertices, then the crossings, each dropped when closer
    than ``merge`` to an earlier one; except that two crossings of the same
    two pieces on different segments of a user curve (``tags``: the pieces, and the curves'
    segments, -1 for a region's) more than ``same`` apart are both kept, and so are a crossing
    and a fixed vertex more than ``same`` apart that lies on the crossing's user curve but off
    the crossing's segment.

    A polyline bending back across a region's side crosses it twice, 0.0012 apart for h =
    0.09 (found by fuzzing): merged into one, the point went into one of the polyline's two
    segments only, and the other still crossed the side with no node there (a lost segment).
    The same where the polyline's other leg passes through a corner of the region, 0.0019 from
    the crossing (h = 0.075, found by fuzzing): the crossing became the corner, which only the
    other leg has.
    """
    from scipy.spatial import cKDTree

    pts = np.concatenate([fixed, np.asarray(crossings).reshape(-1, 2)])
    if len(pts) < 2:
        return pts
    first = len(fixed)
    keep = np.ones(len(pts), dtype=bool)
    for a, b in sorted(map(tuple, cKDTree(pts).query_pairs(merge, output_type="ndarray").tolist())):
        ca, cb = a - first, b - first
        apart = bool(np.hypot(*(pts[a] - pts[b])) > same)
        if 0 <= ca < len(tags) and 0 <= cb < len(tags):
            (i, j, si, sj), (i2, j2, si2, sj2) = tags[ca], tags[cb]
            if (i, j) == (i2, j2) and (si, sj) != (si2, sj2) and apart:
                continue
        elif apart and ca < 0 <= cb < len(tags) and _on_another_leg(pts[a], tags[cb], pieces, same):
            continue
        keep[max(a, b)] = False
    out: FloatArray = pts[keep]
    return out


def _on_another_leg(v: FloatArray, tag: tuple[int, int, int, int], pieces: list[Piece], same: float) -> bool:
    """Whether the point ``v`` lies on a crossing's user curve (within ``same``) but not on the
    crossing's own segment of it (``tag``: the pieces and the user curves' segments, as in
    :func:`_merged_junctions`): there the curve passes ``v`` on another leg."""
    for piece, s in ((pieces[tag[0]], tag[2]), (pieces[tag[1]], tag[3])):
        if s < 0:
            continue
        a, b = _segments(piece)
        _, _, d = _nearest_segment(v[None, :], a, b)
        _, _, d_own = _nearest_segment(v[None, :], a[s:s + 1], b[s:s + 1])
        if d[0] <= same < d_own[0]:
            return True
    return False


def _near_misses(pieces: list[Piece], eps: float, merge: float) -> list[list[FloatArray]]:
    """For each piece, the fixed vertices of the other pieces (corners, end points, junctions)
    within ``merge`` of it but not on it: for a user curve, any; for a region's boundary,
    those on the region's true curve.

    A curve drawn past a region's corner, or ending next to another curve, closer than
    ``merge`` (JUNCTION_MERGE * h_min) without touching it: no element can resolve the gap,
    and the two fixed nodes that close lost the curve's segment between them (found by
    fuzzing: a polyline passing 7e-5 and 9e-4 from a region's corner, h = 0.08-0.09).  The curve
    is made to pass through the vertex instead, which moves it by less than ``merge``.  Region
    boundaries are not bent: their nodes slide on the region's own boundary, and a vertex is
    inserted into one only where it lies on that boundary (where a region tangent to it
    leaves it: :func:`_region_pieces`).
    """
    out: list[list[FloatArray]] = [[] for _ in pieces]
    for i, pi in enumerate(pieces):
        others = [pj.points[pj.fixed] for j, pj in enumerate(pieces) if j != i]
        f = np.concatenate(others) if others else np.empty((0, 2))
        lo, hi = pi.points.min(axis=0) - merge, pi.points.max(axis=0) + merge
        f = f[np.all((f >= lo) & (f <= hi), axis=1)]
        if not len(f):
            continue
        a, b = _segments(pi)
        k, t, d = _nearest_segment(f, a, b)
        foot = a[k] + t[:, None] * (b - a)[k]
        # Within eps of a segment but off it, a vertex is no crossing (the crossing test
        # finds segments that meet, or overlap when collinear), so it is taken here too; one
        # at a vertex of the piece is that vertex.
        from scipy.spatial import cKDTree

        take = (d <= merge) & (cKDTree(pi.points).query(f)[0] > 10 * eps)
        if pi.owner >= 0:
            # A region's boundary takes only the vertices on its own stretch of its true curve
            # (a junction put on a circle where a tangent region leaves it lies off the
            # circle's chords by up to their sagitta): where the nearest point of the piece's
            # polyline projects onto the curve.  Another region's corner next to a side is no
            # junction on it, nor a vertex on another stretch of the curve.
            take &= np.hypot(*(pi.project(foot) - f).T) <= 10 * eps
        out[i] += list(f[take])
    return out


def _warn_narrow_angles(pieces: list[Piece], region_names: list[str], curve_names: list[str]) -> None:
    """Warn where curves meet at less than ``NARROW_ANGLE`` degrees (touching regions, a crack
    grazing an interface), or one curve bends back by more than 180 - NARROW_ANGLE degrees:
    the triangles in that angle cannot be well shaped."""
    import warnings

    dirs: dict[tuple[float, float], list[tuple[float, str]]] = {}
    for p in pieces:
        name = region_names[p.owner - 1] if p.owner > 0 else curve_names[-1 - p.owner]
        n = len(p.points)
        for v in np.flatnonzero(p.fixed):
            key = (float(p.points[v, 0]), float(p.points[v, 1]))
            for w in (v - 1, v + 1):
                if not p.closed and not 0 <= w < n:
                    continue
                d = p.points[w % n] - p.points[v]
                dirs.setdefault(key, []).append((float(np.arctan2(d[1], d[0])), name))
    for (x, y), rays in dirs.items():
        # Two rays: a sharp bend of one curve or a sharp corner of one region (a crack drawn
        # with a kink of 3 degrees gave q = 0.016 without a word; found by fuzzing).
        if len(rays) < 2:
            continue
        ang = np.sort([a for a, _ in rays])
        gaps = np.degrees(np.diff(np.concatenate([ang, ang[:1] + 2 * np.pi])))
        if gaps.min() < NARROW_ANGLE:
            names = sorted({nm for _, nm in rays})
            what = (f"{' and '.join(repr(nm) for nm in names)} meet" if len(names) > 1
                    else f"{names[0]!r} bends back on itself")
            warnings.warn(
                f"{what} at ({x:.6g}, {y:.6g}) at "
                f"{gaps.min():.2g} degrees: the triangles in that angle cannot be well shaped "
                f"(q at most about {_angle_bound(float(gaps.min())):.2g})",
                stacklevel=4,
            )


def _angle_bound(degrees: float) -> float:
    """The best q of a triangle with an angle of ``degrees`` (isosceles on that angle)."""
    a = np.radians(degrees)
    # Isosceles with apex angle a: sides 1, 1 and 2 sin(a/2); q = 2 r_in / r_out.
    b = 2 * np.sin(a / 2)
    s = 0.5 * (2 + b)
    area = 0.5 * np.sin(a)
    r_in = area / s
    r_out = b / (2 * np.sin(a)) if a > 0 else np.inf
    return float(2 * r_in / r_out)


def _segments(p: Piece) -> tuple[FloatArray, FloatArray]:
    if p.closed:
        return p.points, np.roll(p.points, -1, axis=0)
    return p.points[:-1], p.points[1:]


def _insert(p: Piece, q: FloatArray, eps: float, snap: float = 0.0) -> Piece:
    """The piece with the points ``q`` (on it) inserted as fixed vertices.

    With ``snap``, a fixed vertex of the piece within ``snap`` of one of the points is moved
    onto it instead: a user curve's turning point 0.02 h past a region's corner it was made to
    pass through left two fixed nodes that close, and the curve's segment between them was
    lost (found by fuzzing).
    """
    pts, fixed = p.points.copy(), p.fixed.copy()
    if snap > 0.0 and fixed.any() and len(q):
        from scipy.spatial import cKDTree

        ids = np.flatnonzero(fixed)
        dist, near = cKDTree(pts[ids]).query(q)
        snapped = np.zeros(len(pts), dtype=bool)
        for j in np.argsort(dist, kind="stable").tolist():  # each vertex to its nearest point
            v = ids[near[j]]
            if dist[j] <= snap and not snapped[v]:
                # A vertex a point is at already stays there: another point near it is a
                # junction of its own (a curve's other leg crossing a region's side 0.0019 from
                # the region's corner the curve turns at; found by fuzzing).
                if dist[j] > 10 * eps:
                    pts[v] = q[j]
                snapped[v] = True
    a, b = _segments(Piece(pts, fixed, p.closed, p.project, p.owner))
    t, dist = _segment_feet(q, a, b)
    seg = np.argmin(dist, axis=1)
    tt = t[np.arange(len(q)), seg]
    # A point at a vertex fixes the vertex; others are inserted in order along the piece.
    near_a = np.hypot(*(q - a[seg]).T) <= 10 * eps
    near_b = np.hypot(*(q - b[seg]).T) <= 10 * eps
    vb = (seg + 1) % len(pts)
    fixed[seg[near_a]] = True
    fixed[vb[near_b & ~near_a]] = True
    new = ~near_a & ~near_b
    if new.any():
        key = np.concatenate([np.arange(len(pts), dtype=float), seg[new] + np.clip(tt[new], 1e-9, 1 - 1e-9)])
        order = np.argsort(key, kind="stable")
        pts = np.concatenate([pts, q[new]])[order]
        fixed = np.concatenate([fixed, np.ones(int(new.sum()), dtype=bool)])[order]
    return Piece(pts, fixed, p.closed, p.project, p.owner)


def _nearest_segment(q: FloatArray, a: FloatArray, b: FloatArray
                     ) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """For each point of ``q``: its nearest segment a-b, the foot's parameter on it and the
    distance, in chunks of about 2e6 point-segment pairs (a digitised fault across a
    coastline's corners would not fit at once)."""
    step = max(1, 2_000_000 // max(len(a), 1))
    seg, tt, dd = [], [], []
    for s in range(0, len(q), step):
        t, dist = _segment_feet(q[s:s + step], a, b)
        k = np.argmin(dist, axis=1)
        rows = np.arange(len(k))
        seg.append(k)
        tt.append(t[rows, k])
        dd.append(dist[rows, k])
    if not seg:
        return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    return np.concatenate(seg), np.concatenate(tt), np.concatenate(dd)


def _with_vertices(loop: FloatArray, keys: list[float], points: list[FloatArray]) -> FloatArray:
    """``loop`` with ``points`` inserted, each after vertex ``floor(key)`` in order of key."""
    if not points:
        return loop
    order = np.argsort(np.concatenate([np.arange(len(loop), dtype=float), keys]), kind="stable")
    out: FloatArray = np.concatenate([loop, np.array(points)])[order]
    return out


def _segment_feet(q: FloatArray, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
    """For each point of ``q`` and each segment a-b: the foot's parameter along the segment
    (clamped to [0, 1]) and the distance to it, both ``(len(q), len(a))``."""
    ab = b - a
    ab2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    t = np.clip(np.einsum("qmk,mk->qm", q[:, None, :] - a[None], ab) / ab2, 0, 1)
    dist = np.hypot(*(q[:, None, :] - a[None] - t[..., None] * ab[None]).transpose(2, 0, 1))
    return t, dist


def _polyline_distance(q: FloatArray, loop: FloatArray) -> FloatArray:
    """Distance from each point of ``q`` to the closed polyline ``loop``."""
    out: FloatArray = _segment_feet(q, loop, np.roll(loop, -1, axis=0))[1].min(axis=1)
    return out


def _unique_points(q: FloatArray, eps: float) -> FloatArray:
    """``q`` with points closer than ``eps`` to an earlier one dropped."""
    if len(q) < 2:
        return q
    from scipy.spatial import cKDTree

    pairs = cKDTree(q).query_pairs(eps, output_type="ndarray")
    keep = np.ones(len(q), dtype=bool)
    if len(pairs):
        keep[np.maximum(pairs[:, 0], pairs[:, 1])] = False
    return q[keep]





def split_geojson(obj: object) -> tuple[object | None, dict[str, Domain], dict[str, FloatArray]]:
    """Separate a GeoJSON FeatureCollection into the domain, its regions and its curves.

    A feature whose ``properties`` has a ``"region"`` entry is a region named by it; a
    LineString feature is a curve (named by its ``"name"`` or ``"curve"`` property, else
    ``"curve k"``; a MultiLineString gives one curve per line); the other features make the
    domain.  Anything that is not a FeatureCollection is returned unchanged with no regions.

    Returns
    -------
    domain : GeoJSON mapping or None
        A FeatureCollection of the domain's features, or None when there are none.
    regions : dict name -> Domain
    curves : dict name -> (k, 2) array

    Examples
    --------
    >>> fc = {"type": "FeatureCollection", "features": [
    ...     {"type": "Feature", "properties": {},
    ...      "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0]]]}},
    ...     {"type": "Feature", "properties": {"name": "crack"},
    ...      "geometry": {"type": "LineString", "coordinates": [[0.5, 0.1], [0.8, 0.4]]}}]}
    >>> rest, regions, curves = split_geojson(fc)
    >>> len(rest["features"]), list(regions), list(curves)
    (1, [], ['crack'])
    """
    if not (isinstance(obj, Mapping) and obj.get("type") == "FeatureCollection"):
        return obj, {}, {}
    features = obj.get("features")
    if not isinstance(features, list):
        raise GeometryError("a FeatureCollection needs a list of features")
    rest: list[object] = []
    regions: dict[str, Domain] = {}
    curves: dict[str, FloatArray] = {}
    for k, f in enumerate(features, start=1):
        if not isinstance(f, Mapping):
            raise GeometryError(f"feature {k} is not a GeoJSON object")
        props = f.get("properties") or {}
        geom = f.get("geometry") or {}
        kind = geom.get("type") if isinstance(geom, Mapping) else None
        if kind in ("LineString", "MultiLineString"):
            base = str(props.get("name") or props.get("curve") or f"curve {len(curves) + 1}")
            lines = [geom.get("coordinates")] if kind == "LineString" else list(geom.get("coordinates") or [])
            for j, line in enumerate(lines, start=1):
                name = base if len(lines) == 1 else f"{base} {j}"
                curves[_fresh(name, curves)] = np.asarray(line, dtype=float)
        elif isinstance(props, Mapping) and props.get("region") is not None:
            name = _fresh(str(props["region"]), regions)
            try:
                regions[name] = as_domain(dict(geom))
            except (TypeError, ValueError) as exc:
                raise RegionError(f"region {name!r}: {exc}") from None
        else:
            rest.append(f)
    domain = {"type": "FeatureCollection", "features": rest} if rest else None
    return domain, regions, curves


def _fresh(name: str, taken: Mapping[str, object]) -> str:
    """``name``, or ``name 2``, ``name 3``, ... if taken."""
    if name not in taken:
        return name
    k = 2
    while f"{name} {k}" in taken:
        k += 1
    return f"{name} {k}"

__all__ = ["Constraints", "CurveError", "Piece", "RegionError", "build_constraints", "split_geojson"]
