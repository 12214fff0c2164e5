"""Step 2 of Algorithm 1: Advancing Node Injection (paper Section 3.1, Algorithm 4).

Interior nodes are injected layer by layer from the boundary front inwards; no triangulation is
built.  The front is a set of *chains*: polylines of nodes with the unmeshed region on their left
(the boundary loops to begin with).  One layer does, for all chains at once:

1. **Inject.**  Every front edge e gives the apex of the equilateral triangle on its inner side:
   its midpoint moved by ``sqrt(3)/2 * h`` along the inward normal, h taken at the apex.  At a
   front vertex whose interior angle theta exceeds 180 degrees the two apexes drift apart, so
   ``m = round((theta - 120) / 60) - 1`` more points are injected on the arc of radius h around
   the vertex (the paper's "angles between e_i and the previous and the next edges").  At convex
   vertices the apexes draw together and the next step merges them.
2. **Space along the front.**  The injected points of a chain, in order, form the new chain.  It
   is re-laid at equal h-length, ``round(int ds / h)`` segments (closed chains keep at least
   three; a closed chain shorter than 2.5 h collapses to its centroid).  A straight front with
   constant h is left exactly as injected (the staggered, equilateral layout); the strips' rings
   keep their points (see below).
3. **Merge fronts.**  A new point is rejected when it is outside the domain (``d > 0``), or
   closer than ``MERGE * h`` to any existing node (earlier layers, other fronts, the boundary), or
   to a lower-numbered point of the same layer.  This is how fronts that meet — across a narrow
   part, around holes, at re-entrant corners, where h changes fast — stop without clusters;
   gaps left are below about ``(MERGE + sqrt(3)/2) h`` wide and smoothing closes them.
4. **Advance.**  The surviving runs of consecutive points are the next front.

**Strips first, then a lattice, where h is the same on every loop.**  Interior curves
(regions' boundaries, cracks; ``inject_nodes``' ``curves``) are fronts facing both ways.
Advanced all together to the end (the rule otherwise), fronts grown from a circle are rings
whose node count changes every layer, re-laid each time at equal spacing: rows out of step
all round, and seams where they meet that relaxed for a hundred smoothing steps.  So when h
at the nodes of every loop (boundary and curves) is within ``STAGED_SPREAD`` (10 %) of its
smallest value (a uniform h, or one graded away from every wall alike):

* if the outer loops are mostly straight (half their nodes turning less than
  ``STRAIGHT_TURN``), the holes and the curves that do not meet the boundary advance
  ``INNER_LAYERS`` (2) layers first, a strip of two rows along each side, and then the outer
  loops' fronts fill the domain up to those strips: along straight walls they lay a lattice
  themselves;
* if they are curved, their fronts are rings as well, so every loop only lays its strip;

then what no front reached is filled with the equilateral lattice, if h is uniform over all
of it (within ``UNIFORM_H`` of the lattice's spacing at every lattice point inside: a band of
lattice where h happens to match would wall the rest in), and the strips' fronts resume to
fill whatever is left (all of it where h is not uniform).  Measured at 1e5 nodes
(``benchmarks/regions.py``), the unit square with two circular inclusions and a crack: 125
-> 50 smoothing steps, q_min 0.823 -> 0.882, q_mean 0.9896 -> 0.9983; with the same circles
as holes 128 -> 47 steps, q_mean 0.9928 -> 0.9989, 0.80 -> 0.42 s.  A disc at h = 0.005
(146,000 nodes): 209 -> 47 steps, 2.2 -> 0.62 s, q_mean 0.979 -> 0.9995, q_min 0.789 ->
0.829; an annulus (123,000): 233 -> 48 steps, 2.2 -> 0.59 s, q_mean 0.981 -> 0.999.  The
NACA 0012 in a box of ``benchmarks/robustness.py --real`` (h = 0.01 + 0.3 d on both loops)
q_min 0.679 -> 0.733.  (Staging the holes inside a curved outer wall whose fronts then ran
to the end gained nothing: an annulus lost 0.002 of q_mean.)  Where h differs between loops
the fronts all advance together, as before: fronts from a fine loop lay the grading as they
go out, while a coarse front arriving at a fine strip does not (staged, the paper's square
with a hole at 2h took 209 steps against 114); the paper's cases, whose h differs between
their loops, are unchanged, and so is a disc graded 20:1 from its centre (its h is the same
on its one loop, but no lattice suits its interior).  Curves that meet the boundary (a crack
from a wall, a region's side on it) always advance with the outer front: in the wedge
between a wall and a curve leaving it the two fronts must meet as at a corner (a crack
leaving a wall at 15 degrees got a triangle of q 0.389 next to its tip when staged, 0.446
otherwise).

**The strips' rings stay in step.**  A ring's injected layer is in step with the layer
before (each point the apex over one of its edges), but it needs a few points more (going
out) or fewer (going in) than it has: re-laid uniformly (step 2), it slipped out of step by
that many spacings, a little at every point, and smoothing then moved the strips' nodes
0.15-0.18 h sideways on average (0.07-0.09 h now, on the 1e5-node square with two
inclusions of ``benchmarks/regions.py``).  So the strips' layers keep their injected points
and take up the points gained or lost in a few windows of at most ``RING_WINDOW`` segments,
where the slip builds (evenly round a ring, at a crack's ends), each re-laid at equal
spacing (:func:`~injmesh.kernels.inject.relay`); a chain too short for such windows is
re-laid uniformly, as are the layers of every other front.

After the last layer, **gaps the fronts never reached are filled** (:func:`_fill_gaps`): fronts
from a crinkled outline break into short runs that die before they meet, and the equilateral
lattice of h over the cells they left empty is offered to the same admission test.  Where the
fronts fill the domain (every case of the paper) nothing is added.

The proximity tests of step 3 run on a background grid of about h_min cells that every
admitted node is inserted into as it is admitted (:mod:`injmesh.kernels.inject`): nothing is
rebuilt per layer, so the whole injection is linear in the number of nodes.  The wall test
measures the exact distance to the boundary segments of Step 1 listed in the nearby cells.

*Stopping condition*: a layer in which no point survives (the front is exhausted), or
``2 * diameter / (sqrt(3)/2 * h_min) + 10`` layers, h_min the smallest h met so far (on the
boundary or at an admitted node).  A front advances by about ``sqrt(3)/2 * h`` per layer, so a
cap from the boundary's h alone stopped fronts short of the places where h is smaller inside:
on a disc with h growing 20:1 from its centre to its rim (1e5 nodes) a hole about 15 h_min
wide was left at the centre, and the smoothing did not converge in 1000 steps (a node in
the hole, pulled by every neighbour, swung across it at each step).

h is asked only at points inside the domain or on its boundary: a candidate beyond the boundary
(an apex past the opposite wall, the midpoint of a chord across a notch) takes h at its
projection onto the boundary.  DistMesh users write h that is meaningless, even negative,
outside the domain.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .boundary import BoundaryMesh
from .errors import NodeBudgetError
from .geometry import Domain
from .progress import Callback, report

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]
SizeFn = Callable[[FloatArray], FloatArray]

#: Layer height as a fraction of h: the height of the equilateral triangle.
HEIGHT = np.sqrt(3.0) / 2.0
#: A new node closer than MERGE * h to an existing one is not injected.
MERGE = 0.6
#: A new node closer than CLEARANCE * h to a boundary segment is not injected.
CLEARANCE = 0.5
#: Most cells of the proximity grid (16 MiB of list heads).
MAX_CELLS = 1 << 21
#: Angle (degrees) between injected points on the arc around a reflex front vertex.
FAN_STEP = 60.0


class Front:
    """Chains of front nodes, stored contiguously.

    ``points[i]`` is followed by ``points[i + 1]`` within a chain; ``start[c]:start[c + 1]`` is
    chain c, ``closed[c]`` says whether its last node joins its first.
    """

    def __init__(self, points: FloatArray, lengths: IntArray, closed: BoolArray) -> None:
        self.points = points
        self.lengths = lengths
        self.closed = closed
        self.start = np.concatenate([[0], np.cumsum(lengths)])
        self.chain = np.repeat(np.arange(len(lengths)), lengths)

    def __len__(self) -> int:
        return len(self.points)


def inject_nodes(
    domain: Domain,
    h: SizeFn,
    boundary: BoundaryMesh,
    existing: FloatArray,
    *,
    max_nodes: int,
    callback: Callback | None = None,
    curves: BoundaryMesh | None = None,
    attached: BoundaryMesh | None = None,
) -> FloatArray:
    """Inject interior nodes by advancing fronts from the boundary (Algorithm 4).

    Parameters
    ----------
    domain : Domain
    h : callable
        Validated size function.
    boundary : BoundaryMesh
        Step 1's result; its loops are the initial front.
    existing : (k, 2) array
        Nodes already placed (boundary nodes, interior curves' nodes and user fixed points);
        new nodes keep clear of them.
    max_nodes : int
        Node budget.
    curves : BoundaryMesh, optional
        Interior curves that do not meet the boundary (regions' boundaries, free cracks), as
        loops facing the way their front advances (a closed curve twice, one each way; see
        ``pipeline._curve_front``).  Where h is the same on every loop they go first with the holes (the
        module documentation); new nodes keep clear of their segments as of the boundary's.
    attached : BoundaryMesh, optional
        Interior curves that meet the boundary, as loops: they advance with the outer loops.

    Returns
    -------
    (n, 2) array
        The injected nodes only, in injection order.
    """
    loops = boundary
    for more in (attached, curves):
        if more is not None:
            loops = _joined(loops, more)
    h_bnd = h(loops.points)
    h_min = float(h_bnd.min())
    n_loop = len(loops.points)
    h_existing = np.concatenate([h_bnd, h(existing[n_loop:])]) if _starts_with(
        existing, loops.points) else h(existing)
    grid = _Proximity(domain, loops, existing, h_existing, h_min)
    run = _Advance(domain, h, grid, len(existing), max_nodes, callback)
    # Inner loops (holes, curves inside) go first only where h is the same on every loop:
    # where it differs, fronts advancing from the finer loops outwards lay the grading as
    # they go, and a coarse front arriving at a fine strip does not.
    inner = _no_loops()
    if len(h_bnd) > 0 and float(h_bnd.max()) <= (1.0 + STAGED_SPREAD) * h_min:
        outer, holes = _split_holes(boundary)
        # A curved outer wall's fronts are rings too: then every loop lays its strip.
        boundary, inner = (outer, holes) if _straight(outer) else (_no_loops(), boundary)
        if curves is not None:
            inner = _joined(inner, curves)
    elif curves is not None:
        boundary = _joined(boundary, curves)
    if attached is not None:
        boundary = _joined(boundary, attached)
    if len(inner.points) == 0:
        run(_loops_front(boundary), None)
    else:
        rest = run(_loops_front(inner), INNER_LAYERS, RING_WINDOW)
        run(_loops_front(boundary), None)
        # What the outer fronts do not reach (inside an inclusion, inside a curved wall): the
        # lattice where h is uniform, the strips' own fronts where it is not.
        run.add(_fill_gaps(domain, h, grid, uniform=True), "filling what the strips left")
        run(rest, None)
    # Fronts from a crinkled outline break into short runs that die before they meet: fill
    # what they left empty.
    run.add(_fill_gaps(domain, h, grid), "filling gaps")
    # The layer count is not known in advance: close the progress at 100 %.
    report(callback, "injection", run.layer + 1, run.layer + 1, nodes=run.n_placed, front=0)
    return np.concatenate(run.placed) if run.placed else np.empty((0, 2))


#: Layers the holes' and inner curves' fronts advance before the outer loops' fill the
#: domain, where h is the same on every loop (``inject_nodes``).  Measured on a 1e5-node unit square with two
#: circular inclusions and a crack (``benchmarks/regions.py``), all fronts together: 125
#: smoothing steps, q_min 0.823, q_mean 0.9896, 1.28 s; 1, 2, 3 layers: 48 / 50 / 52 steps,
#: q_min 0.882 / 0.882 / 0.876, q_mean 0.9984 / 0.9983 / 0.9980, about 0.66 s.  Two give a
#: strip of two rows on each side of an interface.
INNER_LAYERS = 2
#: ... when h at every loop's nodes is within this fraction of the smallest.
STAGED_SPREAD = 0.1
#: The strips' layers (``INNER_LAYERS``) keep their rings in step: each layer keeps its
#: injected points (the apexes over the layer before) and takes up the points it gains or
#: loses in windows of at most RING_WINDOW segments where the slip builds
#: (:func:`~injmesh.kernels.inject.relay`), instead of being re-laid uniformly, which put its
#: rows out of step with the layer before all round.  Measured, uniform -> windows of 12: the
#: 1e5-node square with two inclusions and a crack (``benchmarks/regions.py``) 50 -> 45
#: smoothing steps, 1.32x -> 1.20x the plain square's time (which is unchanged: its walls are
#: straight, its own fronts are not windowed), the two regions alone 1.26x -> 1.17x, the same
#: circles as holes 0.94x -> 0.92x; at 1e6 nodes 1.25x -> 1.15x and 1.20x -> 1.16x; a plate
#: with 5 x 5 holes at h = 0.005 0.287 -> 0.267 s; an annulus at h = 0.005 0.558 -> 0.538 s,
#: q_min 0.829 -> 0.895; a disc 0.595 -> 0.567 s, q_min 0.829 -> 0.878.  Windows of 6 to 24
#: segments gave the same times (q_min at 1e5 0.866-0.890; 12: 0.890).  Only the strips:
#: every front windowed (the paper's cases) moved their q_min both ways by up to 0.08, and the
#: strips' fronts resuming on a graded h (a disc graded 20:1) did not converge in 1000 steps.
RING_WINDOW = 12
#: Outer loops with at least half their nodes turning less than this (radians) lay a lattice
#: with their own fronts, and only the holes and inner curves go first; otherwise every loop
#: lays its strip and the lattice fills the rest (see the module documentation).
STRAIGHT_TURN = 1e-3


def _loops_front(loops: BoundaryMesh) -> Front:
    """Closed chains of a boundary mesh's loops (numbered from 0, contiguous)."""
    counts = np.bincount(loops.node_loop - loops.node_loop.min(initial=0))
    counts = counts[counts > 0]
    return Front(loops.points, counts, np.ones(len(counts), dtype=bool))


def _no_loops() -> BoundaryMesh:
    return BoundaryMesh(np.empty((0, 2)), np.empty((0, 2), dtype=np.intp), np.empty(0, dtype=np.intp),
                        np.empty(0, dtype=bool))


def _straight(loops: BoundaryMesh) -> bool:
    """Whether most nodes of ``loops`` lie on straight stretches (turning less than
    ``STRAIGHT_TURN``): there the outer fronts lay a lattice that the inner loops' strips can
    wait for (see ``inject_nodes``)."""
    p, e = loops.points, loops.edges
    if len(e) == 0:
        return False
    d = p[e[:, 1]] - p[e[:, 0]]
    nxt = np.empty(len(p), dtype=np.intp)
    nxt[e[:, 0]] = np.arange(len(e))
    prv = np.empty(len(p), dtype=np.intp)
    prv[e[:, 1]] = np.arange(len(e))
    a, b = d[prv[e[:, 0]]], d[nxt[e[:, 0]]]
    turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b)))
    return bool(np.mean(turn < STRAIGHT_TURN) >= 0.5)


def _split_holes(b: BoundaryMesh) -> tuple[BoundaryMesh, BoundaryMesh]:
    """The loops of ``b`` that bound the domain from outside (counter-clockwise) and the holes."""
    p, e = b.points, b.edges
    cross = p[e[:, 0], 0] * p[e[:, 1], 1] - p[e[:, 1], 0] * p[e[:, 0], 1]
    hole = np.bincount(b.node_loop[e[:, 0]], weights=cross)[b.node_loop] < 0

    def sub(sel: NDArray[np.bool_]) -> BoundaryMesh:
        idx = np.flatnonzero(sel)
        inv = np.full(len(p), -1)
        inv[idx] = np.arange(len(idx))
        es = e[sel[e[:, 0]]]
        return BoundaryMesh(p[idx], inv[es], b.node_loop[idx], b.fixed[idx])
    return sub(~hole), sub(hole)


def _joined(a: BoundaryMesh, b: BoundaryMesh) -> BoundaryMesh:
    """Two boundary meshes as one (``b``'s nodes, edges and loops after ``a``'s)."""
    shift = int(a.node_loop.max(initial=-1)) + 1 - int(b.node_loop.min(initial=0))
    return BoundaryMesh(np.concatenate([a.points, b.points]),
                        np.concatenate([a.edges, b.edges + len(a.points)]),
                        np.concatenate([a.node_loop, b.node_loop + shift]),
                        np.concatenate([a.fixed, b.fixed]))


class _Advance:
    """Layers of Algorithm 4 from a front, on one proximity grid shared by every front
    (``inject_nodes``); ``placed`` collects the nodes admitted, in order."""

    def __init__(self, domain: Domain, h: SizeFn, grid: _Proximity, n_existing: int, max_nodes: int,
                 callback: Callback | None) -> None:
        self.domain, self.h, self.grid, self.max_nodes, self.callback = domain, h, grid, max_nodes, callback
        self.placed: list[FloatArray] = []
        self.n_placed = n_existing
        self.layer = 0

    def add(self, points: FloatArray, where: str) -> None:
        """Take the admitted ``points``, within the node budget."""
        if not len(points):
            return
        self.placed.append(points)
        self.n_placed += len(points)
        if self.n_placed > self.max_nodes:
            raise NodeBudgetError(f"node injection passed max_nodes={self.max_nodes} ({where})")

    def __call__(self, front: Front, layers: int | None, window: int = 0) -> Front:
        """Advance ``front`` until it is exhausted, or ``layers`` layers; the front left.
        ``window``: see :func:`_respace`."""
        domain, h, grid = self.domain, self.h, self.grid
        max_layers = _layer_cap(domain, grid.h_min)
        done = 0
        while done < max_layers and (layers is None or done < layers) and len(front):
            done += 1
            self.layer += 1
            cand = _inject(front, domain, h)
            cand = _respace(cand, domain, h, window)
            keep = _admissible(domain, h, cand.points, grid)
            if not keep.any():
                return _survivors(cand, keep)
            max_layers = _layer_cap(domain, grid.h_min)
            front = _survivors(cand, keep)
            self.add(front.points, f"layer {self.layer}")
            # Progress against the layers the smallest h so far would need (the cap is twice that).
            report(self.callback, "injection", self.layer, max(self.layer + 1, max_layers // 2),
                   nodes=self.n_placed, front=len(front))
            front = _drop_isolated(front)
        return front


#: Gap filling: levels of lattice spacing from the largest h admitted down to that divided by
#: FILL_LEVELS halvings (not below the smallest h), and at most FILL_CELLS cells per level.
FILL_LEVELS = 5
FILL_CELLS = 1 << 22
#: A lattice point is a candidate where h is at least FILL_H times the lattice spacing (and
#: below twice that after the first level), in cells whose nearest node has h below FILL_NEAR
#: times that.
FILL_H = 0.75
FILL_NEAR = 4.0
#: The lattice that fills what the strips left (``inject_nodes``) is laid only where h is
#: within this fraction of its spacing s everywhere.
UNIFORM_H = 0.05
#: Each row of a gap-filling lattice is shifted along x by this fraction of s times its row
#: number: exactly, rows r and r + 2 line up and every rectangle of four lattice points is
#: cocircular, which sends the first triangulation's incircle tests to their exact stage (the
#: 1e5-node square with two inclusions, whose insides are lattices: 0.230 -> 0.191 s).  At
#: most 2e-3 s over the rows a level can have (``FILL_CELLS``).
LATTICE_SHEAR = 1e-6


def _fill_gaps(domain: Domain, h: SizeFn, grid: _Proximity, uniform: bool = False) -> FloatArray:
    """Nodes for the parts of the domain the fronts did not reach.

    A front advancing from a crinkled outline (a fractal coastline with vertices h/40 apart)
    breaks into short open chains that erode from their ends and die within a few layers; on
    the 20,000-vertex outline they left 80 % of the interior empty, and smoothing, stretching
    the few nodes over it, swung at its step cap for 1000 steps.  After the layers, for lattice
    spacings s from the largest h admitted down by halvings: a cell of side s is *deep empty*
    when it and its eight neighbours hold no node; the equilateral lattice of spacing s over
    the empty cells next to deep-empty ones is offered, in row order, where h is between
    ``FILL_H * s`` and twice that (any larger h at the first level), to the same admission
    test as injected nodes (inside, clear of the boundary and of every node by ``MERGE * h``).
    Gaps the fronts leave where they meet are narrower than two h and hold no deep-empty cell,
    so a domain the fronts fill gets nothing here.

    Outside the domain every cell is empty, so each level would offer the lattice over the
    whole exterior of the bounding box: 4x more points per halving, 97 % of the 575,000 at the
    last level of the 20,000-vertex outline, and their sdf cost more than the rest of the
    injection.  For an exact distance (1-Lipschitz) a lattice point farther outside than a
    cell's diagonal puts its whole cell outside, and so the four cells of the next level in
    it: those are never offered again.
    """
    from .kernels.inject import fill_census

    x0, y0, x1, y1 = (float(v) for v in domain.bbox)
    s = grid.h_max
    out: list[FloatArray] = []
    exact = getattr(domain, "exact_distance", False) is True
    before: NDArray[np.bool_] | None = None  # cells of the previous level wholly outside
    for level in range(1 if uniform else FILL_LEVELS + 1):
        first = level == 0
        if not (s > 0 and math.isfinite(s)) or s < grid.h_min:
            break
        nx, ny = int((x1 - x0) / s) + 1, int((y1 - y0) / s) + 1
        if nx * ny > FILL_CELLS:
            break
        if before is None:
            outside = np.zeros((ny, nx), dtype=bool)
        else:
            # This level's cell (j, i) lies in the previous level's cell (j // 2, i // 2).
            py = np.minimum(np.arange(ny) // 2, before.shape[0] - 1)
            px = np.minimum(np.arange(nx) // 2, before.shape[1] - 1)
            outside = before[np.ix_(py, px)]
        # Empty cells next to deep-empty ones (compiled: 18 passes over the grid in NumPy).
        occupied, cells, cell_h, n_deep, n_near = fill_census(
            grid.pts[: grid.n], grid.hs[: grid.n], x0, y0, s, nx, ny, np.ascontiguousarray(outside))
        if n_deep:
            if not first and cells.any():
                # Only where the nearest node's h suits this spacing: a coarser level has
                # already offered its lattice where h is larger (most of a fine level's empty
                # cells, between nodes far apart), and sdf and h need not be asked there.
                limit = FILL_NEAR * FILL_H * s
                if cells.size >= FILL_SEARCH_CELLS and n_near > FILL_NEAR_SHARE * np.count_nonzero(cells):
                    below, unsettled = _near_small_h(occupied, cell_h, cells, limit)
                else:
                    below, unsettled = np.zeros_like(cells), cells.copy()
                if np.count_nonzero(unsettled) * FILL_FEW > unsettled.size:
                    # Many: the distance transform costs less than their sdf (a detailed
                    # outline's sdf can cost ~1 us per point, the transform ~0.1 us per cell).
                    below |= _near_small_h_edt(occupied, cell_h, unsettled, limit)
                    unsettled[:] = False
                if exact and unsettled.any():
                    # Cells far from every node are mostly far outside the domain (the corners
                    # of a disc's box): a cell whose centre is farther outside than its
                    # diagonal lies wholly outside, offers nothing and never will.
                    uj, ui = np.nonzero(unsettled)
                    centre = np.stack([x0 + (ui + 0.5) * s, y0 + (uj + 0.5) * s], axis=1)
                    gone = domain.sdf(centre) > s
                    outside[uj[gone], ui[gone]] = True
                    unsettled[uj[gone], ui[gone]] = False
                    cells &= ~outside
                if unsettled.any():
                    # The others matter only if one of their lattice points would be a node
                    # of this level (inside, h in its range); then, and only then, the whole
                    # level's distance transform decides.
                    q, _ = _lattice(unsettled, x0, y0, y1, s)
                    if _suited(domain, h, q, s, first)[0].any():
                        below |= _near_small_h_edt(occupied, cell_h, unsettled, limit)
                cells &= below
            q, (cy, i) = _lattice(cells, x0, y0, y1, s)
            if len(q):
                inside, hq, d = _suited(domain, h, q, s, first)
                if uniform:
                    # The lattice only where h is uniform over all that is left: a band of it
                    # would wall in the rest from the fronts that resume (a graded disc, its
                    # loop staged: 10,278 nodes for 1e5).
                    if np.any((d < 0) & (np.abs(hq - s) > UNIFORM_H * s)):
                        return np.empty((0, 2))
                    inside &= np.abs(hq - s) <= UNIFORM_H * s
                if exact:
                    far = d > math.sqrt(2.0) * s
                    outside[cy[far], i[far]] = True
                keep = grid.admit(q, hq, inside)
                if keep.any():
                    out.append(q[keep])
        before = outside
        s *= 0.5
    return np.concatenate(out) if out else np.empty((0, 2))


def _lattice(cells: NDArray[np.bool_], x0: float, y0: float, y1: float,
             s: float) -> tuple[FloatArray, tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """The equilateral lattice of spacing s over the flagged cells (origin ``(x0, y0)``).

    Rows sqrt(3)/2 s apart, odd rows shifted by s/2 (row r by ``LATTICE_SHEAR * r * s`` more):
    point i of row r is in cell column i, row floor((y_r - y0) / s).  Listed row by row, in x
    order.  Returns the points ``(m, 2)`` and the row and column of each one's cell.
    """
    ny = cells.shape[0]
    rows = np.arange(int((y1 - y0) / (HEIGHT * s)) + 1)
    ys = y0 + rows * HEIGHT * s
    cy = np.floor((ys - y0) / s).astype(np.int64)
    rows = rows[cy < ny]
    r, i = np.nonzero(cells[cy[rows]])
    r = rows[r]
    return np.stack([x0 + (i + 0.5 * (r % 2) + LATTICE_SHEAR * r) * s, ys[r]], axis=1), (cy[r], i)


def _suited(domain: Domain, h: SizeFn, q: FloatArray, s: float,
            first: bool) -> tuple[BoolArray, FloatArray, FloatArray]:
    """Which lattice points of spacing s may be nodes (inside, h suits s), their h (1 where
    not inside) and their signed distance."""
    d = domain.sdf(q)
    inside = d < 0
    hq = np.ones(len(q))
    if inside.any():
        hq[inside] = h(q[inside])
    # This level's spacing suits h in [FILL_H s, 2 FILL_H s); the first level also takes any
    # larger h (h there is above every h admitted so far).
    inside &= (hq >= FILL_H * s) & ((hq < 2.0 * FILL_H * s) | first)
    return inside, hq, d


#: Gap filling's search for each empty cell's nearest occupied cell: on levels of at least
#: FILL_SEARCH_CELLS cells (on smaller ones the transform costs a few ms), when more than
#: FILL_NEAR_SHARE of the cells to decide touch an occupied cell (else they are mostly far from
#: every node, and a distance transform of the whole level is cheaper), rings of cells up to
#: FILL_RINGS[0] around each, then up to FILL_RINGS[1] if at most 1 / FILL_FEW of the level's
#: cells are left; the transform decides the rest.  A ring search visits cells about ten
#: times faster than the transform works per cell.
FILL_RINGS = (3, 8)
FILL_SEARCH_CELLS = 1 << 19
FILL_NEAR_SHARE = 0.2
FILL_FEW = 256
#: ... and a sample of every FILL_SAMPLE-th cell predicts whether it is so.
FILL_SAMPLE = 16


def _near_small_h(occupied: NDArray[np.bool_], cell_h: FloatArray, cells: NDArray[np.bool_],
                  limit: float) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Which of the ``cells`` have a nearest occupied cell whose ``cell_h`` is below ``limit``.

    Most cells are settled by a search of a few rings of cells round each
    (:func:`injmesh.kernels.inject.nearest_occupied_below`); the others -- far from every
    node, or nearest to several that disagree -- are returned as unsettled, for the caller to
    drop if they lie outside the domain, or to pass to :func:`_near_small_h_edt`.

    Returns
    -------
    below, unsettled : (ny, nx) bool arrays
    """
    from .kernels.inject import nearest_occupied_below

    occ = np.ascontiguousarray(occupied)
    out = np.zeros_like(cells)
    unsettled = cells.copy()
    cj, ci = np.nonzero(cells)
    if len(cj) >= FILL_SAMPLE * FILL_FEW:
        # Every FILL_SAMPLE-th cell first: if too many would be left unsettled, the transform
        # decides them all, and the search would be spent for nothing (the 1e5-node graded
        # disc's finest level: 20 % of a million cells far from every node, 0.14 s).
        cj, ci = cj[::FILL_SAMPLE].astype(np.int64), ci[::FILL_SAMPLE].astype(np.int64)
        _, settled = nearest_occupied_below(occ, cell_h, cj, ci, float(limit), FILL_RINGS[0])
        if (len(cj) - int(np.count_nonzero(settled))) * FILL_SAMPLE * FILL_FEW > cells.size:
            return out, unsettled
    for rings in FILL_RINGS:
        cj, ci = np.nonzero(unsettled)
        below, settled = nearest_occupied_below(occ, cell_h, cj.astype(np.int64), ci.astype(np.int64),
                                                float(limit), rings)
        out[cj, ci] = below & settled
        unsettled[cj[settled], ci[settled]] = False
        if (len(cj) - int(np.count_nonzero(settled))) * FILL_FEW > cells.size:
            break
    return out, unsettled


def _near_small_h_edt(occupied: NDArray[np.bool_], cell_h: FloatArray, cells: NDArray[np.bool_],
                      limit: float) -> NDArray[np.bool_]:
    """:func:`_near_small_h` by the Euclidean distance transform of the whole level."""
    from scipy import ndimage

    _, (jj, ii) = ndimage.distance_transform_edt(~occupied, return_indices=True)
    return cells & (cell_h[jj, ii] < limit)


def _layer_cap(domain: Domain, h_min: float) -> int:
    """Most layers: twice the domain's diameter in layer heights of the smallest h met."""
    return int(2.0 * domain.diameter / (HEIGHT * h_min)) + 10


def _starts_with(a: FloatArray, b: FloatArray) -> bool:
    """Whether the rows of ``b`` are the first rows of ``a`` (the boundary nodes among the seeds)."""
    return len(a) >= len(b) and np.array_equal(a[: len(b)], b)


def _h_inside(domain: Domain, h: SizeFn, q: FloatArray) -> FloatArray:
    """h at ``q``, taken at the boundary projection for points outside the domain."""
    value = getattr(h, "constant", None)
    if value is not None:  # a constant h needs no domain query (one per call saved)
        return np.full(len(q), float(value))
    out = domain.sdf(q) > 0
    if out.any():
        q = q.copy()
        q[out] = domain.project(q[out])
    return h(q)


def _inject(front: Front, domain: Domain, h: SizeFn) -> Front:
    """Apexes of the front edges plus arc points at reflex vertices, as new chains."""
    from .kernels.inject import front_edges, interleave

    p = front.points
    first, mid, normal, fan_node, fan_angle = front_edges(p, front.start.astype(np.int64), front.closed,
                                                          FAN_STEP)
    hm = _h_inside(domain, h, mid)
    apex = mid + HEIGHT * hm[:, None] * normal
    # Re-evaluate h at the apex so layers thin out or thicken with h.
    ha = 0.5 * (hm + _h_inside(domain, h, apex))
    apex = mid + HEIGHT * ha[:, None] * normal
    hv = h(p[fan_node])
    fan = p[fan_node] + hv[:, None] * np.stack([np.cos(fan_angle), np.sin(fan_angle)], axis=1)
    pts, lengths = interleave(front.chain.astype(np.int64), len(front.lengths), first, apex, fan_node, fan)
    return Front(pts, lengths, front.closed.copy())


def _respace(front: Front, domain: Domain, h: SizeFn, window: int = 0) -> Front:
    """Re-lay every chain at equal h-length, ``round(S)`` segments (Step 2 of the module doc);
    with ``window``, closed chains keep their points and take up the change in windows
    (``RING_WINDOW``, :func:`~injmesh.kernels.inject.relay`)."""
    from .kernels.inject import chain_polylines, relay

    front = _drop_empty(front)
    if len(front) == 0:
        return front
    start = front.start.astype(np.int64)
    # Polyline per chain with the closing vertex repeated for closed chains.
    poly, pchain = chain_polylines(front.points, start, front.closed)
    same = pchain[1:] == pchain[:-1]
    seg = poly[1:] - poly[:-1]
    ds = np.where(same, np.hypot(*seg.T) / _h_inside(domain, h, 0.5 * (poly[1:] + poly[:-1])), 0.0)
    out, count, closed = relay(poly, pchain, ds, front.closed, front.points, start, window)
    return Front(out, count, closed)


class _Proximity:
    """The nodes placed so far and the boundary segments, on a background grid (compiled).

    Cells are about the smallest boundary h wide (at most ``MAX_CELLS`` of them over the
    domain's box, so a tiny h in a large box makes cells coarser, not the grid huge).  Nodes
    are inserted layer by layer into per-cell lists, never rebuilt; see
    :mod:`injmesh.kernels.inject`.  Each node keeps the h it was admitted with, so the merge
    test needs no further evaluation of h.
    """

    def __init__(self, domain: Domain, boundary: BoundaryMesh, existing: FloatArray,
                 h_existing: FloatArray, h_min: float) -> None:
        from .kernels import inject as kern

        self.kern = kern
        x0, y0, x1, y1 = (float(v) for v in domain.bbox)
        lo = np.minimum([x0, y0], existing.min(axis=0)) if len(existing) else np.array([x0, y0])
        hi = np.maximum([x1, y1], existing.max(axis=0)) if len(existing) else np.array([x1, y1])
        w, ht = float(hi[0] - lo[0]), float(hi[1] - lo[1])
        cell = max(h_min, math.sqrt(max(w * ht, 0.0) / MAX_CELLS), 1e-12 * max(w, ht, 1e-300))
        self.cell = cell
        self.nx = int(w / cell) + 1
        self.ny = int(ht / cell) + 1
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.head = np.full(self.nx * self.ny, -1, dtype=np.int64)
        cap = max(1024, 2 * len(existing))
        self.pts = np.empty((cap, 2))
        self.hs = np.empty(cap)
        self.link = np.empty(cap, dtype=np.int64)
        self.n = len(existing)
        self.pts[: self.n] = existing
        self.hs[: self.n] = h_existing
        self.h_max = float(h_existing.max()) if len(existing) else 0.0
        #: The smallest h of the nodes admitted so far (bounds the layer count).
        self.h_min = h_min
        kern.insert(self.pts, 0, self.n, self.head, self.link, self.x0, self.y0, 1.0 / cell,
                    self.nx, self.ny)
        e = boundary.edges
        self.seg_a = np.ascontiguousarray(boundary.points[e[:, 0]])
        self.seg_b = np.ascontiguousarray(boundary.points[e[:, 1]])
        self.rows, self.items = kern.segment_lists(self.seg_a, self.seg_b, self.x0, self.y0, cell,
                                                   self.nx, self.ny)

    def admit(self, q: FloatArray, hq: FloatArray, inside: BoolArray) -> BoolArray:
        """Which candidates survive (Step 3 of the module doc); the survivors are inserted."""
        need = self.n + len(q)
        if need > len(self.pts):
            cap = max(need, 2 * len(self.pts))
            self.pts = np.concatenate([self.pts[: self.n], np.empty((cap - self.n, 2))])
            self.hs = np.concatenate([self.hs[: self.n], np.empty(cap - self.n)])
            self.link = np.concatenate([self.link[: self.n], np.empty(cap - self.n, dtype=np.int64)])
        keep = inside.copy()
        self.n = int(self.kern.admit(
            np.ascontiguousarray(q), hq, keep, MERGE, CLEARANCE, self.pts, self.hs, self.n,
            self.h_max, self.head, self.link, self.seg_a, self.seg_b, self.rows, self.items,
            self.x0, self.y0, self.cell, self.nx, self.ny,
        ))
        if keep.any():
            self.h_max = max(self.h_max, float(hq[keep].max()))
            self.h_min = min(self.h_min, float(hq[keep].min()))
        return keep


def _admissible(domain: Domain, h: SizeFn, q: FloatArray, grid: _Proximity) -> BoolArray:
    """Points inside, clear of the boundary, of existing nodes and of lower-numbered new points."""
    if len(q) == 0:
        return np.zeros(0, dtype=bool)
    inside = domain.sdf(q) < 0
    hq = np.ones(len(q))
    if inside.any():
        hq[inside] = h(q[inside])
    return grid.admit(q, hq, inside)


def _survivors(front: Front, keep: BoolArray) -> Front:
    """Runs of consecutive kept points become the next chains (:func:`kernels.inject.survivors`)."""
    from .kernels.inject import survivors

    pts, lengths, closed = survivors(front.points, front.start.astype(np.int64), front.closed, keep)
    return Front(pts, lengths, closed)


def _drop_empty(front: Front) -> Front:
    return _keep_chains(front, front.lengths >= 1)


def _drop_isolated(front: Front) -> Front:
    """Chains of a single node have no edge to inject from."""
    return _keep_chains(front, front.lengths >= 2)


def _keep_chains(front: Front, ok: BoolArray) -> Front:
    """The front restricted to the chains flagged ``ok``."""
    if ok.all():
        return front
    sel = ok[front.chain]
    return Front(front.points[sel], front.lengths[ok], front.closed[ok])
