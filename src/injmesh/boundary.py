"""Step 1 of Algorithm 1: meshing of the boundary (paper Section 3.1, Algorithms 2 and 3).

Every boundary curve (outer boundary and each hole) is partitioned into segments that follow h:

1. **Injection-projection** (Eq. 3.1, 3.2, Algorithm 2).  Starting from the domain's boundary
   loops with the corners inserted, every segment longer than ``BOUNDARY_REFINE * h`` receives a
   point at the h-weighted mean of its end points (3.1), projected onto the boundary (3.2); this
   repeats until no segment is that long.  *Stopping condition*: the curve is then resolved to a
   quarter of the local h, which is what the next choice needs.
2. **Node count.**  Between consecutive fixed points (sharp corners, curve end points and user
   fixed points; a closed smooth curve gets one anchor) the curve's h-length ``S = int ds / h``
   is measured on the refined polyline and ``n = max(1, round(S))`` segments are laid out at equal
   h-length, then projected.  This is the choice the paper leaves open: Algorithm 2's bisection
   alone yields powers of two per initial segment, up to 40 % off the count h implies.
3. **1-D balancing** (Eq. 3.3, Algorithm 3).  Each free node moves to the h-weighted mean of the
   midpoints of its two segments, in the arc-length coordinate of the refined curve (truly
   one-dimensional: nodes keep their order however coarse the loop), and is finally projected
   (3.2).  *Stopping condition*: no node moves more than ``BALANCE_TOL * h``, or
   ``BALANCE_ITERATIONS`` sweeps.

Loops come out with the domain on their left (outer boundary counter-clockwise, holes
clockwise), in a stable order that is the boundary tag: outer boundaries by decreasing area, each
followed by its own holes by decreasing area (ties broken by position), whatever order the
geometry lists them in.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import _tolerances as tol
from .errors import NodeBudgetError
from .geometry import BRep, Domain, GeometryError
from .geometry.base import dedupe_points, ring_next, ring_prev
from .geometry.regions import Piece
from .geometry.tracing import grid_spacing
from .progress import Callback, report
from .sizing import SizeFunction

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
SizeFn = Callable[[FloatArray], FloatArray]


@dataclass(frozen=True)
class BoundaryMesh:
    """Nodes on the boundary, loop by loop.

    Attributes
    ----------
    points : (nb, 2) array
        Boundary nodes; each loop's nodes are contiguous and in order.
    edges : (nb, 2) int array
        Segment ``k`` joins node ``edges[k, 0]`` to ``edges[k, 1]`` with the domain on its left.
    node_loop : (nb,) int array
        Loop (boundary tag) of each node.
    fixed : (nb,) bool array
        Nodes that were held fixed (corners, anchors, user points).
    """

    points: FloatArray
    edges: IntArray
    node_loop: IntArray
    fixed: NDArray[np.bool_]


def estimate_nodes(
    domain: Domain, h: SizeFn, cells: int = 64, max_samples: int = 2_000_000
) -> tuple[float, float]:
    """Smallest h inside the domain and the node count h implies (equilateral packing).

    The count is ``(2 / sqrt(3)) * integral of 1/h^2`` over the domain, by adaptive quadrature
    on a quadtree: a ``cells x cells`` grid over the bounding box, each cell sampled once in
    each of its four quarters (h only where ``d <= 0``), and split while it is larger than
    the smallest h it sampled and h varies across it by more than 20 %.  A point refinement
    (``h = 1e-4 + 0.5 r``) is then followed down to its tip wherever the point lies, instead
    of being missed or overcounted by a fixed grid.  At most about ``max_samples`` evaluations;
    an estimate used for the node budget and the tracing resolution, not a bound (a feature of
    h narrower than every sample spacing can still be missed).
    """
    from dataclasses import replace

    from .sizing import SizeFunction

    if isinstance(h, SizeFunction) and h.domain is domain:
        # h is asked only where d <= 0 here: the restriction's own sdf call would repeat ours.
        h = replace(h, domain=None)
    x0, y0, x1, y1 = domain.bbox
    side = max(x1 - x0, y1 - y0) / cells
    # Inside/outside of the samples, evaluated only near the boundary where that is cheaper.
    from .sizing.background import inside_test

    fast_inside = inside_test(domain, side / 2)
    i, j = np.meshgrid(np.arange(cells), np.arange(cells))
    centres = np.stack([x0 + (i.ravel() + 0.5) * side, y0 + (j.ravel() + 0.5) * side], axis=1)
    # The quarters' centres; each sample is jittered within its quarter (see below).
    quarter = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
    r2 = np.array([0.7548776662466927, 0.5698402909980532])
    per_node = np.sqrt(3) / 2
    total, h_min, used, any_inside = 0.0, np.inf, 0, False
    from .kernels.raster import quarter_samples

    for _ in range(60):
        k = len(centres)
        # Each quarter sampled at a point jittered within it by a low-discrepancy sequence
        # (R2) over the cells: a feature of h aligned with the grid (a band along x = 0.5) is
        # not missed by every cell at once, and the result stays deterministic.  Compiled
        # (0.3 ms of NumPy temporaries for the first 16,384 samples).
        q = quarter_samples(np.ascontiguousarray(centres, dtype=np.float64), float(side), quarter, r2)
        inside = fast_inside(q) if fast_inside is not None else domain.sdf(q) <= 0
        flat = np.full(len(q), np.inf)
        if inside.any():
            any_inside = True
            flat[inside] = h(q[inside])
            h_min = min(h_min, float(flat[inside].min()))
        used += len(q)
        hv = flat.reshape(4, k)
        est = np.sum(np.where(np.isfinite(hv), 1.0 / hv**2, 0.0), axis=0) * (side / 2) ** 2 / per_node
        finite = np.isfinite(hv)
        lo = np.min(hv, axis=0)
        hi = np.max(np.where(finite, hv, 0.0), axis=0)
        refine = finite.any(axis=0) & (side > lo) & (hi > 1.2 * lo)
        if used + 4 * len(q) * refine.mean() > max_samples:
            refine[:] = False
        total += float(est[~refine].sum())
        if not refine.any():
            break
        centres = np.asarray((centres[refine][None, :, :] + side * quarter[:, None, :]).reshape(-1, 2))
        side /= 2
    if not any_inside:
        raise GeometryError(f"the domain is empty inside its bounding box {domain.bbox}")
    return h_min, total


def mesh_boundary(
    domain: Domain,
    h: SizeFn,
    fixed_points: FloatArray,
    *,
    max_nodes: int,
    callback: Callback | None = None,
    estimate: tuple[float, float] | None = None,
) -> BoundaryMesh:
    """Partition every boundary curve into segments that follow h (Step 1).

    Parameters
    ----------
    domain : Domain
    h : callable
        Validated size function.
    fixed_points : (k, 2) array
        User points; those on the boundary are kept as nodes and never move.
    max_nodes : int
        Node budget for the whole mesh, checked here before any work that scales with it.
    callback : callable, optional
        Called with a progress event per loop.
    estimate : (h_min, count), optional
        ``estimate_nodes(domain, h)`` when the caller already has it (the same numbers).

    Returns
    -------
    BoundaryMesh
    """
    h_min, expected = estimate_nodes(domain, h) if estimate is None else estimate
    if expected > max_nodes:
        raise NodeBudgetError(
            f"the size function implies about {expected:.3g} nodes, more than max_nodes={max_nodes}"
        )
    diam = domain.diameter
    on = tol.ON_BOUNDARY * diam
    loops = domain.boundary_loops(grid_spacing(domain.bbox, h_min))
    if not loops:
        raise GeometryError("the domain has no boundary inside its bounding box")
    loops = _drop_tiny(order_loops(loops), h)

    corners = np.concatenate([domain.corners(), _resolved_vertices(domain, h), _tip_walls(domain, h)])
    if len(fixed_points):
        dfix = domain.sdf(fixed_points)
        if np.any(dfix > on):
            i = int(np.argmax(dfix > on))
            raise ValueError(f"fixed point {tuple(fixed_points[i].tolist())} lies outside the domain")
        corners = np.concatenate([corners, fixed_points[np.abs(dfix) <= on]])
    # One node per point: a user's point on a vertex the outline resolves anyway (a DistMesh
    # pfix of the polygon's vertices), or a resolved vertex at a corner, was inserted twice
    # (two nodes at one place, their segments lost).  The first, the domain's own, stays.
    corners = dedupe_points(corners, on)

    along = _tip_graded(domain, h)
    pts, fixed, loop_id = [], [], []
    feet = [_corner_feet(loop, corners, on) for loop in loops]
    nearest = _nearest_loop_distance(feet, len(corners))
    for k, loop in enumerate(loops):
        p, f = _insert_corners(loop, corners, feet[k], nearest, on, diam)
        p, f = _tip_marks(domain, p, f, along, on)
        p, f, hp = _refine(domain, along, p, f)
        p, f = _select(domain, p, f, hp)
        pts.append(p)
        fixed.append(f)
        loop_id.append(np.full(len(p), k))
        report(callback, "boundary", k + 1, len(loops), nodes=len(p))
    points = np.concatenate(pts)
    fixed_mask = np.concatenate(fixed)
    node_loop = np.concatenate(loop_id)
    points, fixed_mask, node_loop = _split_encroached(domain, points, fixed_mask, node_loop)
    # A boundary node carries half the area of an interior one.
    if expected + 0.5 * len(points) > max_nodes:
        raise NodeBudgetError(
            f"the size function implies about {expected + 0.5 * len(points):.3g} nodes "
            f"({len(points)} on the boundary), more than max_nodes={max_nodes}"
        )
    nxt = _next(node_loop)
    fixed_mask = _pin_wedges(h, points, fixed_mask, nxt)
    edges = np.stack([np.arange(len(points)), nxt], axis=1)
    return BoundaryMesh(points, edges, node_loop, fixed_mask)


def _pin_wedges(h: SizeFn, p: FloatArray, fixed: NDArray[np.bool_], nxt: IntArray) -> NDArray[np.bool_]:
    """Hold still the boundary nodes of a sharp corner's two walls where the walls are closer
    than ``PIN_WIDTH * h``.

    Step 1 lays the nodes of both walls at the same h-lengths from the corner, so the triangle
    at the tip is isosceles (the best an angle allows) and the strip of triangles between the
    walls is made of isosceles trapezoids.  Sliding would let the interior push them out of
    step (a 20-degree tip measured q = 0.41 where 0.57 is possible).
    """
    prev = np.empty_like(nxt)
    prev[nxt] = np.arange(len(nxt))
    u, w = p[prev] - p, p[nxt] - p
    # Interior angle at each node: from the next wall counter-clockwise to the previous one
    # (the domain is on the left of the loop).
    angle = np.arctan2(w[:, 0] * u[:, 1] - w[:, 1] * u[:, 0], np.einsum("ij,ij->i", w, u)) % (2 * np.pi)
    sharp = np.flatnonzero(fixed & (angle < np.radians(SHARP_CORNER)))
    out = fixed.copy()
    if len(sharp) == 0:
        return out
    for c in sharp.tolist():
        sin_a = np.sin(angle[c])
        for step in (nxt, prev):
            k = int(step[c])
            for _ in range(len(p)):
                if out[k] and k != c:
                    break
                r = float(np.hypot(*(p[k] - p[c])))
                if r * sin_a >= PIN_WIDTH * float(h(p[k : k + 1])[0]):
                    break
                out[k] = True
                k = int(step[k])
    return out


class _TipGraded:
    """h along the walls of sharp corners: ``r1_c`` for ``r <= r1_c`` and
    ``min(h, kappa_c r)`` beyond, within ``reach_c`` of each sharp corner c (r the distance to
    c), h elsewhere."""

    def __init__(self, h: SizeFn, tips: FloatArray, kappa: FloatArray, r1: FloatArray, reach: FloatArray):
        from scipy.spatial import cKDTree

        self.h, self.tips, self.kappa, self.r1, self.reach = h, tips, kappa, r1, reach
        self.tree = cKDTree(tips)

    def __call__(self, p: FloatArray) -> FloatArray:
        hp = self.h(p)
        dist, k = self.tree.query(p, distance_upper_bound=float(self.reach.max()))
        near = np.flatnonzero(np.isfinite(dist))
        if len(near):
            c, r = k[near], dist[near]
            tip = r <= self.r1[c] * (1.0 + 1e-9)  # the wall's mark at r1 (_tip_marks) included
            # Up to r1 the size is r1 itself, not min(h, r1): the walls' first node must land
            # at r1, where the grading starts, or the first step beyond it mixes the two sizes
            # (where h falls away from the tip, the node came before r1 and the next step was
            # about 2 kappa r1: a 2:1 trapezoid of q ~0.63 next to a 5-degree tip).
            graded = np.where(tip, self.r1[c], np.minimum(hp[near], self.kappa[c] * r))
            inside = r < self.reach[c]
            hp[near] = np.where(inside, graded, hp[near])
        return hp


def _tip_graded(domain: Domain, h: SizeFn) -> SizeFn:
    """The size Step 1 follows: h, graded geometrically towards the tips of sharp corners.

    Along the two walls of a corner of angle a the nodes then lie at distances growing by the
    factor ``1 + 2 sin(a / 2)`` from the tip (the walls' separation at each node), on both
    walls alike, so the strip between them is made of nearly square trapezoids (two triangles
    of q ~ 0.8 each) down to the tip triangle, which is isosceles: the best the angle allows.
    Without it the nodes near the tip lie at the floor of the feature size, and the strip
    narrower than that floor is made of slivers as bad as the tip itself.  The first node lies
    at ``r1 = h(tip)`` (the tip triangle, isosceles, has the angle's best q at any size), then
    every segment is kappa times its distance from the tip, until that reaches h.
    """
    brep = _exact_brep(domain)
    if brep is None:
        return h
    pts, turn, before, after = brep.junctions()
    angle = 180.0 - turn  # interior angle: the domain is on the left
    sharp = angle < SHARP_CORNER
    if not sharp.any():
        return h
    tips, a = pts[sharp], np.radians(angle[sharp])
    kappa = np.log1p(2.0 * np.sin(0.5 * a))
    ht = h(tips)
    r1 = ht
    # Graded only along the walls: up to where kappa r reaches h, at most the shorter wall.
    reach = np.minimum(ht / kappa, np.minimum(before[sharp], after[sharp]))
    return _TipGraded(h, tips, kappa, r1, reach)


@dataclass(frozen=True)
class _ShortTips:
    """Sharp corners between two straight walls whose shorter wall (or half of a wall shared
    with another sharp corner) is shorter than the tip's grading reaches (see
    :func:`_tip_walls`)."""

    tips: FloatArray  # (k, 2)
    units: tuple[FloatArray, FloatArray]  # (k, 2) each: unit vectors along the two walls
    room: tuple[FloatArray, FloatArray]  # (k,) each: wall length, or half of a shared wall
    shared: tuple[NDArray[np.bool_], NDArray[np.bool_]]  # wall ends at another sharp corner
    ends: tuple[FloatArray, FloatArray]  # (k, 2) each: the walls' far ends
    g: FloatArray  # grading factor 1 + 2 sin(a / 2)
    short: FloatArray  # the shorter room
    ht: FloatArray  # h at the tip


def _short_tips(domain: Domain, h: SizeFn) -> _ShortTips | None:
    brep = _exact_brep(domain)
    if brep is None:
        return None
    pts, turn, before, after = brep.junctions()
    angle = 180.0 - turn
    sharp = np.flatnonzero(angle < SHARP_CORNER)
    if len(sharp) == 0:
        return None
    start = brep.loop_start
    loop = np.searchsorted(start, sharp, side="right") - 1
    lo, hi = start[loop], start[loop + 1]
    # Junction i ends piece i and starts the next one: its walls end at junctions i -/+ 1.
    prev = np.where(sharp == lo, hi - 1, sharp - 1)
    nxt = np.where(sharp == hi - 1, lo, sharp + 1)
    tips = pts[sharp]
    ends = (pts[prev], pts[nxt])
    walls = (before[sharp], after[sharp])
    straight = np.ones(len(sharp), dtype=bool)
    for end, length in zip(ends, walls, strict=True):
        chord = np.hypot(*(end - tips).T)
        straight &= np.abs(chord - length) <= 1e-9 * length  # an arc is longer than its chord
    # A wall between two sharp corners (a thin triangle) is shared: each corner lays nodes on
    # its half only, and both put the same node at its midpoint when they reach it.
    is_sharp = np.zeros(len(pts), dtype=bool)
    is_sharp[sharp] = True
    shared = (is_sharp[prev], is_sharp[nxt])
    room = (np.where(shared[0], 0.5 * walls[0], walls[0]), np.where(shared[1], 0.5 * walls[1], walls[1]))
    g = 1.0 + 2.0 * np.sin(0.5 * np.radians(angle[sharp]))
    ht = h(tips)
    short = np.minimum(room[0], room[1])
    keep = np.flatnonzero(straight & (short < ht / np.log(g)))
    if len(keep) == 0:
        return None
    units = tuple((e[keep] - tips[keep]) / w[keep, None] for e, w in zip(ends, walls, strict=True))
    return _ShortTips(tips[keep], (units[0], units[1]), (room[0][keep], room[1][keep]),
                      (shared[0][keep], shared[1][keep]), (ends[0][keep], ends[1][keep]),
                      g[keep], short[keep], ht[keep])


def _tip_walls(domain: Domain, h: SizeFn) -> FloatArray:
    """Nodes held on both walls of a sharp corner whose shorter wall ends before the tip's
    grading does, at the same distances from the tip.

    :func:`_tip_graded` lays a corner's walls in whole h-lengths from the tip, which puts the
    nodes of both walls at the same distances only while both walls go on (it grades up to
    ``h(tip) / kappa``, 3-8 h for 20-7 degrees).  A spike or inlet shorter than that (a
    coastline's, a fraction of h long) ends its shorter wall at a polygon vertex first: the
    walls then got nodes at different distances (the longer wall's rounding and balancing,
    then the encroachment splits of :func:`_split_encroached`, which halve each wall by its
    own length), and the tip triangle was far from isosceles (an 11.8-degree coastline spike
    of walls 0.13 and 0.16 h: q = 0.21 where the angle allows 0.37).

    Here the shorter wall's length ``L`` sets the layout: nodes at ``L / g**k`` on both walls
    (``g = 1 + 2 sin(a / 2)``, the grading factor of :func:`_tip_graded`, so the strip between
    the walls is of nearly square trapezoids), k = 0, 1, ... down to the first at most
    ``h(tip)``, which makes the isosceles tip triangle.  ``k = 0`` is the shorter wall's own
    end, so it is added on the longer wall only, and only when that wall is longer by half a
    step (else its end is nearly there).  A wall shared with another sharp corner counts
    half its length, and its midpoint is the same node from both ends.  Only corners between
    two straight pieces.  Beyond ``L`` the size is lowered by :func:`corner_spacing` (the
    mouth there is a corner's spacing).

    Returns
    -------
    (k, 2) array
        Points on the walls, to be held fixed like corners.
    """
    st = _short_tips(domain, h)
    if st is None:
        return np.empty((0, 2))
    out = []
    for c in range(len(st.tips)):
        r = [float(st.short[c])]
        while r[-1] > st.ht[c] and len(r) < TIP_STEPS:
            r.append(r[-1] / st.g[c])
        for side in (0, 1):
            wall = [st.tips[c] + rk * st.units[side][c] for rk in r]
            if st.shared[side][c] and st.room[side][c] == st.short[c]:
                wall[0] = 0.5 * (st.tips[c] + st.ends[side][c])  # the same bits from either end
            elif not st.shared[side][c] and st.room[side][c] < st.short[c] * (1.0 + 0.5 * (st.g[c] - 1.0)):
                # The wall's own end (the shorter wall's, or one within half a step of it)
                # is a vertex already.
                wall = wall[1:]
            out.extend(wall)
    return np.asarray(out, dtype=float).reshape(-1, 2)


def _mouths(domain: Domain, h: SizeFn) -> tuple[FloatArray, FloatArray]:
    """The mouths of the sharp corners :func:`_tip_walls` lays out: the point at the shorter
    wall's length on the longer wall, and the width there (``2 L sin(a / 2)``).

    Past the mouth the longer wall faces the shorter wall's end across that width: sized by
    the wall's own h, its segments there made slivers with that vertex (q = 0.33 where the
    tip allows 0.37, for a 12-degree spike 0.2 h long whose longer wall goes on 0.6 h).
    """
    st = _short_tips(domain, h)
    if st is None:
        return np.empty((0, 2)), np.empty(0)
    longer = (st.room[1] > st.room[0])[:, None]
    unit = np.where(longer, st.units[1], st.units[0])
    return st.tips + st.short[:, None] * unit, st.short * (st.g - 1.0)


#: Nodes laid on each wall of a sharp corner by :func:`_tip_walls`, at most.
TIP_STEPS = 64
#: Corners with an interior angle below this (degrees) are sharp: see :func:`_pin_wedges`.
#: Pinning at 30-60 degrees lowered q_min next to the tip (0.70 -> 0.56 on a 45-degree kite).
#: Above this the isosceles tip costs the strip behind it: the triangle on the tip's base has
#: an angle of 90 + a/2 at a wall node, so its q is at most 8 sin(45 + a/4) sin^2(22.5 - a/8)
#: (0.717 at 20 degrees, 0.70 at 22.9, 0.687 at 25, 0.66 at 30), while unpinned walls come
#: out staggered, tip at ~0.91 of the angle's bound and strip ~0.82.  22.5 keeps that bound
#: at 0.70 or more (issue 8's "thin parts keep q_min >= 0.7").  Over
#: ``benchmarks/robustness.py``'s 1000 polygons, 25 -> 22.5 took the cases whose thin parts
#: fall below 0.7 from 52 to 11; the tip triangles of the 22.5-25 degree corners went from
#: the angle's bound to 0.90-0.95 of it (cases below 0.95 of it: 23 -> 50 of 217).
SHARP_CORNER = 22.5
#: Nodes of a sharp corner's walls are held still where the walls are closer than this times h.
PIN_WIDTH = 0.8


def _resolved_vertices(domain: Domain, h: SizeFn) -> FloatArray:
    """Polygon vertices the mesh can resolve: both pieces at the vertex at least
    ``VERTEX_ARM * h`` long.

    A vertex turning less than ``CORNER_ANGLE`` is not a corner, but an outline with vertices
    far apart (a CAD drawing, a coarse polygon) means its vertices: a chord across one would cut
    the domain.  Only where the vertices are closer than h (a digitised curve) does the boundary
    treat them as samples of a smooth curve.
    """
    brep = _exact_brep(domain)
    if brep is None:
        return np.empty((0, 2))
    pts, turn, before, after = brep.junctions()
    # Smooth junctions (an arc continuing an arc, collinear segments) are no vertices.
    kink = np.abs(turn) > VERTEX_TURN
    pts, before, after = pts[kink], before[kink], after[kink]
    if len(pts) == 0:
        return np.empty((0, 2))
    return np.asarray(pts[np.minimum(before, after) >= VERTEX_ARM * h(pts)], dtype=float)


#: A polygon vertex turning by more than VERTEX_TURN degrees is a node when both its edges are
#: at least VERTEX_ARM h long.  With h/2 a wall digitised at 0.5-1 h kept every vertex, and the
#: boundary edges between them, that short, met interior edges of h: in a channel thinner than
#: the user's h, where h is the feature size / 2, that gave q 0.68-0.70 across the channel.
VERTEX_ARM = 1.0
VERTEX_TURN = 0.1

#: :func:`corner_size`'s search structure: corners per leaf of its k-d tree, cells of its grid
#: of lower bounds per corner.
CONE_LEAF = 8
CONE_CELLS = 2.0


def _exact_brep(domain: Domain) -> BRep | None:
    return domain if isinstance(domain, BRep) else getattr(domain, "exact_brep", lambda: None)()


def corner_spacing(domain: Domain, h: SizeFn) -> tuple[FloatArray, FloatArray]:
    """The junctions Step 1 holds fixed and, for each, the distance along the boundary to the
    nearest other fixed junction of its loop, or to one facing it across the domain if nearer.

    Fixed junctions are the corners (turning more than ``CORNER_ANGLE`` degrees) and the
    vertices :func:`_resolved_vertices` keeps.  A boundary segment cannot be longer than the
    stretch between two fixed nodes, so this distance is the longest segment Step 1 can lay
    next to the corner; across the domain (the mouth of an inlet or a spike, :func:`_across`)
    it is the length of a mesh edge there.  The mouths of sharp corners shorter than their
    grading (:func:`_mouths`) follow the junctions, with their width.

    Returns
    -------
    points : (k, 2) array
    spacing : (k,) array
        Empty arrays for a domain without an exact boundary (an implicit d).
    """
    brep = _exact_brep(domain)
    if brep is None:
        return np.empty((0, 2)), np.empty(0)
    pts, turn, before, after = brep.junctions()
    start = brep.loop_start
    fixed = np.abs(turn) > tol.CORNER_ANGLE
    kink = ~fixed & (np.abs(turn) > VERTEX_TURN)
    if kink.any():
        arms = np.minimum(before[kink], after[kink])
        fixed[np.flatnonzero(kink)] = arms >= VERTEX_ARM * h(pts[kink])
    out_p, out_s = [], []
    for k in range(len(start) - 1):
        lo, hi = int(start[k]), int(start[k + 1])
        # Arc length of each junction (the end of piece i) from the start of its loop.
        arc = np.cumsum(before[lo:hi])
        total = float(arc[-1])
        idx = np.flatnonzero(fixed[lo:hi])
        if len(idx) == 0:
            continue
        at = arc[idx]
        gap = np.diff(np.r_[at, at[0] + total])  # to the next fixed junction
        if len(idx) == 1:
            gap = np.array([total])
        out_p.append(pts[lo:hi][idx])
        out_s.append(np.minimum(gap, np.roll(gap, 1)))
    if not out_p:
        return np.empty((0, 2)), np.empty(0)
    p, spacing = np.concatenate(out_p), np.concatenate(out_s)
    mouth, width = _mouths(domain, h)
    return np.concatenate([p, mouth]), np.concatenate([_across(domain, p, spacing), width])


def _across(domain: Domain, p: FloatArray, spacing: FloatArray) -> FloatArray:
    """``spacing`` lowered to the distance to a nearer fixed junction across the domain.

    Two corners can be far apart along the boundary and close across the domain: the mouth
    of a spike or an inlet narrower than h (a coastline's, a fraction of h wide and long), where
    the boundary turns away on both sides.  The mouth's segment is then a mesh edge, and with
    the boundary beyond it laid at h the triangles on it were slivers (q = 0.16 at an inlet
    0.03 h wide; the feature size, whose grid is coarser than such a mouth, does not see it).
    The segment between the two must cross the domain (its midpoint inside by a tenth of its
    length): corners facing each other across a notch of the outside need nothing.
    """
    from scipy.spatial import cKDTree

    k = min(ACROSS_NEIGHBOURS + 1, len(p))
    if k < 2:
        return spacing
    dist, near = cKDTree(p).query(p, k=k)
    dist, near = dist[:, 1:], near[:, 1:]
    rows, cols = np.nonzero(dist < spacing[:, None] * (1.0 - 1e-9))
    if len(rows) == 0:
        return spacing
    d = dist[rows, cols]
    mid = 0.5 * (p[rows] + p[near[rows, cols]])
    inside = domain.sdf(mid) < -ACROSS_DEPTH * d
    out = spacing.copy()
    np.minimum.at(out, rows[inside], d[inside])
    return out


#: :func:`_across` looks at this many nearest fixed junctions of each, and counts one whose
#: segment's midpoint lies this far (a fraction of its length) inside the domain.
ACROSS_NEIGHBOURS = 4
ACROSS_DEPTH = 0.1


class _CornerCap:
    """``min(h(p), min_c (s_c + rate |p - c|))`` over all corners c, the brute-force minimum
    bit for bit (:func:`injmesh.kernels.outline.corner_cones`: a k-d tree of the corners, and
    a grid whose cells know a lower bound of the cones over them and list the tree's leaves that
    can hold the minimum there; a point reads a few leaves and corners)."""

    def __init__(self, h: SizeFn, corners: FloatArray, spacing: FloatArray, rate: float) -> None:
        from .kernels.outline import cone_index

        self.h, self.rate = h, rate
        self.corners = np.ascontiguousarray(corners, dtype=np.float64)
        self.spacing = np.ascontiguousarray(spacing, dtype=np.float64)
        # Cones over a uniform size are meaningful anywhere: callers that evaluate h just
        # outside the domain need not project there first (sizing.features.unrestricted).
        self.everywhere = getattr(h, "constant", None) is not None
        # The grid reaches as far beyond the corners as a cone can lower the h found at them
        # (at most the corners' extent), and its cells list leaves where a cone can lower that
        # h.  A point elsewhere (h larger than at the corners, or outside the grid) searches
        # the whole tree: as exact, a little slower; the root's bound dismisses a far point.
        h_max = float(np.max(h(self.corners)))
        reach = (h_max - float(self.spacing.min())) / rate
        extent = float(np.ptp(self.corners, axis=0).max())
        margin = min(reach, extent) if extent > 0.0 else reach
        self.index = cone_index(self.corners, self.spacing, float(rate), CONE_LEAF, margin,
                                CONE_CELLS * len(self.corners), h_max)

    def __call__(self, p: FloatArray) -> FloatArray:
        from .kernels.outline import threaded_corner_cones

        hp = self.h(p)
        if len(p) == 0:
            return hp
        out: FloatArray = threaded_corner_cones(
            np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(hp, dtype=np.float64),
            self.index)
        return out


def corner_size(domain: Domain, h: SizeFunction, rate: float = 0.2) -> SizeFunction:
    """h lowered near corners closer together than h, graded back at slope ``rate``.

    Every corner of a polygon is a node (Step 1 fixes it), so where corners are closer than h
    (a digitised coastline, a detailed outline) the boundary segments are as short as the
    corners' spacing whatever h says.  Interior nodes at h next to them would make fans of
    slivers; the size instead becomes ``min(h, min_c (s_c + rate |p - c|))`` over every corner
    c, with s_c the distance to c's nearest fixed neighbour along the boundary
    (:func:`corner_spacing`), a cone that Eq. 3.1-3.3 and the injection then follow.  The
    minimum over every corner (exact, not over a few nearest ones) is rate-Lipschitz wherever h
    is, which is what gradation needs; a point costs a handful of corners
    (:func:`injmesh.kernels.outline.corner_cones`).

    Returns
    -------
    SizeFunction
        ``h`` itself when no corner is closer to its neighbours than h there.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Polygon
    >>> from injmesh.sizing import as_size_function
    >>> zigzag = Polygon([(0, 0), (1, 0), (1, 1), (0.55, 1.02), (0.5, 1), (0.45, 1.02), (0, 1)])
    >>> hc = corner_size(zigzag, as_size_function(0.2))
    >>> hc(np.array([[0.5, 1.0], [0.5, 0.2]])).round(3).tolist()
    [0.054, 0.2]
    """
    pts, spacing = corner_spacing(domain, h)
    if len(pts) == 0:
        return h
    low = spacing < h(pts) * (1.0 - 1e-9)
    if not low.any():
        return h
    return SizeFunction(_CornerCap(h, pts[low], spacing[low], float(rate)))


def _drop_tiny(loops: list[FloatArray], h: SizeFn) -> list[FloatArray]:
    """Drop boundary curves shorter than ``TINY_LOOP`` times h, with a warning.

    Such a curve (a hole or an island smaller than the elements, a sliver where two curves
    almost touch) cannot carry three nodes without elements far smaller than h.
    """
    keep = []
    for k, loop in enumerate(loops):
        closed = np.concatenate([loop, loop[:1]])
        # h at the vertices, which are on the boundary (h is never asked outside the domain).
        hv = h(closed)
        hlen = float(np.sum(np.hypot(*np.diff(closed, axis=0).T) / (0.5 * (hv[1:] + hv[:-1]))))
        if hlen >= tol.TINY_LOOP or k == 0:
            keep.append(loop)
        else:
            c = loop.mean(axis=0)
            warnings.warn(
                f"a boundary curve near ({c[0]:.4g}, {c[1]:.4g}) is {hlen:.2g} h long, shorter "
                f"than {tol.TINY_LOOP} h: it is smaller than the elements and is left out",
                stacklevel=4,
            )
    return keep


def _split_encroached(
    domain: Domain, p: FloatArray, fixed: NDArray[np.bool_], node_loop: IntArray
) -> tuple[FloatArray, NDArray[np.bool_], IntArray]:
    """Split boundary segments whose diametral circle holds another boundary node on the
    domain's side.

    Delaunay triangulation keeps a segment only if no node lies in that circle; a spike
    narrower than h or a hole close to the outer boundary would otherwise lose segments.  The
    projected midpoint is inserted (Ruppert's segment splitting), at most ``ENCROACH_ROUNDS``
    times, which refines the boundary locally where features are thinner than h.  A node
    across the outside (the other wall of a narrow slit or notch of non-domain) does not
    count: a triangle reaching it would lie outside and is never kept, the segment is
    recovered by flips at the end if Delaunay misses it, and splitting for it cascaded
    towards the slit's tip (a coastline's 12-degree land spike: 18 boundary nodes within
    1.7 h of the tip, slivers of q 0.13 fanning to them).
    """
    from scipy.spatial import cKDTree

    # A segment is tested again only where its answer can change.  Its nodes never move and
    # its diametral circle is fixed, so its set S of other nodes strictly inside the circle
    # changes only when a new node lands there.  The three nearest nodes the test reads are
    # S first (nearer than the segment's own ends), so with at most two nodes in S the test is
    # "a node of S on the domain's side", whatever the tree returns on ties: a segment that
    # was not split stays unsplit until a new node lands in its circle.  With three nodes or
    # more in S, the three the tree returns can depend on its ties: such a segment is tested
    # in every round, as all were.
    ask = np.arange(len(p))
    for _ in range(tol.ENCROACH_ROUNDS):
        nxt = _next(node_loop)
        mid = 0.5 * (p + p[nxt])
        radius = 0.5 * np.hypot(*(p[nxt] - p).T)
        k = min(3, len(p))
        dist, near = cKDTree(p).query(mid[ask], k=k)
        own = (near == ask[:, None]) | (near == nxt[ask][:, None])
        # The domain is on the left of every loop: a node counts when it is left of a -> b.
        e = p[nxt[ask]] - p[ask]
        rel = p[near] - p[ask][:, None, :]
        left = e[:, None, 0] * rel[..., 1] - e[:, None, 1] * rel[..., 0] > 0
        inside = ~own & (dist < radius[ask][:, None] * (1 - 1e-9))
        split = np.zeros(len(p), dtype=bool)
        split[ask] = np.any(inside & left, axis=1)
        if not split.any():
            break
        crowded = np.zeros(len(p), dtype=bool)
        crowded[ask] = inside.all(axis=1)
        new = domain.project(mid[split])
        # Unsplit segments with a new node in their circle (the nearest new node suffices).
        reached = np.zeros(len(p), dtype=bool)
        gap, _ = cKDTree(new).query(mid)
        reached[~split] = gap[~split] <= radius[~split] * (1 + 1e-9)
        key = np.concatenate([np.arange(len(p), dtype=float), np.flatnonzero(split) + 0.5])
        order = np.argsort(key, kind="stable")
        p = np.concatenate([p, new])[order]
        fixed = np.concatenate([fixed, np.zeros(len(new), dtype=bool)])[order]
        node_loop = np.concatenate([node_loop, node_loop[split]])[order]
        # Next round: both halves of every split segment, and the segments above.
        again = np.concatenate([split | reached | crowded, np.ones(len(new), dtype=bool)])[order]
        ask = np.flatnonzero(again)
    return p, fixed, node_loop


def order_loops(loops: list[FloatArray]) -> list[FloatArray]:
    """Outer boundaries by decreasing area, each followed by its holes by decreasing area.

    A hole (clockwise, negative area) belongs to the smallest outer boundary that contains its
    first vertex.  Equal areas are ordered by the loops' lowest-leftmost vertex, so the order,
    hence the boundary tags, depends on the shape only.

    Examples
    --------
    >>> import numpy as np
    >>> sq = lambda x, y, s: np.array([[x, y], [x + s, y], [x + s, y + s], [x, y + s]], float)
    >>> out = order_loops([sq(1, 1, 1)[::-1], sq(10, 0, 2), sq(0, 0, 4)])
    >>> [round(_area(lp), 1) for lp in out]
    [16.0, -1.0, 4.0]
    """
    area = np.array([_area(lp) for lp in loops])
    lowest = [tuple(lp[np.lexsort((lp[:, 1], lp[:, 0]))[0]].tolist()) for lp in loops]
    outer = sorted(np.flatnonzero(area > 0).tolist(), key=lambda k: (-area[k], lowest[k]))
    holes = sorted(np.flatnonzero(area <= 0).tolist(), key=lambda k: (area[k], lowest[k]))
    owner: dict[int, list[int]] = {k: [] for k in outer}
    orphans = []
    for k in holes:
        probe = loops[k][:1]
        inside = [j for j in outer if _contains(loops[j], probe)]
        if inside:
            owner[min(inside, key=lambda j: area[j])].append(k)
        else:
            orphans.append(k)
    order = [j for k in outer for j in [k, *owner[k]]] + orphans
    return [loops[k] for k in order]


def _contains(loop: FloatArray, q: FloatArray) -> bool:
    """Even-odd test of the single point ``q (1, 2)`` against a closed polyline."""
    a, b = loop, np.roll(loop, -1, axis=0)
    y, x = float(q[0, 1]), float(q[0, 0])
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xint = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(crosses & (x < xint)) % 2)


def _area(loop: FloatArray) -> float:
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _next(node_loop: IntArray) -> IntArray:
    """Next node of each node along its (closed) loop."""
    idx = np.arange(len(node_loop))
    start = np.flatnonzero(np.r_[True, node_loop[1:] != node_loop[:-1]])
    end = np.r_[start[1:], len(node_loop)] - 1
    first = np.repeat(start, end - start + 1)
    last = np.repeat(end, end - start + 1)
    return np.where(idx == last, first, idx + 1)


#: :func:`_tip_marks`' second vertex lies this fraction of r1 beyond the first.
MARK_GAP = 1e-6


def _tip_marks(
    domain: Domain, p: FloatArray, fixed: NDArray[np.bool_], along: SizeFn, on: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Insert, as free vertices of the loop ``p``, the points at arc length ``r1`` from each
    sharp corner's tip along both its walls (:func:`_tip_graded`), where the walls are that long.

    The size along the walls jumps there, from ``r1`` to ``kappa r1``.  Step 1 integrates 1/h
    linearly between the refined vertices, so a refined segment across the jump smeared it and
    the walls' first nodes landed a little off ``r1``, each wall by its own refinement; at 5
    degrees walls out of step by 0.4 % let the opposite node encroach the tip segment, which
    was then halved again and again (a cascade of tip slivers).  With a vertex at ``r1`` the
    integral up to it is exact, one h-length, on both walls alike; a second vertex just beyond
    (``MARK_GAP`` r1 further) takes ``kappa r1``, so the next step is exact too.
    """
    if not isinstance(along, _TipGraded) or not fixed.any():
        return p, fixed
    tips = along.tips
    from scipy.spatial import cKDTree

    held = np.flatnonzero(fixed)
    dist, which = cKDTree(tips).query(p[held], distance_upper_bound=on)
    at_tip = np.isfinite(dist)
    n = len(p)
    seglen = np.hypot(*(np.roll(p, -1, axis=0) - p).T)
    keys, marks = [], []
    for i, c in zip(held[at_tip].tolist(), which[at_tip].tolist(), strict=True):
        for r in (float(along.r1[c]), float(along.r1[c]) * (1.0 + MARK_GAP)):
            for step in (1, -1):
                j, walked = i, 0.0
                for _ in range(n):
                    nxt = (j + step) % n
                    seg = j if step == 1 else nxt  # segment k joins vertices k and k + 1
                    if walked + seglen[seg] >= r:
                        frac = (r - walked) / seglen[seg]  # from j towards nxt
                        if frac < 1.0 - 1e-9 or not fixed[nxt]:
                            marks.append(p[j] + frac * (p[nxt] - p[j]))
                            keys.append(seg + (frac if step == 1 else 1.0 - frac))
                        break
                    walked += seglen[seg]
                    j = nxt
                    if fixed[j]:  # the wall ends before r1 (a short tip: _tip_walls lays it out)
                        break
    if not marks:
        return p, fixed
    pts = domain.project(np.asarray(marks, dtype=float))  # Eq. 3.2
    key = np.concatenate([np.arange(n, dtype=float), np.clip(keys, 1e-9, n - 1e-9)])
    order = np.argsort(key, kind="stable")
    return np.concatenate([p, pts])[order], np.concatenate([fixed, np.zeros(len(pts), dtype=bool)])[order]


#: What :func:`_corner_feet` finds of the corners near one loop: their indices, the nearest
#: segment of each, the parameter and distance of its foot, and the radius within which a
#: corner counts as the loop's.
_Feet = tuple[NDArray[np.intp], NDArray[np.intp], FloatArray, FloatArray, float]


def _corner_feet(loop: FloatArray, corners: FloatArray, on: float) -> _Feet:
    """The corners within reach of this loop (closed polyline) and their feet on it."""
    a, b = loop, np.roll(loop, -1, axis=0)
    ab = b - a
    ab2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    # A corner belongs to this loop when the traced polyline passes close to it; traced
    # polylines cut corners by up to about a grid cell, hence the loose radius.
    radius = max(on, 2.0 * float(np.sqrt(ab2.max())))
    if len(corners) == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, np.zeros(0), np.zeros(0), radius
    # Only corners that near the loop's box are measured (the other loops' corners, far
    # away, would each be measured against many of this loop's segments): a point's
    # nearest segment does not depend on the other points asked.
    gap = np.maximum(np.maximum(loop.min(axis=0) - corners, corners - loop.max(axis=0)), 0.0)
    near = np.flatnonzero(np.hypot(gap[:, 0], gap[:, 1]) <= radius * (1 + 1e-9))
    seg, t, d = _nearest_segments(corners[near], a, ab, ab2)
    return near, seg, t, d, radius


def _nearest_loop_distance(feet: list[_Feet], n_corners: int) -> FloatArray:
    """Each corner's distance to its nearest loop (``inf`` when no loop reaches it)."""
    best = np.full(n_corners, np.inf)
    for near, _, _, d, _ in feet:
        np.minimum.at(best, near, d)
    return best


def _insert_corners(
    loop: FloatArray, corners: FloatArray, feet: _Feet, nearest: FloatArray, on: float, diam: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Insert the corners that lie on this loop as fixed vertices; fix one anchor if none.

    ``feet``: :func:`_corner_feet` of this loop; ``nearest``: each corner's distance to its
    nearest loop.  A corner is this loop's when it lies within the loop's radius and this loop
    is (to ``on``) its nearest: two loops passing within the radius of each other (a polygon
    vertex 0.0015 off a circle it nearly touches, for h = 0.006) would otherwise both take the
    vertex, and the two coincident nodes lost the segments at it (found by fuzzing).  A point
    where loops touch lies on both, and both take it.
    """
    n = len(loop)
    fixed = np.zeros(n, dtype=bool)
    near, seg, near_t, near_d, radius = feet
    if len(near):
        mine = (near_d <= radius) & (near_d <= nearest[near] + on)
        if mine.any():
            seg, tt, c = seg[mine], near_t[mine], corners[near[mine]]
            # Vertices that coincide with a corner become that corner.
            key = np.concatenate([np.arange(n, dtype=float), seg + np.clip(tt, 1e-9, 1 - 1e-9)])
            allp = np.concatenate([loop, c])
            allf = np.concatenate([fixed, np.ones(len(c), dtype=bool)])
            order = np.argsort(key, kind="stable")
            loop, fixed = allp[order], allf[order]
            # Drop free vertices within a tiny distance of a fixed one (duplicates).
            nb = np.roll(np.arange(len(loop)), -1)
            pb = np.roll(np.arange(len(loop)), 1)
            close_n = np.hypot(*(loop - loop[nb]).T) < 1e-9 * diam
            close_p = np.hypot(*(loop - loop[pb]).T) < 1e-9 * diam
            dup = ~fixed & ((close_n & fixed[nb]) | (close_p & fixed[pb]))
            # Fixed duplicates of fixed points (a corner listed twice): keep the first.
            dup |= fixed & close_p & fixed[pb] & (np.arange(len(loop)) > 0)
            loop, fixed = loop[~dup], fixed[~dup]
    if not fixed.any():
        # A closed smooth curve: fix one point so balancing cannot rotate the nodes (Sec. 3.1).
        fixed[np.lexsort((loop[:, 1], loop[:, 0]))[0]] = True
    # Start each loop at a fixed vertex.
    first = int(np.argmax(fixed))
    return np.roll(loop, -first, axis=0), np.roll(fixed, -first)


def _nearest_segments(
    q: FloatArray, a: FloatArray, ab: FloatArray, ab2: FloatArray
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Nearest segment ``a[i] -> a[i] + ab[i]`` of each point q: index (the lowest on a tie),
    parameter t in [0, 1] of the foot, and distance.

    O((n + k) log n) for n segments of similar lengths: a segment within distance D of q has
    its midpoint within ``D + length / 2``, and D is at most the distance to the nearest segment
    end, so only the segments whose midpoints lie in that ball are measured (a uniform grid of
    the midpoints, :func:`injmesh.kernels.outline.points_in_balls`).
    Segments more than ``4x`` the median length would make every ball large: they are measured
    against every point, in chunks.  Up to ``BRUTE_PAIRS`` point-segment pairs (a polygon's
    corners against its loop: a few hundred segments), every pair is measured in one compiled
    pass instead (:func:`~injmesh.kernels.outline.nearest_segments_brute`, the same numbers:
    the balls hold every segment that can be nearest, the others are farther by their margin).
    """
    m = len(q)
    if m == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    if m * len(a) <= BRUTE_PAIRS:
        from .kernels.outline import nearest_segments_brute

        seg, t, d = nearest_segments_brute(np.ascontiguousarray(q, dtype=np.float64),
                                           np.ascontiguousarray(a, dtype=np.float64),
                                           np.ascontiguousarray(ab, dtype=np.float64),
                                           np.ascontiguousarray(ab2, dtype=np.float64))
        return np.asarray(seg, dtype=np.intp), t, d
    return _nearest_segments_search(q, a, ab, ab2)


#: :func:`_nearest_segments` measures every pair up to this many point-segment pairs.
BRUTE_PAIRS = 1 << 16


def _nearest_segments_search(
    q: FloatArray, a: FloatArray, ab: FloatArray, ab2: FloatArray
) -> tuple[IntArray, FloatArray, FloatArray]:
    """:func:`_nearest_segments` by the balls around the points (any number of them)."""
    from scipy.spatial import cKDTree

    from .kernels.outline import points_in_balls

    m = len(q)
    length = np.sqrt(ab2)
    long = length > 4.0 * float(np.median(length))
    rows, cols = [np.empty(0, dtype=np.intp)], [np.empty(0, dtype=np.intp)]
    short = np.flatnonzero(~long)
    ends = np.concatenate([a[short], a[short] + ab[short]])
    reach, _ = cKDTree(ends).query(q)
    mid = a[short] + 0.5 * ab[short]
    half = 0.5 * float(length[short].max()) if len(short) else 0.0
    radius = (reach + half) * (1 + 1e-9)  # rounding: keep the rim
    # Cells as wide as the longest short segment: a ball (the distance to the nearest end plus
    # half that length) overlaps a few cells; at most about 4 cells per segment (short
    # segments far apart along long ones).
    extent = float(np.ptp(mid, axis=0).max()) if len(mid) else 0.0
    cell = max(2.0 * half, extent / (2.0 * np.sqrt(len(mid)) + 1.0), 1e-300)
    r_, c_ = points_in_balls(q, radius, mid, cell)
    rows.append(r_)
    cols.append(short[c_])
    lg = np.flatnonzero(long)
    step = max(1, 4_000_000 // max(1, len(lg)))
    for s0 in range(0, m if len(lg) else 0, step):
        k = min(step, m - s0)
        rows.append(np.repeat(np.arange(s0, s0 + k), len(lg)))
        cols.append(np.tile(lg, k))
    r, c = np.concatenate(rows), np.concatenate(cols)
    t = np.clip(np.einsum("ij,ij->i", q[r] - a[c], ab[c]) / ab2[c], 0, 1)
    foot = a[c] + t[:, None] * ab[c]
    dist = np.hypot(q[r, 0] - foot[:, 0], q[r, 1] - foot[:, 1])
    # Per point: the smallest distance, then the lowest segment index (as np.argmin would).
    order = np.lexsort((c, dist, r))
    first = order[np.r_[True, r[order][1:] != r[order][:-1]]]
    out_seg = np.zeros(m, dtype=np.intp)
    out_t, out_d = np.zeros(m), np.full(m, np.inf)
    out_seg[r[first]], out_t[r[first]], out_d[r[first]] = c[first], t[first], dist[first]
    return out_seg, out_t, out_d


def _refine(
    domain: Domain, h: SizeFn, p: FloatArray, fixed: NDArray[np.bool_]
) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """Algorithm 2: inject h-weighted midpoints (3.1), project them (3.2), until resolved.

    Returns the refined closed polyline, its fixed vertices and h at its vertices.  h is a
    function of each point alone, so it is asked once per vertex, when the vertex is made (a
    detailed outline's boundary grows from 20,000 to 100,000 vertices in a few rounds, and
    asking h again at every vertex of every round cost seven times as many evaluations).
    """
    hp = h(p)
    for _ in range(40):
        q = ring_next(p)
        hq = ring_next(hp)
        length = np.hypot(*(q - p).T)
        split = length > tol.BOUNDARY_REFINE * np.minimum(hp, hq)
        if not split.any():
            break
        wp, wq = 1.0 / hp[split], 1.0 / hq[split]
        new = (p[split] * wp[:, None] + q[split] * wq[:, None]) / (wp + wq)[:, None]  # Eq. 3.1
        new = domain.project(new)  # Eq. 3.2
        key = np.concatenate([np.arange(len(p), dtype=float), np.flatnonzero(split) + 0.5])
        order = np.argsort(key, kind="stable")
        p = np.concatenate([p, new])[order]
        fixed = np.concatenate([fixed, np.zeros(len(new), dtype=bool)])[order]
        hp = np.concatenate([hp, h(new)])[order]
    return p, fixed, hp


def _select(
    domain: Domain, p: FloatArray, fixed: NDArray[np.bool_], hp: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Lay ``round(S)`` segments at equal h-length between fixed vertices, then balance them.

    ``p`` is the refined closed polyline of one loop, starting at a fixed vertex, and ``hp`` h
    at its vertices (:func:`_refine`).  Nodes are handled by their arc length t along it, so
    balancing (Eq. 3.3) is truly one-dimensional: each node stays between the midpoints of its
    two segments and nodes can neither cross nor collapse, however few there are on a tightly
    curved loop (in the plane, chord midpoints and projection made Eq. 3.3 drift there).
    """
    closed = np.concatenate([p, p[:1]])
    seglen = np.hypot(*np.diff(closed, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seglen)])
    total = float(arc[-1])
    # h at the vertices of the refined curve (on the boundary; chord midpoints of a concave
    # curve are outside the domain, where h may mean nothing), linear along each segment.
    hv = np.concatenate([hp, [0.0]])
    hv[-1] = hv[0]
    ds = seglen / (0.5 * (hv[1:] + hv[:-1]))
    s = np.concatenate([[0.0], np.cumsum(ds)])
    fixed_idx = np.r_[np.flatnonzero(fixed), len(p)]  # fixed[0] is True; len(p) closes the loop
    s_start = s[fixed_idx[:-1]]
    span = s[fixed_idx[1:]] - s_start
    count = np.maximum(1, np.rint(span).astype(int))
    if count.sum() < 3:  # a loop needs three nodes at least
        count[np.argmax(span)] += 3 - count.sum()
    piece = np.repeat(np.arange(len(count)), count)
    k = np.arange(len(piece)) - np.repeat(np.cumsum(count) - count, count)
    # Stretches that start or end at a sharp corner are laid in whole h-lengths from the corner
    # (the rounding left at their other end), and those nodes are not balanced: both walls of
    # the corner then carry nodes at the same distances from its tip (see _tip_graded).
    tip = _sharp_vertices(p)
    from_start = tip[fixed_idx[:-1]] & ~tip[fixed_idx[1:] % len(p)]
    from_end = tip[fixed_idx[1:] % len(p)] & ~tip[fixed_idx[:-1]]
    whole = (from_start | from_end) & (count > 1)
    offset = np.where(from_end, span - count, 0.0)
    equal = s_start[piece] + k * span[piece] / count[piece]
    at = np.where(whole[piece], s_start[piece] + offset[piece] + k, equal)
    t = np.interp(at, s, arc)
    t[k == 0] = arc[fixed_idx[:-1]]
    held = (k == 0) | (from_start[piece] & (k < count[piece] - 2)) | (from_end[piece] & (k > 2))
    t = _balance(hv, t, held, arc, total)
    out = np.stack([np.interp(t, arc, closed[:, 0]), np.interp(t, arc, closed[:, 1])], axis=1)
    new_fixed = k == 0
    out[new_fixed] = p[fixed_idx[:-1]]
    free = ~new_fixed
    if free.any():
        out[free] = domain.project(out[free])  # Eq. 3.2
    return out, new_fixed


def _sharp_vertices(p: FloatArray) -> NDArray[np.bool_]:
    """Vertices of a closed polyline (domain on the left) whose interior angle is below
    ``SHARP_CORNER``."""
    u, w = ring_prev(p) - p, ring_next(p) - p
    angle = np.arctan2(w[:, 0] * u[:, 1] - w[:, 1] * u[:, 0], np.einsum("ij,ij->i", w, u)) % (2 * np.pi)
    return np.asarray(angle < np.radians(SHARP_CORNER))


def _balance(
    hv: FloatArray,
    t: FloatArray,
    fixed: NDArray[np.bool_],
    arc: FloatArray,
    total: float,
) -> FloatArray:
    """Algorithm 3 on arc length: each free node goes to the h-weighted mean (Eq. 3.3) of the
    midpoints of its two segments, until no node moves ``BALANCE_TOL * h``.  ``hv`` is h at the
    refined curve's vertices (arc lengths ``arc``), interpolated linearly between them."""
    free = ~fixed
    if not free.any():
        return t
    t = t.copy()
    for _ in range(tol.BALANCE_ITERATIONS):
        nxt = ring_next(t)
        nxt[-1] += total  # the segment from the last node back to the first
        mid = 0.5 * (t + nxt)  # midpoint of the segment after each node
        at = np.mod(mid, total)
        w = 1.0 / np.interp(at, arc, hv)
        before, w_before = ring_prev(mid), ring_prev(w)
        before[0] -= total
        new = (before * w_before + mid * w) / (w_before + w)  # Eq. 3.3
        move = np.abs(new - t)[free] * w[free]
        t[free] = new[free]
        if move.max() < tol.BALANCE_TOL:
            break
    return t


@dataclass(frozen=True)
class CurveMesh:
    """Nodes on the interior curves (regions' boundaries and user curves), piece by piece.

    Attributes
    ----------
    points : (nc, 2) array
        Curve nodes; junctions (where pieces end or cross) appear once.
    fixed : (nc,) bool array
        Junctions, corners and end points: they never move.
    edges : (k, 2) int array
        Segments, each oriented along its piece.
    edge_piece : (k,) int array
        Piece of each segment.
    node_piece : (nc,) int array
        Piece of each node (for a junction: the first piece through it).
    chains : tuple of (int array, bool)
        Each piece's nodes in order and whether it is closed (then the last joins the first).
    """

    points: FloatArray
    fixed: NDArray[np.bool_]
    edges: IntArray
    edge_piece: IntArray
    node_piece: IntArray
    chains: tuple[tuple[IntArray, bool], ...]


def mesh_curves(pieces: Sequence[Piece], h: SizeFn, diameter: float) -> CurveMesh:
    """Step 1 on interior curves: refine (Eq. 3.1, 3.2), lay ``round(S)`` segments at equal
    h-length between fixed vertices, balance (Eq. 3.3), exactly as on the boundary loops.

    Each piece projects onto its own curve.  A closed piece without a fixed vertex gets one
    anchor (its lowest-leftmost vertex), as a smooth boundary loop does.

    Parameters
    ----------
    pieces : sequence of :class:`~injmesh.geometry.regions.Piece`
    h : callable
        Validated size function.
    diameter : float
        The domain's diameter (scale of the tolerance that merges junctions).

    Returns
    -------
    CurveMesh
    """
    from scipy.spatial import cKDTree

    eps = 10 * tol.ON_BOUNDARY * diameter
    placed: list[tuple[FloatArray, NDArray[np.bool_], bool]] = []
    for piece in pieces:
        p, f = piece.points, piece.fixed.copy()
        if piece.closed:
            if not f.any():
                f[np.lexsort((p[:, 1], p[:, 0]))[0]] = True
            first = int(np.argmax(f))
            p, f = np.roll(p, -first, axis=0), np.roll(f, -first)
            p, f = np.concatenate([p, p[:1]]), np.r_[f, True]
        p, f, hp = _refine_open(piece.project, h, p, f)
        out, fixed = _select_open(piece.project, p, f, hp, piece.closed)
        placed.append((out, fixed, piece.closed))
    # Junctions shared by pieces become one node each.
    junction = np.concatenate([o[f] for o, f, _ in placed]) if placed else np.empty((0, 2))
    uniq = np.empty((0, 2))
    jid = np.zeros(len(junction), dtype=np.intp)
    if len(junction):
        tree = cKDTree(junction)
        rep = np.arange(len(junction))
        for i, j in sorted(tree.query_pairs(eps)):
            rep[j] = min(rep[j], rep[i])
        # Follow chains of representatives to their root.
        while np.any(rep[rep] != rep):
            rep = rep[rep]
        roots, jid = np.unique(rep, return_inverse=True)
        uniq = junction[roots]
    points = [uniq]
    fixed_all = [np.ones(len(uniq), dtype=bool)]
    node_piece = [np.full(len(uniq), -1, dtype=np.intp)]
    edges, edge_piece, chains = [], [], []
    n, jpos = len(uniq), 0
    for k, (out, fixed, closed) in enumerate(placed):
        ids = np.empty(len(out), dtype=np.intp)
        nf = int(fixed.sum())
        ids[fixed] = jid[jpos:jpos + nf]
        jpos += nf
        free = ~fixed
        ids[free] = n + np.arange(int(free.sum()))
        n += int(free.sum())
        points.append(out[free])
        fixed_all.append(np.zeros(int(free.sum()), dtype=bool))
        node_piece.append(np.full(int(free.sum()), k, dtype=np.intp))
        edges.append(np.stack([ids[:-1], ids[1:]], axis=1))
        edge_piece.append(np.full(len(ids) - 1, k, dtype=np.intp))
        chains.append((ids[:-1] if closed else ids, closed))
    npc = np.concatenate(node_piece)
    e = np.concatenate(edges) if edges else np.zeros((0, 2), dtype=np.intp)
    ep = np.concatenate(edge_piece) if edge_piece else np.zeros(0, dtype=np.intp)
    # Junctions belong to the first piece through them.
    first_piece = np.full(n, len(placed), dtype=np.intp)
    np.minimum.at(first_piece, e.ravel(), np.repeat(ep, 2))
    npc = np.where(npc < 0, first_piece, npc)
    return CurveMesh(np.concatenate(points), np.concatenate(fixed_all), e, ep, npc, tuple(chains))


def sharp_junctions(
    domain: Domain, h: SizeFn, pieces: Sequence[Piece], junctions: FloatArray
) -> tuple[FloatArray, tuple[Piece, ...]]:
    """Nodes held at equal distances from the tip on both walls of a sharp junction: where an
    interior curve leaves the domain's boundary at less than ``SHARP_CORNER`` degrees.

    The domain's own sharp corners are laid out so (:func:`_tip_graded`, :func:`_pin_wedges`),
    but at a junction the boundary wall and the curve are laid by Step 1 each on its own, and
    their first nodes came at different distances from the tip (a 20-degree wedge: 0.0075 and
    0.006, tip triangle q = 0.46 where the angle allows 0.57).  Here the distances are
    ``r_k = h(tip) g**k`` (``g = 1 + 2 sin(a / 2)``, the tip grading's factor) on both walls,
    held fixed like :func:`_pin_wedges`'s nodes while the walls are closer than ``PIN_WIDTH *
    h``, and at least the first: the tip triangle is then isosceles.  Only straight stretches
    are used: ``r_k`` stays below half of the curve's first polyline segment and of the
    distance to the nearest other junction or domain corner.

    Returns
    -------
    points : (k, 2) array
        Nodes on the boundary, to be held fixed like corners.
    pieces : tuple of Piece
        The pieces with the nodes on their walls added as fixed vertices.
    """
    from dataclasses import replace

    out_b: list[FloatArray] = []
    new_pieces = list(pieces)
    if len(junctions) == 0 or not pieces:
        return np.empty((0, 2)), tuple(new_pieces)
    diam = domain.diameter
    eps = 10 * tol.ON_BOUNDARY * diam
    corners = domain.corners().reshape(-1, 2)
    others = np.concatenate([corners, junctions])
    normal = domain.gradient(junctions)
    normal = normal / np.maximum(np.hypot(*normal.T), 1e-300)[:, None]
    for j, tip in enumerate(junctions):
        d_other = np.hypot(*(others - tip).T)
        d_other = d_other[d_other > eps]
        if np.any(np.hypot(*(corners - tip).T) <= eps):
            continue  # a domain corner: its walls' directions are not the gradient's
        room_b = 0.5 * float(d_other.min()) if len(d_other) else diam
        walls = _junction_walls(domain, tip, normal[j], min(0.25 * float(h(tip[None, :])[0]), 0.5 * room_b))
        for k, piece in enumerate(new_pieces):
            p = piece.points
            n = len(p)
            # The stretches leaving the tip: (vertex at the tip, its neighbour along the piece).
            ends = []
            for e in np.flatnonzero(np.hypot(*(p - tip).T) <= eps).tolist():
                for nb_ in (e - 1, e + 1):
                    if piece.closed and n > 2:
                        ends.append((e, nb_ % n))
                    elif 0 <= nb_ < n:
                        ends.append((e, nb_))
            inserts: list[tuple[int, FloatArray]] = []
            for e, nb_ in ends:
                seg = p[nb_] - p[e]
                length = float(np.hypot(*seg))
                if length <= eps:
                    continue
                t_c = seg / length
                w = walls[int(np.argmax(walls @ t_c))]
                a = float(np.arccos(min(1.0, float(w @ t_c))))
                # Along the wall (a tangent stretch the regions merge into it) the radii would
                # not grow: no tip to lay out.
                if not np.radians(JUNCTION_MIN_ANGLE) < a < np.radians(SHARP_CORNER):
                    continue
                g = 1.0 + 2.0 * np.sin(0.5 * a)
                room = min(0.5 * length, room_b)
                r = float(h(tip[None, :])[0])
                radii: list[float] = []
                while r < room and len(radii) < TIP_STEPS:
                    hr = float(np.min(h(np.stack([tip + r * w, tip + r * t_c]))))
                    if radii and r * np.sin(a) >= PIN_WIDTH * hr:
                        break
                    radii.append(r)
                    r *= g
                if not radii:
                    continue
                rr = np.asarray(radii)
                out_b.append(domain.project(tip + rr[:, None] * w))
                q = piece.project(tip + rr[:, None] * t_c)  # nearest the tip first
                # Between the vertex and its neighbour, in the piece's order: after the
                # vertex going forward, before it going back (a closed piece's vertex 0
                # going back to its last: after the last).
                if nb_ == e + 1 or piece.closed and (e, nb_) == (n - 1, 0):
                    inserts.append((e + 1, q))
                else:
                    inserts.append((e if e > 0 else n, q[::-1]))
            if not inserts:
                continue
            pts, fix = p, piece.fixed
            # Later positions first, so the earlier ones stay where they are.
            for at, rows in sorted(inserts, key=lambda x: -x[0]):
                pts = np.concatenate([pts[:at], rows, pts[at:]])
                fix = np.concatenate([fix[:at], np.ones(len(rows), dtype=bool), fix[at:]])
            new_pieces[k] = replace(piece, points=pts, fixed=fix)
    points = np.concatenate(out_b) if out_b else np.empty((0, 2))
    return points, tuple(new_pieces)


#: :func:`sharp_junctions` lays out the tips of junctions between JUNCTION_MIN_ANGLE and
#: SHARP_CORNER degrees.
JUNCTION_MIN_ANGLE = 1.0
#: :func:`_junction_walls` samples a circle round the junction at this many angles.
JUNCTION_RAYS = 720
#: ... and takes the boundary's crossings of it for the walls' directions where they are more
#: than this many degrees off the tangent of the boundary's gradient at the junction.
JUNCTION_TURN = 1.0


def _junction_walls(domain: Domain, tip: FloatArray, normal: FloatArray, rho: float) -> FloatArray:
    """The directions (2, 2) in which the boundary leaves the junction ``tip``: both ways along
    the tangent of its gradient ``normal``, unless the boundary turns there.

    A corner of the domain turning less than its corner angle is not among its corners, and
    its gradient is one wall's: a region's side leaving the boundary there at 14 degrees to the
    other wall was judged parallel to the first, its tip radii never grew, and 64 nodes were
    laid at one point (found by fuzzing).  Where the boundary crosses the circle of radius
    ``rho`` round the tip exactly twice, more than ``JUNCTION_TURN`` degrees off the tangent,
    the crossings' directions are the walls'.
    """
    wall_dir = np.array([-normal[1], normal[0]])
    tangent = np.stack([wall_dir, -wall_dir])
    if not rho > 0.0:
        return tangent
    theta = np.linspace(0.0, 2.0 * np.pi, JUNCTION_RAYS, endpoint=False)
    ring = tip + rho * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    d = domain.sdf(ring)
    nxt = np.roll(d, -1)
    change = np.flatnonzero((d < 0) != (nxt < 0))
    if len(change) != 2:
        return tangent
    # The zero between two samples, linearly (the sdf is a distance there).
    step = 2.0 * np.pi / JUNCTION_RAYS
    at = theta[change] + step * d[change] / (d[change] - nxt[change])
    dirs = np.stack([np.cos(at), np.sin(at)], axis=1)
    off = np.degrees(np.arccos(np.clip(np.max(dirs @ tangent.T, axis=1), -1.0, 1.0)))
    return dirs if np.any(off > JUNCTION_TURN) else tangent


def _refine_open(
    project: Callable[[FloatArray], FloatArray], h: SizeFn, p: FloatArray, fixed: NDArray[np.bool_]
) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """Algorithm 2 on an open polyline (the curve's own projection in Eq. 3.2); the refined
    polyline, its fixed vertices and h at its vertices (asked once per vertex, as in
    :func:`_refine`)."""
    hp = h(p)
    for _ in range(40):
        a, b = p[:-1], p[1:]
        ha, hb = hp[:-1], hp[1:]
        split = np.hypot(*(b - a).T) > tol.BOUNDARY_REFINE * np.minimum(ha, hb)
        if not split.any():
            break
        wa, wb = 1.0 / ha[split], 1.0 / hb[split]
        new = project((a[split] * wa[:, None] + b[split] * wb[:, None]) / (wa + wb)[:, None])
        key = np.concatenate([np.arange(len(p), dtype=float), np.flatnonzero(split) + 0.5])
        order = np.argsort(key, kind="stable")
        p = np.concatenate([p, new])[order]
        fixed = np.concatenate([fixed, np.zeros(len(new), dtype=bool)])[order]
        hp = np.concatenate([hp, h(new)])[order]
    return p, fixed, hp


def _select_open(
    project: Callable[[FloatArray], FloatArray],
    p: FloatArray,
    fixed: NDArray[np.bool_],
    hv: FloatArray,
    closed: bool,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """``round(S)`` segments at equal h-length between fixed vertices, balanced (Eq. 3.3) on
    arc length, as :func:`_select` does on a loop; ``p`` starts and ends at fixed vertices,
    ``hv`` is h at them."""
    seglen = np.hypot(*np.diff(p, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seglen)])
    total = float(arc[-1])
    s = np.concatenate([[0.0], np.cumsum(seglen / (0.5 * (hv[1:] + hv[:-1])))])
    fixed_idx = np.flatnonzero(fixed)
    s_start = s[fixed_idx[:-1]]
    span = s[fixed_idx[1:]] - s_start
    count = np.maximum(1, np.rint(span).astype(int))
    if closed and count.sum() < 3:  # a closed curve needs three nodes at least
        count[np.argmax(span)] += 3 - count.sum()
    piece = np.repeat(np.arange(len(count)), count)
    k = np.arange(len(piece)) - np.repeat(np.cumsum(count) - count, count)
    t = np.interp(s_start[piece] + k * span[piece] / count[piece], s, arc)
    t = np.r_[t, total]
    is_fixed = np.r_[k == 0, True]
    t[is_fixed] = arc[fixed_idx]
    t = _balance(hv, t, is_fixed, arc, total)
    out = np.stack([np.interp(t, arc, p[:, 0]), np.interp(t, arc, p[:, 1])], axis=1)
    out[is_fixed] = p[fixed_idx]
    free = ~is_fixed
    if free.any():
        out[free] = project(out[free])  # Eq. 3.2, onto the curve itself
    return out, is_fixed
