"""Step 3 of Algorithm 1: smoothing (paper Section 3.2, Eq. 3.4, in the stepping of 2.4-2.5).

The nodes are joined by Delaunay triangulation (triangles whose centroid is outside are
dropped) and moved by forward Euler steps of the truss model (2.4), (2.5)::

    p_i <- p_i + dt * hbar_i * sum_j f(lc_ij, ld_ij) (p_i - p_j) / lc_ij,    ld = h(midpoint)

Two bar forces are used, in this order (``smoothing="hybrid"``, the default):

1. **Attractive** (the paper's Eq. 3.4), ``f = -0.2 lc / ld``, for ``ATTRACTIVE_ITERATIONS``
   steps.  Its fixed point is an h-weighted Laplacian: measured on the paper's six cases it
   improves the injected nodes for about 20 steps, then drifts away from h (relative size error
   0.08 -> 0.21, q_mean 0.955 -> 0.913 on the unit disc after 300 steps).  So it is used to
   relax the injected layout, not run to its fixed point.
2. **Spring**, ``f = (ld - lc) / ld``: attractive above h, repulsive below, with rest length h
   itself (no DistMesh rescaling, since Step 2 already placed the right number of nodes).
   Run to convergence.  It is what makes edges follow h: relative error 0.06-0.09 on the
   paper's cases, q_mean 0.95-0.97.
3. **Repair.**  In each triangle with q < ``REPAIR_Q``, the edge furthest from h is collapsed
   (too short) or split (too long) when its nodes are free interior nodes; in a triangle of
   three boundary nodes, its longest edge when that is a chord inside the domain (a flat cap
   at a blunt corner or across a channel: the new node is free; the unit square's corner caps,
   q 0.828, become two triangles of q ~0.91).  Non-conflicting
   repairs are applied together, the spring relaxation resumes on the nodes within
   ``REPAIR_RING`` edges of the changed ones only (the rest of the mesh is already at rest),
   and the best round (by q_min) is kept; at most ``REPAIR_ROUNDS`` rounds.  The edits are
   made on the triangle arrays (a split edge's triangles are halved, a collapsed edge's
   removed) and Lawson flips make the result Delaunay again: no triangulation from scratch
   unless an edit inverts a triangle.  The rounds see only a sub-mesh: the triangles within
   ``REPAIR_REACH + REPAIR_BAND`` edges of the bad ones, with a band that does not move, so
   their cost follows the number of bad triangles, not the mesh (1e6-node square: about 15 s
   of whole-mesh arrays per ten rounds before, a fraction of a second now).  Each connected
   part of that sub-mesh keeps its own best round (on a large mesh one worse edit anywhere
   made every round lose; the 1e5 square with regions: q_min 0.722 -> 0.743).  A triangle of
   three fixed nodes and no chord to split (a sharp tip) is left out of its part's score when
   it is the part's worst: no round can change it, and scored it made every round lose, so
   the strip behind a narrow spike went unrepaired (q 0.57-0.68; ``REPAIR_EXCUSED``).  Where
   a split is chosen on an edge between two fixed nodes (a wall segment, a rung of a strip
   one triangle wide), the free node opposite it, if inside its diametral circle, is
   collapsed into the nearer end instead: in a strip narrowing from two layers to one that
   node has no good place (``kernels.repair.choose_edits``).  Over ``robustness.py``'s 1000
   polygons the two raised q_min away from sharp vertices at 1 % / median from 0.622 / 0.772
   to 0.657 / 0.784, and thin parts from 0.688 to 0.703 at 1 % (11 meshes below 0.7, now 5).
4. **Quality pass.**  Free and sliding nodes of triangles with q < ``OPTIMIZE_Q`` move towards
   the mean equilateral apex over their opposite edges when that raises the worst quality of
   their star (line search, connectivity kept; a node at most ``OPTIMIZE_MOVES`` times, and
   not again until its star changes after a failed trial).  Each sweep visits only those candidates'
   stars; targets, trials and star updates are compiled (``kernels.smooth.star_targets``,
   ``star_trial``, ``restar``), the domain is asked once per trial length; on a compiled
   boundary a sweep's whole line search is one call (``optimize_trials``, the same numbers).
   A sliding node's trial whose midpoint lies outside the domain by more than ``ACROSS`` of
   the move crossed a gap to another stretch of boundary, and is refused.

``smoothing="attractive"`` runs the paper's force alone to its convergence, to reproduce the
paper as printed.

Other choices the paper leaves open:

* **Units of the step.**  As printed, ``dt * f`` is dimensionless yet moves a point.  Here the
  step is scaled by ``hbar_i``, the mean desired length of the bars at node i, so meshing a
  domain and h scaled by s gives the mesh scaled by s.
* **Stable steps.**  Forward Euler on a node whose bars are all stretched (in a hole left
  by the fronts, at the tip of a fan into a narrow inlet) has a gain ``DT * hbar * stiffness``
  above 2: the node swings across its place at the step cap for ever and the run never
  converges (a coastline: 1000 steps, no repair, q_min 0.10).  Each node's force is scaled
  down where that gain exceeds ``STABLE_GAIN = 1`` (``kernels.smooth.stable_scale``, per
  connectivity update like ld); a node at rest among six to ten neighbours has 0.6-1.0 and
  is never touched (the paper's cases give the same meshes bit for bit).  The coastline
  converges in 12 s, q_min 0.13.
* **Boundary nodes.**  Corners, curve anchors and user points never move.  Other boundary nodes
  slide: their force is half the total bar force and half the spring force of their two
  boundary bars (measured over the six cases at h/2, h and 2h: worst q_min 0.73, against 0.59
  with the total force alone, which lets the interior squeeze boundary edges to 0.7 h); they
  take the step, are projected back (Eq. 3.2), and the step is refused if it is not shorter
  than half the distance to either boundary neighbour (Algorithm 3's barriers), so they keep
  their order and cannot cross a corner, or if it would close a gap to a neighbour below
  h/2 (at a sharp corner the interior would otherwise push them into the tip).  An interior
  node whose step would leave the domain keeps its place for that step.
* **Re-triangulation.**  When some node has moved more than ``RETRIANGULATE * hbar`` since the
  last triangulation (DistMesh's ``ttol``), and once at the end, so the result is Delaunay.
  A full triangulation (our exact Delaunay kernel) runs only at the start, where flips meet
  an inverted triangle, and in the boundary recovery below; otherwise the mesh is made
  Delaunay again by Lawson flips with exact predicates on the kept triangles
  (``kernels.delaunay.flip_rows_to_delaunay`` on the compact arrays and their neighbour table,
  kept between steps), which also keeps its boundary edges.  The flips start from the
  triangles of the nodes that drifted more than ``LOCAL_DRIFT`` (half of
  ``RETRIANGULATE``) since their own last update, and only those nodes' bars, hbar and inside
  flags are renewed: the update is usually triggered by a handful of nodes (on a 1e6-node
  square the five whole-mesh flip passes of a run changed no edge at all).  The node lists
  have ``ROW_SLACK`` free slots per node, so the flips' new edges are written into them in
  place, from the flips' own log (``kernels.delaunay.flips_logged``: which edge gave way to
  which; at a million nodes comparing every triangle with a copy cost more than the flips);
  a list that runs out of slots is rebuilt.  At the end the flips run everywhere.
* **The step** is compiled (:mod:`injmesh.kernels.smooth`): the bars are node neighbour lists
  in CSR form built once per connectivity, and each node gathers its own bar forces in a fixed
  order, so the result is bit-identical whatever the thread count.  On large node lists the
  step's per-node kernels (forces, stability limit, the move) and the drift scan run over
  consecutive chunks on a few threads (:mod:`injmesh.kernels.threads`; ``NUMBA_NUM_THREADS``
  of them): each node's numbers are the serial ones, and the step's reductions (largest move,
  counts) are combined in chunk order with the serial loop's ties.
  Three quantities are computed per connectivity rather than per step:

  - ``ld = h(midpoint)`` of every bar, and hbar.  Between two updates no node drifts more than
    ``RETRIANGULATE * hbar`` (plus one step), so the midpoints move by a fraction of an edge
    and ld by a fraction of h's variation over one edge.
  - The inside test.  A step is clamped to ``STEP_CAP * hbar`` (on the paper's six cases it
    never binds: the output is identical without it), so between two updates a node moves less
    than ``(RETRIANGULATE + STEP_CAP) * hbar``; free nodes deeper than ``DEEP * hbar`` (twice
    that, for distances that are not exact) skip ``domain.sdf`` at each step.  Of the others,
    a node still within its anchor's depth of its anchor (half of it when d is not an exact
    distance) is inside without asking; and
    when d is an exact distance, ``d0 + drift`` bounds it from above, so the depth of the
    nodes far inside is not asked again at each connectivity update (a detailed outline's
    distance queries went from the whole mesh to a few rows along the boundary).
  - The boundary bars' ld for the sliding nodes (see :func:`_slide`).

  On a small node list (a small mesh, the repair's patches) the kernels take microseconds and
  the Python between them (dispatches, the sliding nodes' projection through the domain's
  methods) cost several times more.  When the sliding nodes project onto the domain's boundary
  and the domain has a :meth:`~injmesh.geometry.Domain.kernel_boundary` (B-reps, circles,
  rectangles and their exact set operations), the steps up to the next connectivity update
  are one compiled call (``kernels.smooth.run_steps``), and the connectivity update between
  two runs is two compiled calls around the one Python call it needs, h at the new bars'
  midpoints (``kernels.smooth.relink`` and ``resize``; it was ~180 us of a dozen calls, three
  quarters of a run's time).  The same kernels in the same order, and the boundary queries
  the methods make, so the meshes are bit-identical to the loop's (curves without a kernel
  form keep the loop).  Interior curves too: each sliding row projects onto its own boundary
  (the domain's, a region's, a polyline's), each boundary queried on its rows in order as the
  Python projectors are.  A plain signed distance, which has no kernel form, is stepped
  against a fine polygon of its boundary (``_stand_in``), its boundary nodes projected back
  onto d = 0 at the end.  The paper's six cases: 6-28 % less time in all; with
  one inclusion, 17-29 % (A/B in one run, with the patch set-up and quality-pass sweeps
  compiled too).  A large node list steps through the threaded kernels instead, but its
  sliding rows too are projected in one compiled call when the boundaries have a kernel
  form (``kernels.smooth.project_rows``, the same queries: the 1e5-node square with regions
  and a crack about 10 ms faster, the meshes bit-identical).

  The repair rounds' bookkeeping is compiled too (:mod:`injmesh.kernels.repair`, one call
  per step, the numbers of the NumPy lines they replaced): a round's quality, chords, parts'
  minima and bad triangles (``round_state``), its edits' choice around the one call of h
  (``edge_midpoints``, ``choose_edits``), the collapse and split renumbering
  (``apply_edits``), the flips after them (``flip_near``), its patch's cut and write-back
  (``patch_of``, ``patch_merge``), and the sub-mesh's cut and stitch (``sub_mesh_of``,
  ``stitch``); a relaxation's set-up is ``moving_nodes``, then ``connect_bars`` and
  ``connect_rest`` around h.  On the paper's small cases a round's sub-mesh has a few
  hundred triangles, and its few hundred NumPy calls of 1-5 us cost more than the work: the
  rounds took 11.7 / 9.9 / 6.0 ms per mesh on the unit disc / square with a hole / two
  circles and a square, 7.0 / 5.6 / 2.9 ms now (A/B in one run, best of 7 over three
  alternations; the whole mesh 27.8 / 29.9 / 28.5 -> 22.2 / 24.6 / 24.7 ms on a loaded
  machine).  What remains of a round is mostly its patch's spring runs (``run_steps``,
  ``relink``, ``resize``) and the calls of h between them.

  Measured with ``benchmarks/scale.py`` (CPU seconds of the smoothing stage, 2 cores under
  heavy load): 1e3 nodes 0.15 -> 0.04, 1e4 2.44 -> 0.28, 1e5 17.8 -> 1.7, together with the
  local repair, the candidate-only quality pass and ``DPTOL`` below; at 1e5 a step's two
  kernels take about 12 + 5 ms and the one remaining full triangulation most of the rest.
  The meshes are not bit-identical to those of the former NumPy step: repair rounds are
  sensitive to the exact positions, and q_min moves by a few hundredths either way from case
  to case (worst q_min over the paper's cases at h/2, h, 2h: 0.821, formerly 0.710).
* **Boundary conformity.**  Delaunay keeps a boundary segment when no node lies in its
  diametral circle.  At the end, free nodes found in the circle of a missing segment are pushed
  just outside it and the nodes re-triangulated (kept only if fewer segments are then missing:
  in a notch the pushed nodes can land in other segments' circles); a segment still missing is
  split at its projected midpoint (a new boundary node), repeatedly, until Delaunay keeps its
  halves, and what splitting cannot recover is recovered by flips.
  Triangles are kept or dropped by flood fill from the segments' sides
  (``triangulation.classify_by_walls``), so a triangle bridging a narrow notch is never kept.
  ``generate`` then checks the result (:mod:`injmesh.validate`).
* **The slow tail.**  Once at most ``TAIL_FRACTION`` (2 %) of the nodes move more than
  ``DPTOL * hbar`` in a step, after ``TAIL_AFTER`` steps, the few still moving are relaxed on
  their own sub-mesh (the nodes within ``TAIL_RING`` edges of them; :func:`_settle`) and the
  global steps resume to check: on graded sizes and around regions' curves a few hundred
  nodes near where fronts met kept the whole mesh stepping for hundreds of steps (20:1 graded
  disc, 3e5 nodes: 12 -> 9 s).  The sub-mesh only flips, so its triangles are written back
  over its own rows and the node lists are updated from the flips' edge differences, as
  after a local re-triangulation (a whole-mesh rebuild cost ~1 s per round at 1e6 nodes).
* **Stopping condition.**  No node moves more than ``DPTOL * hbar`` in a step, or the cap is
  reached (then ``converged`` is False).  ``DPTOL = 3e-3``: over the paper's six cases at
  h/2, h and 2h (18 meshes) it takes 2329 steps in all against 4089 with 1e-3, with worst
  q_min 0.821 (1e-3: 0.817), mean q_mean 0.9673 (0.9669) and mean relative size error 0.0715
  (0.0716); the repair and quality passes, not the last thousandths of a step, set the
  quality.  5e-3 gave 2025 steps and worst q_min 0.818, 1e-2 1581 steps and 0.796.  On a
  100 000-node square: 57 steps against 123, q_mean 0.99942 (0.99944), q_min 0.828 (0.828).
* **Interior curves** (regions' boundaries, cracks: :class:`Interfaces`).  Their nodes slide
  like boundary nodes, each projected onto its own curve; their junctions are fixed.  At the
  end their segments are recovered like the boundary's (``_recover_interfaces``), except that
  a free node encroaching a missing segment is dropped, not pushed (pushed, it made slivers:
  q 0.47 on the issue's square); they never bound the domain, so triangles are classified by
  the boundary segments alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from . import _tolerances as tol
from .geometry import Domain
from .progress import Callback, report
from .quality import triangle_quality
from .triangulation import (
    constrained_triangles,
    delaunay,
    delaunay_with_neighbours,
    inside_mask,
    inside_triangles,
)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
Int32Array = NDArray[np.int32]
SizeFn = Callable[[FloatArray], FloatArray]
Smoothing = Literal["hybrid", "attractive"]

#: Coefficient of the attractive force, Eq. (3.4).
ATTRACTION = 0.2
#: Steps of the attractive force before the spring takes over (hybrid smoothing).
ATTRACTIVE_ITERATIONS = 20
#: Euler step (2.4), dimensionless; the step length is DT * hbar * |sum of bar forces|.
DT = 0.2
#: Re-triangulate when a node has moved this fraction of its hbar since the last triangulation.
RETRIANGULATE = 0.1
#: Converged when no node moves more than this fraction of its hbar in a step (see the module
#: documentation for how 3e-3 was chosen).
DPTOL = 3e-3
#: A step is clamped to this fraction of the node's hbar.  On the paper's six cases it never
#: binds (the output is identical without it); it bounds how far a node can go between two
#: connectivity updates (see DEEP).
STEP_CAP = 0.5
#: A re-triangulation checks the triangles of the nodes that drifted more than this fraction
#: of their hbar since their own last update (see ``_Relaxation.retriangulate``).  Over the
#: paper's cases at h/2, h and 2h: RETRIANGULATE / 4 gave worst q_min 0.821 and mean 0.854,
#: / 2 0.821 and 0.857, RETRIANGULATE itself 0.803 and 0.849; the 1e6 graded disc took 160,
#: 80 and 79 whole-mesh steps (32, 30 and 27 s).
LOCAL_DRIFT = RETRIANGULATE / 2
#: Free slots per node list: flips change the lists in place until a node gains more
#: neighbours than this since the last rebuild (see ``_Relaxation._flipped``).
ROW_SLACK = 3
#: A node's step is scaled down where its stiffness times the step exceeds this (see
#: ``kernels.smooth.bar_forces``): explicit Euler without overshoot.
STABLE_GAIN = 1.0
#: Free nodes deeper inside than DEEP * hbar (from d at the last connectivity update) skip
#: the inside test of each step: they drift less than (RETRIANGULATE + STEP_CAP) * hbar before
#: the next update, and DEEP leaves a factor 2 for signed distances that are not exact.
DEEP = 2.0 * (RETRIANGULATE + STEP_CAP)
#: The spring's slow tail is relaxed locally (``_settle``) once at most this fraction of the
#: nodes (and at least TAIL_MIN) moves more than DPTOL in a step: the nodes within TAIL_RING
#: edges of them, at most TAIL_ROUNDS times.
TAIL_FRACTION = 0.02
TAIL_MIN = 16
TAIL_RING = 4
#: After TAIL_WHOLE rounds come up to TAIL_WHOLE_STEPS whole-mesh steps, then local rounds
#: again.  Most meshes still moving after a few rounds converge so (the graded disc at 1e5
#: nodes: 124 steps in all, 150 with only local rounds); a detailed outline's tail (the
#: 20,000-vertex fixture of ``benchmarks/robustness.py``) keeps a few hundred nodes moving, a
#: few here and a few there, and took 370 whole steps after 4 rounds (532 in all; 255 now).
TAIL_ROUNDS = 20
TAIL_WHOLE = 4
TAIL_WHOLE_STEPS = 10
#: ... and only after this many steps: a spring that converges in fewer (a uniform square
#: takes 30-45 steps from 1e3 to 1e6 nodes) is not slow, and a local round's set-up costs a
#: few whole-mesh passes (1e6-node square: 7.7 s CPU with every tail local, 9.8 s without).
#: Measured on the 1e6-node graded disc (20:1): 30 steps 19.1 s, 40 16.8 s, 50 18.1 s, 60
#: 20.2 s, the same q_min within 0.01; the square and the paper's cases do not change.
TAIL_AFTER = 40
#: Most steps of one local relaxation of the tail.
TAIL_STEPS = 500
#: A boundary the kernels cannot query is stepped against a polygon of it (``_stand_in``)
#: whose chords are within this fraction of the shortest wall segment from the curve, found
#: by at most STAND_IN_HALVINGS halvings of the traced loops' chords.
STAND_IN_SAG = 1e-3
STAND_IN_HALVINGS = 8
#: Default iteration cap (all phases together).
MAX_ITERATIONS = 1000
#: Triangles below this quality are repaired; at most REPAIR_ROUNDS rounds.
REPAIR_Q = 0.85
REPAIR_ROUNDS = 10
#: ... ending early after this many rounds in a row that change no part's q_min (see
#: ``_repair_rounds``).
REPAIR_STALL = 1
#: A part whose q_min is a sharp tip's (a triangle of three fixed nodes, which no round can
#: change) is scored without it when it has at most this many bad triangles (see
#: ``_repair_rounds``); a larger one is left alone: the 20,000-vertex outline of
#: ``benchmarks/robustness.py`` is one part of ~3000, whose six rounds all lost (4.7 s -> 7.9 s
#: without this bound).  The 1000 random polygons there have no part above it.
REPAIR_EXCUSED = 200
#: ... or at a round no better than the best that has an earlier round's triangles, every node
#: within this fraction of h of where it was then (a cycle: the paper's circle with a hole and
#: an inclusion came back to the same two triangulations from round 4 on, the nodes within
#: 0.004 h, the tolerance the patches' relaxation stops at).
REPAIR_SAME = 0.02
#: Spring steps after each repair round: the change is local and settles quickly.
REPAIR_STEPS = 40
#: Repair relaxes only the nodes within this many edges of the nodes it changed.
REPAIR_RING = 3
#: Repair works on a sub-mesh (``_repair``): its free nodes within REPAIR_REACH edges of a
#: bad triangle may change, and a band REPAIR_BAND edges wide around them stays.  Each part
#: of the sub-mesh keeps its own best round, so a shorter reach (more, smaller parts) lets
#: more of them win.  q_min at 1e5 nodes (graded disc 20:1 / square with regions / square
#: with two holes) and over the paper's cases at h/2, h, 2h (worst / mean): reach 8: 0.760 /
#: 0.743 / 0.814, 0.821 / 0.8572; 6: 0.764 / 0.779 / 0.814, the same; 5: 0.831 / 0.774 /
#: 0.816, the same; 4: 0.824 / 0.772 / 0.828, 0.821 / 0.8564; 3: 0.781 / 0.767 / 0.804,
#: 0.729 / 0.8463.
REPAIR_REACH = 5
REPAIR_BAND = 3
#: Rounds of boundary-segment recovery at the end: pushing free nodes out of the segments'
#: diametral circles, then splitting the segments still missing.
CONFORM_ROUNDS = 5
RECOVER_ROUNDS = 4
#: A missing segment is split only while longer than this fraction of h.
SPLIT_MIN = 0.25
#: Final quality-driven pass: nodes whose star has q below OPTIMIZE_Q, at most OPTIMIZE_SWEEPS,
#: each node moving at most OPTIMIZE_MOVES times.  Two neighbours can each raise their own
#: star's minimum while lowering the other's, for ever: on the 20,000-vertex outline the same
#: 994 nodes moved in each of the last twelve sweeps.  With at most 3 or 4 moves a node, and a
#: node whose trial failed left out until its star changes, the paper's cases at h/2, h, 2h
#: went from worst / mean q_min 0.821 / 0.8576 to 0.826 / 0.8722 (unbounded: 0.826 / 0.8680),
#: the 1e5 square with regions from 0.774 to 0.823, the real outlines' 1 % quantile of q up
#: by 0.02.
OPTIMIZE_Q = 0.9
OPTIMIZE_SWEEPS = 20
OPTIMIZE_MOVES = 4


@dataclass(frozen=True)
class SmoothResult:
    """Smoothed nodes and their triangulation.

    ``kept`` maps each of the first output nodes to its index in the input; nodes that repair
    or boundary recovery added come last and map to -1.  ``walls`` are the boundary segments in
    output numbering (Step 1's, some split by recovery), ``wall_origin`` the index of the
    Step 1 segment each comes from.
    """

    points: FloatArray
    triangles: IntArray
    kept: IntArray
    iterations: int
    converged: bool
    retriangulations: int
    walls: IntArray
    wall_origin: IntArray
    unsettled: tuple[float, float] | None = None
    #: Interior constraint segments in output numbering (split by recovery) and their curve.
    interfaces: IntArray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.intp))
    interface_group: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))


#: ``active`` of a relaxation whose free nodes all move (``kernels.smooth.moving_nodes``).
_NO_FLAGS = np.zeros(0, dtype=np.bool_)

#: ``project(points (m, 2), nodes (m,))``: each point onto the curve its node slides on.
NodeProjector = Callable[[FloatArray, IntArray], FloatArray]


#: A projection the kernels make themselves: each sliding row's boundary (0 the domain's) and
#: the boundaries (``kernels.smooth.pack_boundaries``).
_Compiled = tuple[IntArray, tuple[Any, ...]]


class _OnDomain:
    """The :data:`NodeProjector` of a mesh without interior curves: every sliding node onto
    the domain's boundary (Eq. 3.2).  Like the other projectors here it tells a relaxation how
    the kernels can project in its place (:meth:`compiled`), so that it steps in compiled
    calls."""

    def __init__(self, domain: Domain) -> None:
        self.domain = domain
        self._packed: tuple[Any, ...] | None | bool = None

    def __call__(self, q: FloatArray, nodes: IntArray) -> FloatArray:
        return self.domain.project(q)

    def compiled(self, domain: Domain, nodes: IntArray) -> _Compiled | None:
        """The boundary of each node of ``nodes`` and the boundaries packed for the kernels,
        boundary 0 being ``domain``'s (which the relaxation asks for its inside test); None
        when a boundary has no :meth:`~injmesh.geometry.Domain.kernel_boundary`."""
        if domain is not self.domain:
            return None
        if self._packed is None:
            kb = domain.kernel_boundary()
            from .kernels.smooth import pack_boundaries

            self._packed = False if kb is None else pack_boundaries([kb])
        if self._packed is False:
            return None
        return np.zeros(len(nodes), dtype=np.int64), self._packed  # type: ignore[return-value]


class _OnCurves:
    """The :data:`NodeProjector` of a mesh with interior curves (:meth:`Interfaces.projector`):
    each node onto its own curve, or onto the domain's boundary."""

    def __init__(self, interfaces: Interfaces, domain: Domain, groups: IntArray) -> None:
        self.interfaces, self.domain, self.groups = interfaces, domain, groups
        # The split of the last node list: a relaxation asks for the same nodes at every
        # step until its connectivity changes.
        self._last: list[IntArray] = []
        self._packed: tuple[Any, ...] | None | bool = None

    def _split(self, nodes: IntArray) -> list[IntArray]:
        last = self._last
        if last and len(last[0]) == len(nodes) and np.array_equal(last[0], nodes):
            return last
        g = self._group(nodes)
        on_domain = g == 0
        curve = np.flatnonzero(~on_domain)
        last[:] = [nodes.copy(), np.flatnonzero(on_domain), curve, g[curve]]
        return last

    def _group(self, nodes: IntArray) -> IntArray:
        g = np.zeros(len(nodes), dtype=np.intp)
        known = nodes < len(self.groups)
        g[known] = self.groups[nodes[known]]
        return g

    def __call__(self, q: FloatArray, nodes: IntArray) -> FloatArray:
        _, on_domain, curve, g = self._split(nodes)
        out = np.empty_like(q)
        if len(on_domain):
            out[on_domain] = self.domain.project(q[on_domain])
        if len(curve):
            out[curve] = self.interfaces.project(q[curve], g)
        return out

    def compiled(self, domain: Domain, nodes: IntArray) -> _Compiled | None:
        """As :meth:`_OnDomain.compiled`: boundary 0 the domain's, 1 + k the curves' k-th
        (:attr:`Interfaces.kernels`, by :attr:`Interfaces.group_kernel`)."""
        itf = self.interfaces
        if domain is not self.domain or not itf.kernels:
            return None
        if self._packed is None:
            kb = domain.kernel_boundary()
            from .kernels.smooth import pack_boundaries

            self._packed = False if kb is None else pack_boundaries([kb, *itf.kernels])
        if self._packed is False:
            return None
        g = self._group(nodes)
        target = np.zeros(len(nodes), dtype=np.int64)
        curve = g > 0
        target[curve] = 1 + itf.group_kernel[g[curve] - 1]
        return target, self._packed  # type: ignore[return-value]


class _Renumbered:
    """A sub-mesh's :data:`NodeProjector`: its node k is node ``nodes[k]`` of ``inner``'s."""

    def __init__(self, inner: NodeProjector, nodes: IntArray) -> None:
        self.inner, self.nodes = inner, nodes

    def __call__(self, q: FloatArray, idx: IntArray) -> FloatArray:
        return self.inner(q, self.nodes[idx])

    def compiled(self, domain: Domain, idx: IntArray) -> _Compiled | None:
        inner = getattr(self.inner, "compiled", None)
        return None if inner is None else inner(domain, self.nodes[idx])


@dataclass(frozen=True)
class Interfaces:
    """Interior constraint curves (regions' boundaries, user curves) for Step 3.

    Their nodes come among the first ``n_fixed`` and slide like boundary nodes (rows of
    ``sliding``), but on their own curve; their segments are recovered like the boundary's at
    the end (every one an edge, so no triangle straddles a curve) without bounding the domain.

    Attributes
    ----------
    segments : (k, 2) int array
        Segments that must be mesh edges.
    group : (k,) int array
        Curve of each segment, >= 1 (0 is the domain's boundary).
    node_group : (n_fixed,) int array
        Curve of each node (0 for nodes on no interior curve).
    project : callable
        ``project(points (m, 2), group (m,))``: the nearest point on curve ``group`` (>= 1).
    kernels : tuple
        The curves' projections as compiled boundaries
        (:meth:`~injmesh.geometry.Domain.kernel_boundary`), when every one has one; empty
        otherwise.  ``project`` must give their numbers (each called on its points in order).
    group_kernel : (groups,) int array
        The entry of ``kernels`` of curve ``group`` (at ``group - 1``).
    """

    segments: IntArray
    group: IntArray
    node_group: IntArray
    project: Callable[[FloatArray, IntArray], FloatArray]
    kernels: tuple[Any, ...] = ()
    group_kernel: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    def projector(self, domain: Domain, node_group: IntArray | None = None) -> NodeProjector:
        """Project each node's point onto its own curve, or onto the domain's boundary."""
        return _OnCurves(self, domain, self.node_group if node_group is None else node_group)


def triangulate(domain: Domain, p: FloatArray, walls: IntArray | None = None) -> IntArray:
    """Delaunay triangles of ``p`` with those outside the domain (or outside the boundary
    segments ``walls``, near the boundary) removed."""
    tri, nbr = delaunay_with_neighbours(p)
    return inside_triangles(p, tri, domain.sdf, walls, nbr)


def _triangulated(
    domain: Domain, p: FloatArray, walls: IntArray | None = None
) -> tuple[IntArray, Int32Array]:
    """:func:`triangulate`'s triangles ordered by their least node (as the relaxation keeps
    them) and their neighbour table (int32, -1 where there is none), which the Delaunay
    kernel kept as it went: the relaxation takes both, instead of finding every edge's twin
    again (~0.25 s at a million nodes)."""
    from .kernels.mesh import by_least_vertex, kept_neighbours

    tri, nbr = delaunay_with_neighbours(p)
    rows = np.flatnonzero(inside_mask(p, tri, domain.sdf, walls, nbr))
    rows = rows[by_least_vertex(tri[rows], len(p))]
    return tri[rows], kept_neighbours(nbr, rows)


class _Relaxation:
    """Euler steps of the truss model for one set of nodes.

    ``active`` (optional, a boolean mask over the nodes) restricts the moving nodes to a subset:
    the repair relaxes only the rings around the nodes it changed.  ``nbr`` (optional, with
    ``tri``): the neighbour table (int32) of ``tri``, whose rows are then ordered by their
    least node already (``kernels.repair.patch_of`` makes both for a repair patch).
    """

    def __init__(
        self,
        domain: Domain,
        h: SizeFn,
        p: FloatArray,
        n_fixed: int,
        slide: IntArray,
        walls: IntArray,
        callback: Callback | None,
        cap: int,
        active: NDArray[np.bool_] | None = None,
        tri: IntArray | None = None,
        project: NodeProjector | None = None,
        patch: bool = False,
        total: int | None = None,
        nbr: Int32Array | None = None,
    ) -> None:
        from .kernels import smooth as kernels

        #: A sub-mesh of the repair (``_patch``): never re-triangulated from scratch.
        self._patch = patch
        self._k = kernels
        self.domain, self.h, self.p = domain, h, p
        #: Sliding nodes return to their own curve (the domain's boundary by default).
        self.project: NodeProjector = project or _OnDomain(domain)
        self._kernel_boundary: _Compiled | None = None
        self.n_fixed, self.slide, self.walls = n_fixed, slide, walls
        self.callback, self.cap = callback, cap
        #: Steps taken, in whole-mesh steps: a step of a sub-mesh (the repair's patches, the
        #: slow tail) counts the fraction of the mesh's nodes it moves (``weight``), so the
        #: iteration cap bounds the work, whatever the size of the parts that still move.
        self.iterations = 0.0
        self.retriangulations = 0
        #: The last run stopped at its slow tail (see ``run``).
        self.in_tail = False
        #: final() left ld, hbar and the flags of the old positions (see ``final``).
        self._stale = False
        #: Where the largest move of the last step was: where a run that stops at its cap is
        #: still moving.
        self.unsettled: tuple[float, float] | None = None
        n = len(p)
        # The free nodes that may move, the sliding rows of those that may, all of them, and
        # the free nodes' mask, in one call (a repair patch is made every round).
        self._free, self._sl, self._moving, self._is_free = kernels.moving_nodes(
            n, n_fixed, _NO_FLAGS if active is None else np.ascontiguousarray(active, dtype=np.bool_),
            np.ascontiguousarray(slide, dtype=np.int64).reshape(-1, 3))
        #: The nodes that may move (None: all of them); the others never leave their place.
        self._active = active
        #: The sliding rows' boundaries and the boundaries as the kernels query them, when
        #: the projector can tell (every boundary has a kernel form): then ``run`` steps in
        #: compiled calls (``kernels.smooth.run_steps``).
        compiled = getattr(self.project, "compiled", None)
        if compiled is not None:
            self._kernel_boundary = compiled(domain, self._sl[:, 0])
        #: A zeroed scratch mask over the nodes (``_refresh``).
        self._mark = np.zeros(n, dtype=np.uint8)
        #: Nodes of the whole mesh (this may be a sub-mesh of it), and the weight of a step.
        self.total = n if total is None else int(total)
        self.weight = min(1.0, len(self._moving) / max(self.total, 1))
        self._total = np.zeros((n, 2))
        self._cand = np.empty((len(self._free), 2))
        #: The node lists in CSR form (indptr, adj, eid) and the bars' desired lengths ld.
        self._csr: tuple[NDArray[np.int64], NDArray[np.int32], NDArray[np.int64], FloatArray]
        self._bars: NDArray[np.int64]
        self._near = np.empty(len(self._free), dtype=np.intp)
        self._seen = np.zeros(0, dtype=np.bool_)
        #: d at each free node's anchor, or an upper bound of it for deep nodes (0 elsewhere).
        self._d0 = np.zeros(0)
        #: The fraction of its depth a node may move and be inside without asking the domain.
        self._reach = _inside_reach(domain)
        self._set_triangles(*(_triangulated(domain, p, walls) if tri is None else (tri, nbr)))

    def _projector(self, nodes: IntArray) -> Callable[[FloatArray], FloatArray]:
        """Projection of the points of ``nodes`` onto their own curves (Eq. 3.2)."""
        return lambda q: self.project(q, nodes)

    def _slide_projector(self, nodes: IntArray) -> Callable[[FloatArray], FloatArray]:
        """:meth:`_projector` for the sliding rows' nodes, through the compiled boundaries
        when there are (``kernels.smooth.project_rows``: the queries the Python projectors
        make, so the same numbers; on the 1e5-node square with regions and a crack the
        Python projectors' grouping and calls cost about 10 ms over a run)."""
        if self._kernel_boundary is None:
            return self._projector(nodes)
        target, arrays = self._kernel_boundary

        def project(q: FloatArray) -> FloatArray:
            out = np.empty_like(q)
            self._k.project_rows(target, *arrays, np.ascontiguousarray(q, dtype=np.float64), out)
            return out

        return project

    def _set_triangles(self, tri: IntArray, nbr: Int32Array | None = None) -> None:
        """Take a new triangulation (from scratch): its neighbour table for the flips.  The
        rows are ordered by their least node (the nodes are in Hilbert order): the flips' and
        kernels' gathers stay local.  ``nbr``: the table of ``tri`` when the caller has it,
        ``tri`` being in that order already (:func:`_triangulated`)."""
        from .kernels.mesh import by_least_vertex

        if nbr is None:
            tri = tri[by_least_vertex(tri, len(self.p))]
        t32 = np.ascontiguousarray(tri, dtype=np.int32)
        self._t32 = t32
        self._nbr = _neighbours32(t32, len(self.p)) if nbr is None else nbr
        self._con = np.zeros(t32.shape, dtype=np.uint8)
        self._vt = self._k.vertex_rows(t32, len(self.p))
        self._connect()

    def _connect(self, rebuild: bool = True) -> None:
        """Everything that stays fixed until the next change of connectivity.

        With ``rebuild=False`` the connectivity did not change (the flips found every edge
        Delaunay): the node lists are kept and only what depends on the positions is renewed.

        The bars and their desired lengths ``ld = h(midpoint)``: between two re-triangulations
        no node moves more than ``RETRIANGULATE * hbar`` (plus one step), so h at the
        midpoints changes by a small fraction of its own variation over one edge, and is
        evaluated once here instead of at every step.  The free nodes deeper than
        ``DEEP * hbar`` inside cannot leave the domain before the next call (see ``DEEP``), so
        only the others are tested with ``domain.sdf`` at each step.
        """
        k, p = self._k, self.p
        if rebuild and self._kernel_boundary is not None and not k.threads.worth(len(p)):
            self._connect_compiled()
            return
        if rebuild:
            self.tri = self._t32.astype(np.intp)
            # Free slots in every row: later flips update the rows in place (_flipped).
            indptr, adj, eid, bars = k.adjacency(len(p), self._t32, ROW_SLACK)
            self._bars = bars
        else:
            indptr, adj, eid = self._csr[:3]
            bars = self._bars
        constant = getattr(self.h, "constant", None)
        ld_slide: FloatArray | None = None
        if constant is not None and not rebuild:
            ld = self._csr[3]  # a constant h: the bars' desired lengths did not change
        elif constant is not None:
            ld = np.full(len(bars), float(constant))
        else:
            # The bars' midpoints and the sliding nodes' two boundary bars' in one call of h
            # (a small sub-mesh of the repair pays the call, not the points).
            mid = 0.5 * (p[bars[:, 0]] + p[bars[:, 1]])
            if len(self._sl):
                b, bp, bn = self._sl.T
                mid = np.concatenate([mid, 0.5 * (p[b] + p[bp]), 0.5 * (p[b] + p[bn])])
            values = np.asarray(self.h(mid), dtype=np.float64)
            ld = np.ascontiguousarray(values[:len(bars)])
            ld_slide = values[len(bars):]
        hbar = k.mean_bar_size(indptr, eid, ld)
        # A node in no triangle (the triangulation leaves out coincident points) feels no force; its own h
        # keeps the relative measures finite.
        lonely = np.flatnonzero(hbar == 0)
        if len(lonely):
            hbar[lonely] = self.h(p[lonely])
        self._csr = (indptr, adj, eid, ld)
        self.hbar = hbar
        # The stability limit of each moving node's step (see kernels.smooth.stable_scale).
        self._damp = np.ones(len(p))
        k.threaded_stable_scale(p, self._moving, indptr, adj, eid, ld, DT * hbar, STABLE_GAIN, self._damp)
        self._slide_lengths(ld_slide)
        self._depth_arrays()
        self._inside_depth(self._free)
        self.anchor = p.copy()
        self.retriangulations += 1

    def _slide_lengths(self, ld_slide: FloatArray | None) -> None:
        """The sliding rows' boundary bars' ld: from ``ld_slide`` (h at their midpoints, to
        the previous nodes then to the next ones) when the caller asked h for them, else here."""
        p = self.p
        if len(self._sl) and ld_slide is not None:
            k_sl = len(self._sl)
            self._ld_slide = (ld_slide[:k_sl].copy(), ld_slide[k_sl:].copy())
        elif len(self._sl):
            b, bp, bn = self._sl.T
            self._ld_slide = (np.array(self.h(0.5 * (p[b] + p[bp])), dtype=np.float64),
                              np.array(self.h(0.5 * (p[b] + p[bn])), dtype=np.float64))

    def _depth_arrays(self) -> None:
        """The inside depths, flags and anchors, made on the first connectivity."""
        p = self.p
        if len(self._d0) != len(p):
            self._d0 = np.zeros(len(p))
            self._deep = np.zeros(len(p), dtype=np.bool_)
            self.anchor = np.full_like(p, np.nan)  # no bound yet: every free node is evaluated

    def _connect_compiled(self) -> None:
        """``_connect(rebuild=True)`` in two compiled calls around h (``kernels.smooth.
        connect_bars`` and ``connect_rest``), the depth asked of the compiled boundary: the
        same numbers."""
        k, p = self._k, self.p
        constant = getattr(self.h, "constant", None)
        sl = np.ascontiguousarray(self._sl, dtype=np.int64)
        tri, indptr, adj, eid, bars, mid = k.connect_bars(p, self._t32, ROW_SLACK, sl, constant is None)
        self.tri, self._bars = tri, bars
        ld_slide: FloatArray | None = None
        if constant is not None:
            ld = np.full(len(bars), float(constant))
        else:
            values = np.asarray(self.h(mid), dtype=np.float64)
            ld = np.ascontiguousarray(values[:len(bars)])
            ld_slide = values[len(bars):]
        hbar = k.mean_bar_size(indptr, eid, ld)
        lonely = np.flatnonzero(hbar == 0)  # as in _connect
        if len(lonely):
            hbar[lonely] = self.h(p[lonely])
        self._csr = (indptr, adj, eid, ld)
        self.hbar = hbar
        self._slide_lengths(ld_slide)
        self._depth_arrays()
        assert self._kernel_boundary is not None
        exact = bool(getattr(self.domain, "exact_distance", False))
        self._damp = k.connect_rest(p, self._moving, self._free, indptr, adj, eid, ld, hbar, DT,
                                    STABLE_GAIN, self.anchor, self._d0, self._deep, DEEP, exact,
                                    *self._kernel_boundary[1])
        self.retriangulations += 1

    def _inside_depth(self, free: IntArray) -> None:
        """Renew ``_d0`` and ``_deep`` of the free nodes ``free`` before their anchors move to
        where they are.

        When the domain's d is an exact distance (``Domain.exact_distance``: primitives,
        polygons, their exact set operations), d moves by at most the distance moved
        (1-Lipschitz), so ``d0 + |p - anchor|`` bounds d from above: a node whose bound is
        below ``-DEEP * hbar`` is deep without asking the domain, and keeps the bound as its
        ``d0``.  Only the others (a few rows along the boundary) are evaluated, which leaves
        ``_deep`` as the exact test would and spares a detailed outline's distance queries
        over the whole mesh.  A plain signed distance promises no such bound: every node is
        evaluated.
        """
        if not len(free):
            return
        k = self._k
        free = free.astype(np.int64)
        exact = bool(getattr(self.domain, "exact_distance", False))
        ask = k.depth_bounds(self.p, self.anchor, self._d0, self.hbar, free, DEEP, exact)
        if len(ask):
            self._d0[ask] = self.domain.sdf(self.p[ask])
        k.mark_deep(self._d0, self.hbar, free, DEEP, self._deep)

    def retriangulate(self, everywhere: bool = False) -> None:
        """Make the triangulation Delaunay again after the nodes moved (see the module doc).

        Lawson flips (exact predicates, on the triangles kept, so the mesh keeps its boundary
        edges) restore Delaunay far more cheaply than a new triangulation; an inverted triangle
        sends us back to one.  Unless ``everywhere``, the flips start from the triangles of
        the nodes that drifted more than ``RETRIANGULATE / 2`` of their hbar since their own
        last update (``LOCAL_DRIFT``): the step that triggers an update is usually a handful
        of nodes past ``RETRIANGULATE``, and checking every edge of the mesh for them cost
        more than the steps.  An edge between nodes that drifted less stays as it was (at
        worst nearly Delaunay) until one of them drifts further; ``final`` flips everywhere.
        ``everywhere`` is ``final``'s on a relaxation with ``active`` nodes (the repair's
        patches): only they moved, so the flips start from all their triangles.
        """
        from .kernels.delaunay import flip_rows_to_delaunay, flips_logged

        if not everywhere and self._kernel_boundary is not None and not self._k.threads.worth(len(self.p)):
            self._retriangulate_compiled()
            return
        moved: IntArray | None = None
        log: NDArray[np.int64] | None = None
        if everywhere:
            assert self._active is not None  # final() flips a whole relaxation itself
            rows = np.flatnonzero(self._active[self._t32].any(axis=1)).astype(np.int32)
            res = int(flip_rows_to_delaunay(self.p, self._t32, self._nbr, self._con, self._vt, rows))
        else:
            moved, rows = self._k.drifted(self.p, self.anchor, self.hbar, LOCAL_DRIFT, self._t32)
            res, log = flips_logged(self.p, self._t32, self._nbr, self._con, self._vt, rows, False)
            res = int(res)
        if res < 0:
            self._from_scratch()
        elif res == 0 and moved is not None:
            # No flip: the node lists stay; only the moved nodes' bars and anchors are renewed.
            self._refresh(moved)
        elif moved is not None and log is not None and self._flipped(_flip_changes(log), moved):
            pass
        else:
            # No flip keeps the node lists (the usual case once the nodes settle).
            self._connect(rebuild=res > 0)

    def _retriangulate_compiled(self) -> None:
        """The local update of :meth:`retriangulate` in two compiled calls around h
        (``kernels.smooth.relink`` and ``resize``): the same kernels in the same order, the
        depth asked through the domain's compiled boundary, so the same numbers."""
        k, p = self._k, self.p
        indptr, adj, eid, ld = self._csr
        if len(self._seen) != len(ld):
            self._seen = np.zeros(len(ld), dtype=np.bool_)
        constant = getattr(self.h, "constant", None)
        graded = constant is None
        sl = np.ascontiguousarray(self._sl, dtype=np.int64)
        outcome, nodes, near, bars, mid, rows = k.relink(
            p, self.anchor, self.hbar, LOCAL_DRIFT, self._t32, self._nbr, self._con, self._vt,
            self.tri, indptr, adj, eid, ld, self._bars, self._mark, self._seen, graded,
            math.nan if constant is None else float(constant), sl)
        if outcome == k.RELINK_INVERTED:
            self._from_scratch()
            return
        if outcome == k.RELINK_REBUILD:
            self._connect(rebuild=True)
            return
        values = np.asarray(self.h(mid), dtype=np.float64) if len(mid) else np.zeros(0)
        no_bars = np.zeros(0)
        ld_prev, ld_next = self._ld_slide if len(sl) else (no_bars, no_bars)
        assert self._kernel_boundary is not None
        kinds, shapes, origins, cat, offs = self._kernel_boundary[1]
        exact = bool(getattr(self.domain, "exact_distance", False))
        k.resize(values, bars, rows, ld, ld_prev, ld_next, p, nodes, near, indptr, adj, eid, DT,
                 STABLE_GAIN, graded, self.hbar, self._damp, self._is_free, self.anchor, self._d0,
                 self._deep, DEEP, exact, kinds, shapes, origins, cat, offs)
        self.retriangulations += 1

    def _from_scratch(self) -> None:
        """After flips met an inverted triangle: a new triangulation, or ``_PatchInverted`` for
        a sub-mesh (only a triangulation of the whole mesh could undo it)."""
        if self._patch:
            raise _PatchInverted
        self._set_triangles(*_triangulated(self.domain, self.p, self.walls))

    def _flipped(self, changes: _Changes, moved: IntArray) -> bool:
        """Apply the change of triangles ``changes`` (:func:`_flip_changes`,
        :func:`_row_changes`) to the node lists in place (``kernels.smooth.flip_update``) and
        renew the nodes they touched; False when that cannot be done (a row out of free
        slots), for a rebuild."""
        added = self._relink(changes)
        if added is None:
            return False
        # The moved nodes and the flips' corners: their bars' ld, hbar, flags and anchors.
        self._refresh(_with_nodes(moved, added.ravel()))
        return True

    def _refresh(self, nodes: IntArray) -> None:
        """Renew what depends on the positions of ``nodes`` only: the desired lengths of their
        bars (and so hbar around them), their inside flags and their anchors."""
        k, p = self._k, self.p
        indptr, adj, eid, ld = self._csr
        nodes = nodes.astype(np.int64)
        graded = getattr(self.h, "constant", None) is None and len(nodes) > 0
        if len(self._seen) != len(ld):
            self._seen = np.zeros(len(ld), dtype=np.bool_)
        # The moved nodes and their neighbours (the ends of their bars), and the bars.
        near, bars, mid = k.moved_bars(indptr, adj, eid, self._bars, p, nodes, self._mark,
                                        self._seen, graded)
        rows = np.zeros(0, dtype=np.intp)
        if len(self._sl) and len(nodes):
            # Only the boundary bars with a node in ``nodes`` changed (on a detailed outline
            # the sliding nodes are a fifth of the mesh, and h there is the costly corner cap).
            b, bp, bn = self._sl.T
            mark = self._mark
            mark[nodes] = 1
            rows = np.flatnonzero(mark[b] | mark[bp] | mark[bn])
            mark[nodes] = 0
            if len(rows):
                b, bp, bn = b[rows], bp[rows], bn[rows]
                mid = np.concatenate([mid, 0.5 * (p[b] + p[bp]), 0.5 * (p[b] + p[bn])])
        # One call of h for the bars and the sliding nodes' boundary bars (h is pointwise; a
        # repair round's sub-mesh pays the call, not the points).
        if len(mid):
            values = np.asarray(self.h(mid), dtype=np.float64)
            ld[bars] = values[:len(bars)]
            if len(rows):
                self._ld_slide[0][rows] = values[len(bars):len(bars) + len(rows)]
                self._ld_slide[1][rows] = values[len(bars) + len(rows):]
        # hbar of the moved nodes and of their neighbours (whose bars these are too), then
        # their stability limits.
        k.threaded_renew_sizes(p, near, indptr, adj, eid, ld, DT, STABLE_GAIN, graded, self.hbar,
                               self._damp)
        self._inside_depth(nodes[self._is_free[nodes]])
        self.anchor[nodes] = p[nodes]
        self.retriangulations += 1

    def run(self, force: Literal["attractive", "spring"], steps: int, tail: int = 0) -> bool:
        """Up to ``steps`` Euler steps; True when the convergence test was met.

        With ``tail > 0`` the run also stops (False, ``in_tail`` set) at the first step in
        which at most ``tail`` nodes, but some, moved more than ``DPTOL * hbar``: the rest of
        the mesh is at rest, and the caller relaxes those nodes locally (:func:`_settle`).
        """
        p, n, k = self.p, len(self.p), self._k
        attraction = ATTRACTION if force == "attractive" else 0.0  # Eq. 3.4: f / lc = -0.2 / ld
        self.in_tail = False
        if self._stale:  # final() updated the lists only: renew what depends on positions
            self._connect(rebuild=False)
            self._stale = False
        # A small node list steps in one kernel call (forces, the move, the near nodes' anchor
        # test: kernels.smooth.step_free); a large one hands chunks to threads.
        fused = not k.threads.worth(len(self._moving))
        ok = np.empty(len(self._free), dtype=np.bool_)
        if fused and self._kernel_boundary is not None:
            return self._run_compiled(force, attraction, steps, tail, ok)
        for _ in range(steps):
            if self.iterations + self.weight > self.cap + 1e-9:
                return False
            self.iterations += self.weight
            indptr, adj, eid, ld = self._csr
            if fused:
                c, worst, at, drift, count, asks = k.step_free(
                    p, self._moving, self._free, indptr, adj, eid, ld, attraction, self._total,
                    self._damp, self.hbar, DT, STEP_CAP, self._deep, self.anchor, self._d0,
                    self._reach, self._cand, self._near, ok, DPTOL)
            else:
                k.threaded_bar_forces(p, self._moving, indptr, adj, eid, ld, attraction,
                                      self._total, self._damp)
                c, worst, at, drift, count = k.threaded_advance(
                    p, self._free, self._total, self.hbar, DT, STEP_CAP, self._deep, self.anchor,
                    self._cand, self._near, DPTOL)
                # A node still within its anchor's depth of its anchor is inside (half of it
                # for a d that is not an exact distance: the factor 2 DEEP allows).
                asks = k.near_inside(self._cand, self._near, c, self.anchor, self._d0, self._reach,
                                     ok) if c else 0
            if c:
                # Nodes near the boundary: a step that would leave the domain is not taken.  The
                # sdf is asked only for the few that went further than the anchor test allows,
                # the costly call on an outline.
                if asks:
                    rest = np.flatnonzero(~ok[:c])
                    ok[rest] = ~(self.domain.sdf(self._cand[rest]) > 0)
                worst, at, drift, count = k.take_near(p, self._near, self._cand, c, ok, self.hbar,
                                                      self.anchor, DPTOL, worst, at, drift, count)
            if len(self._sl):
                b = self._sl[:, 0]
                mv = _slide(p, self._sl, self._total, self.hbar, self._ld_slide, self._slide_projector(b))
                worst, at, drift, count = k.fold_moves(b, mv, p, self.anchor, self.hbar, DPTOL,
                                                       worst, at, drift, count)
            worst = max(worst, 0.0)
            at = max(at, 0)
            self.unsettled = (float(p[at, 0]), float(p[at, 1]))
            report(self.callback, "smoothing", math.ceil(self.iterations), self.cap, nodes=n, max_move=worst,
                   force=force, moving=count)
            if worst < DPTOL:
                return True
            if count <= tail and self.iterations >= TAIL_AFTER:
                self.in_tail = True
                return False
            if drift > RETRIANGULATE:
                self.retriangulate()
        return False

    def _run_compiled(self, force: str, attraction: float, steps: int, tail: int,
                      ok: NDArray[np.bool_]) -> bool:
        """``run``'s steps in compiled calls (``kernels.smooth.run_steps``), each up to the next
        re-triangulation: the same steps, in the same order, with the same numbers, as the
        loop over kernels and the domain's methods.  With a callback, one step per call: it
        hears of every step, as from the loop."""
        k, p = self._k, self.p
        assert self._kernel_boundary is not None
        target, (kinds, shapes, origins, cat, offs) = self._kernel_boundary
        sl = np.ascontiguousarray(self._sl, dtype=np.int64)
        no_bars = np.zeros(0)
        left = steps
        per_call = steps if self.callback is None else 1
        while left > 0:
            # Read at every call: a rebuild of the lists (_connect) makes these arrays anew.
            indptr, adj, eid, ld = self._csr
            ld_prev, ld_next = self._ld_slide if len(sl) else (no_bars, no_bars)
            outcome, taken, self.iterations, worst, at, count = k.run_steps(
                p, self._moving, self._free, indptr, adj, eid, ld, attraction, self._total,
                self._damp, self.hbar, DT, STEP_CAP, self._deep, self.anchor, self._d0,
                self._reach, self._cand, self._near, ok, DPTOL, sl, ld_prev, ld_next, target,
                kinds, shapes, origins, cat, offs, self.iterations, self.weight, float(self.cap),
                min(left, per_call), tail, float(TAIL_AFTER), RETRIANGULATE)
            left -= taken
            if taken:
                self.unsettled = (float(p[at, 0]), float(p[at, 1]))
                report(self.callback, "smoothing", math.ceil(self.iterations), self.cap,
                       nodes=len(p), max_move=worst, force=force, moving=count)
            if outcome == k.RUN_CAP:
                return False
            if outcome == k.RUN_CONVERGED:
                return True
            if outcome == k.RUN_TAIL:
                self.in_tail = True
                return False
            if outcome == k.RUN_RETRIANGULATE:
                self.retriangulate()
        return False

    def final(self) -> IntArray:
        """The triangles made Delaunay for the current positions, and the node lists (CSR)
        updated to them; what depends on positions (ld, hbar, flags) is renewed only if the
        relaxation steps again (``_stale``): after the last step nothing reads it, and at a
        million nodes renewing it for every node that moved a little cost ~1 s."""
        if np.array_equal(self.anchor, self.p):
            return self.tri
        if self._active is not None:
            self.retriangulate(everywhere=True)
            return self.tri
        from .kernels.delaunay import flips_logged

        res, log = flips_logged(self.p, self._t32, self._nbr, self._con, self._vt,
                                np.empty(0, dtype=np.int32), True)
        if res < 0:
            self._from_scratch()
            return self.tri
        if res > 0 and self._relink(_flip_changes(log)) is None:
            self._connect(rebuild=True)
            return self.tri
        # The anchors move to the positions: d0 + drift stays an upper bound of d there.
        f = self._free
        self._d0[f] += np.hypot(*(self.p[f] - self.anchor[f]).T)
        self.anchor = self.p.copy()
        self._stale = True
        return self.tri

    def _relink(self, changes: _Changes) -> NDArray[np.int64] | None:
        """The node lists, bars and ``tri`` follow the change of triangles ``changes``
        (``kernels.smooth.flip_diff``, then ``flip_update``, in place); a constant h's ld of
        the new bars too.  Returns the new edges ``(k, 2)``, or None when that cannot be done
        (a row out of free slots), for a rebuild."""
        changed, removed, added = self._k.flip_diff(*changes)
        if len(removed) != len(added):
            return None
        indptr, adj, eid, ld = self._csr
        ids = self._k.flip_update(indptr, adj, eid, self._bars, removed, added)
        if len(ids) != len(removed):
            return None
        constant = getattr(self.h, "constant", None)
        if constant is not None:
            ld[ids] = float(constant)
        rows = np.asarray(changed, dtype=np.intp)
        self.tri[rows] = self._t32[rows]
        return np.asarray(added)


#: A change of some triangle rows: the rows (repeats allowed), the edges that went and the
#: edges that came, as node pairs with repeats (``kernels.smooth.flip_diff``).
_Changes = tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]


def _flip_changes(log: NDArray[np.int64]) -> _Changes:
    """The change made by the flips of ``log`` (``kernels.delaunay.flips_logged``)."""
    return np.ascontiguousarray(log[:, :2]).ravel(), log[:, 2:4].copy(), log[:, 4:6].copy()


def _row_changes(rows: IntArray, before: Int32Array, after: Int32Array) -> _Changes:
    """The change of the triangle ``rows`` from ``before`` to ``after`` (their contents).

    Only the rows that differ are listed: a patch of the slow tail holds ~10^5 rows, of which
    its flips changed a few hundred, and the sides of a row kept would cancel anyway."""

    def sides(t: Int32Array) -> NDArray[np.int64]:
        return np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]).astype(np.int64)

    differ = (before != after).any(axis=1)
    return np.asarray(rows, dtype=np.int64)[differ], sides(before[differ]), sides(after[differ])


def _with_nodes(nodes: IntArray, more: NDArray[np.int64]) -> IntArray:
    """``np.union1d(nodes, more)`` for ``nodes`` up to the whole mesh and a few ``more``: when
    ``nodes`` is sorted and distinct (a connectivity update's), they are put in their places
    instead of sorting the lot again."""
    if len(nodes) == 0 or not bool(np.all(nodes[1:] > nodes[:-1])):
        return np.union1d(nodes, more)
    extra = np.unique(more).astype(nodes.dtype)
    at = np.searchsorted(nodes, extra)
    present = nodes[np.minimum(at, len(nodes) - 1)] == extra
    return np.insert(nodes, at[~present], extra[~present])


def _stand_in(domain: Domain, p: FloatArray, walls: IntArray) -> Domain | None:
    """A polygon of ``domain``'s boundary that the kernels query (a B-rep), for a domain they
    cannot (a plain signed distance): None when the domain has a kernel form, or no walls.

    The plain function's own projection is Newton's method on d, about three calls of d per
    step of the sliding nodes: on the paper's cases 2-4x the time of the same mesh from a
    composed geometry, almost all of it in the repair rounds' patches, which step a handful
    of sliding nodes many times.  The polygon's vertices are points of the exact boundary:
    the domain's traced loops (the tracing its corners were found on, kept by the domain),
    each corner in place of its nearest vertex, then chords halved by their projected
    midpoints until each is within ``STAND_IN_SAG`` of the shortest wall segment from the
    curve.  Step 1 put the sliding nodes on the exact boundary, within that of the polygon,
    and ``smooth`` projects them back onto it after the repair.
    """
    if domain.kernel_boundary() is not None or len(walls) == 0:
        return None
    from .geometry.brep import BRep
    from .geometry.tracing import grid_spacing

    ends = p[walls]
    shortest = float(np.hypot(*(ends[:, 0] - ends[:, 1]).T).min())
    sag = STAND_IN_SAG * shortest
    traced = domain.boundary_loops(grid_spacing(domain.bbox, np.inf))
    # No piece of zero length (two traced vertices projected onto one point: a corner's
    # nearest vertex would be either, and the polygon would fold back there).
    tiny = 1e-9 * domain.diameter
    loops = [np.asarray(loop, dtype=float) for loop in traced]
    loops = [loop[np.hypot(*(loop - np.roll(loop, 1, axis=0)).T) > tiny] for loop in loops]
    loops = [loop for loop in loops if len(loop) >= 3]
    if not loops:
        return None
    corners = domain.corners()
    if len(corners):
        # First, so that the chords next to a corner lie along its sides.
        from scipy.spatial import cKDTree

        a = np.concatenate(loops)
        nearest = cKDTree(a).query(corners)[1]
        a[nearest] = corners
        is_corner = np.zeros(len(a), dtype=bool)
        is_corner[nearest] = True
        cuts = np.cumsum([len(loop) for loop in loops])[:-1]
        # A traced vertex just past a corner, now the corner's neighbour, can turn the polygon
        # back on itself: a vertex that is no corner and turns by more than 90 degrees goes
        # (on a curve the tracing resolves, its vertices turn by a few degrees).
        loops = [_unfolded(loop, mark) for loop, mark in zip(np.split(a, cuts), np.split(is_corner, cuts),
                                                             strict=True)]
        loops = [loop for loop in loops if len(loop) >= 3]
        if not loops:
            return None
    loops = _oriented(domain, _halved(domain, loops, sag))
    p0 = np.concatenate(loops)
    p1 = np.concatenate([np.roll(loop, -1, axis=0) for loop in loops])
    poly = BRep(p0, p1, np.zeros_like(p0), np.zeros(len(p0)), np.cumsum([0] + [len(loop) for loop in loops]))
    # Every wall node (on the exact boundary) must be within the sag of the polygon: a loop the
    # corners' tracing did not see (a hole smaller than its grid, which Step 1's finer one
    # found) or lost would send its nodes to another loop.  Then no stand-in.
    on = np.unique(walls)
    if np.abs(poly.sdf(p[on])).max() > 10 * sag:
        return None
    return poly


def _halved(domain: Domain, loops: list[FloatArray], sag: float) -> list[FloatArray]:
    """``loops`` (vertices on the boundary) with every chord farther than ``sag`` from the curve
    halved by its midpoint projected onto the boundary, again on the halves, at most
    ``STAND_IN_HALVINGS`` times; only the chords not yet within ``sag`` are projected, in one
    call of the domain per halving."""
    loops = list(loops)
    pending = [np.ones(len(loop), dtype=bool) for loop in loops]
    for _ in range(STAND_IN_HALVINGS):
        rows = [np.flatnonzero(pk) for pk in pending]
        if not any(len(r) for r in rows):
            break
        a = np.concatenate([loop[r] for loop, r in zip(loops, rows, strict=True)])
        b = np.concatenate([np.roll(loop, -1, axis=0)[r] for loop, r in zip(loops, rows, strict=True)])
        mid = domain.project(0.5 * (a + b))
        ab, am = b - a, mid - a
        off = np.abs(ab[:, 0] * am[:, 1] - ab[:, 1] * am[:, 0]) / np.maximum(np.hypot(*ab.T), 1e-300)
        at = 0
        for k, (loop, r) in enumerate(zip(loops, rows, strict=True)):
            split = np.zeros(len(loop), dtype=bool)
            split[r] = off[at:at + len(r)] > sag
            m = mid[at:at + len(r)][split[r]]
            at += len(r)
            place = np.arange(len(loop)) + np.concatenate([[0], np.cumsum(split)[:-1]])
            out = np.empty((len(loop) + len(m), 2))
            out[place] = loop
            out[place[split] + 1] = m
            flags = np.zeros(len(out), dtype=bool)
            flags[place[split]] = True
            flags[place[split] + 1] = True
            loops[k], pending[k] = out, flags
    return loops


def _oriented(domain: Domain, loops: list[FloatArray]) -> list[FloatArray]:
    """``loops`` turned so that the domain is on the left of every chord: each loop's longest
    chord's left normal against d's gradient at its foot on the boundary (a local test; a
    probe point off the chord could land across a slit narrower than its offset)."""
    mids, normals = [], []
    for loop in loops:
        t = np.roll(loop, -1, axis=0) - loop
        k = int(np.argmax(np.hypot(*t.T)))
        mids.append(loop[k] + 0.5 * t[k])
        normals.append((-t[k, 1], t[k, 0]))
    grad = domain.gradient(domain.project(np.array(mids)))
    flip = np.einsum("ij,ij->i", grad, np.array(normals)) > 0
    return [loop[::-1] if f else loop for loop, f in zip(loops, flip, strict=True)]


def _unfolded(loop: FloatArray, keep: NDArray[np.bool_]) -> FloatArray:
    """``loop`` without its vertices not in ``keep`` whose two chords turn by more than 90
    degrees (at most three passes: dropping one can make its neighbour turn)."""
    for _ in range(3):
        u = loop - np.roll(loop, 1, axis=0)
        v = np.roll(loop, -1, axis=0) - loop
        back = (np.einsum("ij,ij->i", u, v) < 0) & ~keep
        if not back.any() or len(loop) - int(back.sum()) < 3:
            break
        loop, keep = loop[~back], keep[~back]
    return loop


def _inside_reach(domain: Domain) -> float:
    """The fraction of its depth |d| a point may move and still be inside: all of it (a hair
    less) when d is an exact distance, half when it is not (the factor 2 ``DEEP`` allows)."""
    return 1.0 - 1e-9 if getattr(domain, "exact_distance", False) is True else 0.5


def _slide(
    p: FloatArray,
    slide: IntArray,
    total: FloatArray,
    hbar: FloatArray,
    ld: tuple[FloatArray, FloatArray],
    project: Callable[[FloatArray], FloatArray],
) -> FloatArray:
    """Move the sliding boundary nodes (rows ``(node, previous, next)`` of ``slide``) in place.

    Each takes its Euler step, is put back on the boundary by ``project`` (Eq. 3.2) and keeps
    the result only where the barriers allow it.  ``total`` holds the bar forces on the nodes,
    ``ld`` the desired lengths of the bars to the previous and next boundary neighbours.
    Returns each node's move over its hbar.
    """
    from .kernels.smooth import slide_accept, slide_targets

    # Half the node's total force, half its two boundary bars (a 1-D spring along the boundary,
    # as in balancing): all of the former lets the interior squeeze boundary edges to 0.7 h;
    # only the latter leaves bad triangles at the boundary.  Then the barriers of Algorithm 3:
    # a step shorter than half the gap to either neighbour can neither overtake it nor jump
    # across a corner to another curve; the projection must keep the node on its own stretch
    # of boundary, next to the two segments it had, not across a slit or notch narrower than
    # the step (there the nearest boundary point is on the opposite wall; a curved boundary
    # strays from the two segments by about its own sagitta, a straight wall by nothing); nor
    # may a step close a gap below half of h (at a sharp corner the interior pushes boundary
    # nodes into the tip, where they would crowd without end).
    target = np.empty((len(slide), 2))
    slide_targets(p, slide, total, hbar, ld[0], ld[1], DT, target)
    cand = np.ascontiguousarray(project(target), dtype=np.float64)
    moved = np.empty(len(slide))
    slide_accept(p, slide, hbar, cand, moved)
    return moved


def smooth(
    domain: Domain,
    h: SizeFn,
    points: FloatArray,
    *,
    n_fixed: int,
    sliding: IntArray | None = None,
    walls: IntArray | None = None,
    smoothing: Smoothing = "hybrid",
    max_iterations: int | None = None,
    callback: Callback | None = None,
    interfaces: Interfaces | None = None,
) -> SmoothResult:
    """Smooth the nodes (Step 3).

    Parameters
    ----------
    domain : Domain
    h : callable
        Validated size function.
    points : (n, 2) array
        Initial nodes; the first ``n_fixed`` never move (sliding ones excepted).
    sliding : (k, 3) int array, optional
        Rows ``(node, previous, next)``: boundary nodes free to slide along the boundary, with
        their neighbours on it.
    walls : (k, 2) int array, optional
        The boundary segments of Step 1; at the end, nodes inside their diametral circles are
        pushed out so that the final Delaunay triangulation contains them (see ``_conform``).
    smoothing : {"hybrid", "attractive"}
        See the module documentation.
    max_iterations : int, optional
        Cap on Euler steps over all phases, default ``MAX_ITERATIONS``.
    interfaces : Interfaces, optional
        Interior curves: their sliding nodes (in ``sliding``) stay on their own curve and their
        segments become mesh edges (see :class:`Interfaces`).

    Returns
    -------
    SmoothResult
    """
    cap = MAX_ITERATIONS if max_iterations is None else int(max_iterations)
    p = np.array(points, dtype=float, copy=True)
    slide = np.zeros((0, 3), dtype=np.intp) if sliding is None else np.asarray(sliding, np.intp)
    if smoothing == "attractive":
        slide = slide[:0]  # the paper keeps boundary nodes where Step 1 put them
    wall = np.zeros((0, 2), dtype=np.intp) if walls is None else np.asarray(walls, np.intp)
    # The stage starts now: the first triangulation takes seconds at a million nodes.
    report(callback, "smoothing", 0, cap, nodes=len(p))
    # The free nodes renumbered along a Hilbert curve, and the triangles listed by their lowest
    # node (``_set_triangles``): mesh neighbours are then near each other in memory, which the
    # kernels' gathers (forces, neighbour lists, flips) need at a million nodes.  Injection
    # numbers nodes front by front, and the triangulation lists triangles in the randomized
    # order of insertion.
    kept = np.arange(len(p))
    if len(p) - n_fixed > 1:
        from .kernels.delaunay import hilbert_order

        kept[n_fixed:] = n_fixed + hilbert_order(p[n_fixed:])
        p = p[kept]
    # A boundary the kernels cannot query (a plain d(p)) is stepped against a fine polygon of
    # it, compiled; the boundary nodes are put back on the exact boundary at the end.
    stand_in = _stand_in(domain, p, wall) if len(slide) else None
    project = None if interfaces is None else interfaces.projector(stand_in or domain)
    relax = _Relaxation(stand_in or domain, h, p, n_fixed, slide, wall, callback, cap, project=project)
    if cap == 0 or len(p) == n_fixed:
        converged = True
    elif smoothing == "attractive":
        converged = relax.run("attractive", cap)
    else:
        relax.run("attractive", ATTRACTIVE_ITERATIONS)
        tail = max(TAIL_MIN, int(TAIL_FRACTION * len(p)))
        converged = relax.run("spring", cap, tail=tail)
        for k in range(TAIL_ROUNDS):
            if converged or not relax.in_tail:
                break
            if k == TAIL_WHOLE and relax.run("spring", TAIL_WHOLE_STEPS):
                converged = True
                break
            converged = _settle(relax) or relax.run("spring", cap, tail=tail)
        if not converged and relax.in_tail:
            converged = relax.run("spring", cap)
    polish = converged and smoothing == "hybrid" and cap > 0 and len(p) > n_fixed
    if polish:
        curves = None if interfaces is None else interfaces.segments
        p, tri, kept, iterations, triangulations = _repair(relax, kept, curves)
    else:
        tri = relax.final()
        p, iterations, triangulations = relax.p, relax.iterations, relax.retriangulations
    # Sub-mesh steps count in proportion (see _Relaxation.iterations); whole steps reported.
    steps = math.ceil(iterations - 1e-9)
    # Repair rounds share the iteration cap: a run that reached it has not converged.
    if polish and steps >= cap:
        converged = False
    p, tri, extra = _conform(domain, p, tri, n_fixed, wall)
    triangulations += extra
    n_pre = len(p)
    p, tri, wall, origin, extra = _recover(domain, h, p, tri, n_fixed, wall)
    triangulations += extra
    iseg = np.zeros((0, 2), dtype=np.intp)
    igroup = np.zeros(0, dtype=np.intp)
    if interfaces is not None and len(interfaces.segments):
        p, tri, iseg, igroup, node_group, extra = _recover_interfaces(
            domain, h, p, tri, n_fixed, n_pre, wall, interfaces)
        triangulations += extra
        project = interfaces.projector(stand_in or domain, node_group)
    kept = np.concatenate([kept, np.full(len(p) - len(kept), -1)])
    if polish:
        movable = np.arange(len(p)) >= n_fixed
        movable[slide[:, 0]] = True
        on_boundary = np.zeros(len(p), dtype=bool)
        on_boundary[wall.ravel()] = True
        on_boundary[iseg.ravel()] = True
        on_boundary[slide[:, 0]] = True
        p = _optimize(stand_in or domain, p, tri, movable, on_boundary, np.concatenate([wall, iseg]),
                      project)
    if stand_in is not None:
        # Back onto the exact boundary (they are within the polygon's sag of it), and made
        # Delaunay again around them: the sliding nodes, and those recovery added on walls
        # (the quality pass moved them along the polygon).
        on = np.unique(wall.ravel())
        on = on[(on >= n_fixed) | np.isin(on, slide[:, 0])]
        p = p.copy()
        p[on] = domain.project(p[on])
        tri = _made_delaunay(domain, p, tri, wall, near=on)
    # Drop nodes that no triangle uses (the triangulation leaves out coincident points, for example).
    used = np.zeros(len(p), dtype=bool)
    used[tri.ravel()] = True
    remap = np.cumsum(used) - 1
    # A segment whose node is unused is lost; it stays in the list (pointing at -1) so that
    # the mesh's own check reports it.
    out_walls = np.where(used[wall], remap[wall], -1)
    out_iseg = np.where(used[iseg], remap[iseg], -1)
    return SmoothResult(p[used], remap[tri], kept[used], steps, bool(converged), triangulations,
                        out_walls, origin, relax.unsettled, out_iseg, igroup)


def _settle(relax: _Relaxation) -> bool:
    """Relax the few nodes still moving (the slow tail of the spring) on a sub-mesh.

    Once at most ``TAIL_FRACTION`` of the nodes move more than ``DPTOL * hbar`` in a step, a
    global step costs the whole mesh for a handful of nodes.  One more global step finds them;
    the nodes within ``TAIL_RING`` edges of them then take spring steps on their own sub-mesh
    (:func:`_patch`, the rest of the mesh held) until they are at rest, and the result
    becomes the mesh's.  Returns True when that global step already met the convergence test.
    """
    before = relax.p.copy()
    if relax.run("spring", 1):
        return True
    if relax.iterations + 1 > relax.cap:
        return False
    moving = np.flatnonzero(np.hypot(*(relax.p - before).T) > DPTOL * relax.hbar)
    if len(moving) == 0:
        return False
    local = _patch_local(relax, relax.p, relax.tri, moving.astype(np.int64), relax.iterations,
                         ring=TAIL_RING, steps=TAIL_STEPS, csr=relax._csr[:2])
    if local is None:
        # A flip met an inverted triangle: the same steps on the whole mesh.
        p, tri, steps, extra = _patch_whole(relax, relax.p, relax.tri, moving.astype(np.int64),
                                            relax.iterations, TAIL_RING, TAIL_STEPS)
        relax.p[:] = p
        relax.iterations += steps
        relax.retriangulations += extra
        relax._set_triangles(tri)
        return False
    state, nodes, rows = local
    relax.iterations += state.iterations - relax.iterations
    relax.retriangulations += state.retriangulations
    relax.p[nodes] = state.p
    if len(state.tri) != len(rows):  # flips keep the count; anything else: rebuild
        in_patch = np.zeros(len(relax.tri), dtype=bool)
        in_patch[rows] = True
        relax._set_triangles(np.concatenate([relax.tri[~in_patch], nodes[state.tri]]))
        return False
    # The patch only flipped (its hull stayed): its triangles replace its rows, and the node
    # lists are updated in place from the flips' edge differences, as after a local
    # re-triangulation; a whole-mesh rebuild costs ~1 s at 1e6 nodes.
    from .kernels.mesh import renew_neighbours

    old_rows = relax._t32[rows]
    relax._t32[rows] = nodes[state.tri].astype(np.int32)
    renew_neighbours(relax._t32, relax._nbr, rows)
    relax._vt[relax._t32[rows].ravel()] = np.repeat(rows.astype(np.int32), 3)
    moved = nodes[state._moving]
    if not relax._flipped(_row_changes(rows, old_rows, relax._t32[rows]), moved.astype(np.intp)):
        relax._set_triangles(relax._t32.astype(np.intp))
    return False


def _repair(
    relax: _Relaxation, kept: IntArray, curves: IntArray | None = None
) -> tuple[FloatArray, IntArray, IntArray, float, int]:
    """Repair rounds (:func:`_repair_rounds`) on the part of the mesh around its bad triangles.

    The bad triangles are few and local; the rounds' bookkeeping (edits, flips, patches,
    quality) costs what the mesh they see costs.  So they see a sub-mesh: every triangle
    within ``REPAIR_REACH + REPAIR_BAND`` edges of a bad triangle's nodes.  Its free nodes
    within ``REPAIR_REACH`` edges may move, be split or collapsed; the band around them stays
    (it is numbered among the sub-mesh's fixed nodes), so the triangles outside never change
    and the sub-mesh's hull is never flipped.  The result is stitched back: surviving nodes
    keep their order, the rounds' new nodes come last.  On a million-node square this takes
    the rounds from about 15 s (ten rounds of whole-mesh arrays) to a fraction of a second.

    ``curves``: the interior curves' segments (:class:`Interfaces`), which, like the
    boundary's, a repair never splits.

    Returns the points, triangles and ``kept`` map, and the total iterations and
    triangulations spent.
    """
    from .kernels.repair import stitch, sub_mesh_of

    tri = relax.final()
    p = relax.p
    # relax.final() left the CSR adjacency of ``tri`` (the last connectivity update).  The
    # sub-mesh is cut in one compiled call (kernels.repair.sub_mesh_of).
    indptr, adj = relax._csr[0], relax._csr[1]
    tri = np.ascontiguousarray(tri, dtype=np.int64)
    no_pairs = np.zeros((0, 2), dtype=np.int64)
    nodes, n_boundary, n_fixed, inner, t32, nbr, slide, walls, inner_curves, outer_q = sub_mesh_of(
        p, tri, indptr, adj, float(REPAIR_Q), REPAIR_REACH, REPAIR_BAND, relax.n_fixed,
        np.ascontiguousarray(relax.slide, dtype=np.int64), np.ascontiguousarray(relax.walls, dtype=np.int64),
        no_pairs if curves is None else np.ascontiguousarray(curves, dtype=np.int64))
    if len(nodes) == 0:
        return p, relax.tri, kept, relax.iterations, relax.retriangulations
    segments = np.concatenate([walls, inner_curves]) if len(inner_curves) else walls
    sub = _Relaxation(relax.domain, relax.h, p[nodes], n_fixed, slide, walls, relax.callback,
                      relax.cap, tri=t32, project=_Renumbered(relax.project, nodes), patch=True,
                      total=relax.total, nbr=nbr)
    sub.iterations = relax.iterations
    sp, stri, skept, iterations, triangulations = _repair_rounds(
        sub, np.arange(len(nodes)), n_boundary, segments, float(outer_q))
    triangulations += relax.retriangulations - 1  # the sub-mesh's own set-up is not one
    if sp is sub.p and stri is sub.tri:
        return p, relax.tri, kept, iterations, triangulations
    # Stitch: old nodes that survive keep their order, the rounds' new nodes come last.
    out, out_tri, out_kept = stitch(p, tri, inner, np.ascontiguousarray(kept, dtype=np.int64), nodes,
                                    sp, np.ascontiguousarray(stri, dtype=np.int64),
                                    np.ascontiguousarray(skept, dtype=np.int64))
    return out, out_tri, out_kept, iterations, triangulations


def _repair_rounds(
    relax: _Relaxation, kept: IntArray, n_boundary: int, segments: IntArray, outer_q: float = np.inf
) -> tuple[FloatArray, IntArray, IntArray, float, int]:
    """Collapse or split the worst edge of bad triangles; keep the best round by q_min, in each
    connected part of the sub-mesh on its own.

    Returns the points, triangles and ``kept`` map of the result, and the total iterations and
    triangulations spent.  ``n_boundary``: the first nodes of ``relax`` that are fixed in the
    whole mesh (the band around the sub-mesh, fixed only here, comes after them);
    ``segments``: the boundary and interior curve segments, which are never split.

    A triangle whose three nodes are fixed cannot change by moving nodes or collapsing edges;
    if it is bad and its longest edge is a chord between two boundary nodes (not a segment),
    that chord is split (:func:`_chords`): a flat cap at a blunt corner or across a channel one
    triangle wide gets a free node.  The other fixed triangles (a sharp tip, whose q is bounded
    by its angle) are frozen: they are not repaired, and one that is its part's worst is left
    out of the part's score (``REPAIR_EXCUSED``), so the rounds can still better the rest.

    A round that does not raise q_min is still the start of the next:
    measured on the paper's cases, later rounds often recover.  Each round relaxes only the
    patch of triangles around its ``REPAIR_RING``-ring of changed nodes (:func:`_patch`), so
    its cost follows the size of the change, not of the mesh.  A round is scored on the
    triangulation its relaxation last used (nodes moved less than ``RETRIANGULATE * hbar``
    since); only the result is made Delaunay again, by flips from that triangulation.

    ``relax`` is a sub-mesh (:func:`_repair`), often of several parts that share no node (the
    bad triangles of a large mesh lie in clusters far apart).  The parts change independently
    (edits and flips never cross from one to another), so each part keeps its own best round:
    kept whole, the rounds lost everything on a large mesh as soon as one edit somewhere made
    a worse triangle (a 1e5-node graded disc: start 0.71, every round 0.49-0.62 somewhere).
    Each part is scored by its own q_min (the rest of the mesh, ``outer_q``, does not change).
    A flip that meets an inverted triangle (which only a triangulation of the whole mesh could
    undo) ends the rounds, and so does a round that comes back to an earlier one (no better,
    the same triangles, the nodes within ``REPAIR_SAME * h``): the rounds are cycling.
    """
    from .kernels.repair import apply_edits, components, frozen_key_rows, round_state

    tri = relax.final()
    p, cur_kept = relax.p, kept
    iterations, triangulations = relax.iterations, relax.retriangulations
    if len(tri) == 0:
        return p, tri, kept, iterations, triangulations
    # The bookkeeping of a round is compiled (kernels.repair): on a small case a round's sub-mesh
    # has a few hundred triangles, and its NumPy lines cost more than the work.
    label, n_parts = components(np.ascontiguousarray(tri, dtype=np.int64), len(p))
    seg_keys = _keys(segments)
    n_fixed = relax.n_fixed

    pinned = np.zeros(n_parts, dtype=np.bool_)
    excused = np.zeros(0, dtype=np.int64)

    def state(p: FloatArray, tri: NDArray[np.int64]) -> tuple[Any, ...]:
        """q, chords, part scores and the bad triangles of a round (``round_state``)."""
        return round_state(p, tri, n_boundary, n_fixed, seg_keys, _KEY, label, n_parts, pinned,
                           float(REPAIR_Q), excused)

    tri = np.ascontiguousarray(tri, dtype=np.int64)
    rounds: list[tuple[FloatArray, IntArray, IntArray, IntArray]] = [(p, tri, cur_kept, label)]
    q, chord, changeable, best, best_changeable, bad = state(p, tri)
    # A frozen triangle (three fixed nodes and no chord: a sharp tip) worse than every
    # triangle a round can change in its part would be the part's q_min whatever a round
    # does, so no round could be kept for the part, and the rest of it went unrepaired (the
    # strip behind a 6.5-degree spike, q 0.57).  Such triangles are left out of the scores;
    # every other triangle counts, frozen ones too: flips after an edit can make new ones.
    # A part with more than REPAIR_EXCUSED bad triangles keeps its tips in its score and is
    # left alone, as before: a round's thousands of edits there always make a worse triangle
    # somewhere (the 20,000-vertex outline: six rounds, none better, 3 s).
    part_of = label[tri[:, 0]]
    small = np.bincount(part_of[bad], minlength=n_parts) <= REPAIR_EXCUSED
    frozen = ~changeable & (q < best_changeable[part_of]) & small[part_of]
    if frozen.any():
        excused = np.unique(frozen_key_rows(tri[frozen], n_fixed))
        _, chord, _, best, _, bad = state(p, tri)
    pinned = best < best_changeable
    bad = bad[~pinned[label[tri[bad, 0]]]]
    best_round = np.zeros(n_parts, dtype=np.intp)
    last: FloatArray | None = None
    stalled = 0
    seen = {_topology(tri): p}
    for _ in range(REPAIR_ROUNDS):
        if len(bad) == 0:
            break
        ops = _choose_repairs(relax, p, tri, bad, chord)
        if ops is None:
            break
        collapse, split = ops
        # Collapse (a, b): b disappears; a moves to the midpoint unless it is fixed.  A split
        # node joins its edge's part.  Only the nodes near the change move: the k-ring of the
        # nodes the operations touched (in the new numbering; the dropped node's neighbours
        # are the keeper's now).
        p, tri, cur_kept, label, touched = apply_edits(
            p, tri, cur_kept, label, np.ascontiguousarray(collapse, dtype=np.int64),
            np.ascontiguousarray(split, dtype=np.int64), n_fixed)
        try:
            tri = _made_delaunay(relax.domain, p, tri, relax.walls, relax._patch, near=touched)
            p, tri, steps, extra = _patch(relax, p, tri, touched, iterations)
        except _PatchInverted:
            break
        tri = np.ascontiguousarray(tri, dtype=np.int64)
        iterations += steps
        triangulations += extra
        # Fixed nodes come first and are never dropped: the segments keep their numbers.
        _, chord, _, score, _, bad = state(p, tri)
        # Later rounds work on copies: every round's arrays stay as they are.
        rounds.append((p, tri, cur_kept, label))
        better = score > best
        best[better] = score[better]
        best_round[better] = len(rounds) - 1
        # Rounds that leave every part's worst triangle exactly as it was, and none better
        # than its best, are stuck on triangles they cannot change (one an earlier round made
        # at fixed nodes): after REPAIR_STALL of them in a row the rest would be thrown away
        # too.
        same = last is not None and not better.any() and np.array_equal(score, last)
        stalled = stalled + 1 if same else 0
        last = score
        if stalled >= REPAIR_STALL:
            break
        # A round that is no better and whose triangles are an earlier round's (the same
        # node numbers, the same triangles), its nodes within REPAIR_SAME * h of where they
        # were then, has come back where the rounds were: a split undone by a collapse, the
        # next rounds would repeat the cycle.
        if not better.any():
            key = _topology(tri)
            if key in seen:
                moved = np.hypot(*(p - seen[key]).T)
                far = moved > 0
                if not far.any() or np.all(moved[far] <= REPAIR_SAME * relax.h(p[far])):
                    break
            seen[key] = p
    if not best_round.any():
        return relax.p, relax.tri, kept, iterations, triangulations
    # Each part from its own best round; the nodes of a part are all in its triangles.
    parts_p, parts_tri, parts_kept = [], [], []
    offset = 0
    for r in np.unique(best_round).tolist():
        rp, rtri, rkept, rlabel = rounds[r]
        take = (best_round == r)[rlabel]
        renumber = np.cumsum(take) - 1 + offset
        parts_p.append(rp[take])
        parts_kept.append(rkept[take])
        parts_tri.append(renumber[rtri[take[rtri[:, 0]]]])
        offset += int(take.sum())
    p, tri, out_kept = np.concatenate(parts_p), np.concatenate(parts_tri), np.concatenate(parts_kept)
    try:
        tri = _made_delaunay(relax.domain, p, tri, relax.walls, relax._patch)
    except _PatchInverted:
        # The result cannot be made Delaunay within its sub-mesh: keep the mesh unrepaired.
        return relax.p, relax.tri, kept, iterations, triangulations
    triangulations += 1
    return p, tri, out_kept, iterations, triangulations


def _topology(tri: IntArray) -> bytes:
    """The triangles ``tri`` as a set (each sorted, then the rows: ``kernels.repair.
    canonical``), as bytes to compare."""
    from .kernels.repair import canonical

    return bytes(canonical(np.ascontiguousarray(tri, dtype=np.int64)).tobytes())


class _PatchInverted(Exception):
    """A patch's flips met an inverted triangle: it cannot be re-triangulated on its own."""


def _patch(
    relax: _Relaxation, p: FloatArray, tri: IntArray, touched: NDArray[np.int64], iterations: float,
    ring: int = REPAIR_RING, steps: int = REPAIR_STEPS,
) -> tuple[FloatArray, IntArray, float, int]:
    """Up to ``steps`` spring steps on the nodes within ``ring`` edges of ``touched``, on a
    sub-mesh.

    The sub-mesh holds every triangle with a node within ``ring + 1`` edges: the moving
    nodes, and a ring of nodes that stay.  Every edge whose empty-circle test involves a moving
    node is then inside it, so its flips (its hull is never flipped) keep the whole mesh
    Delaunay, and the rest of the mesh is left as it is.  If a flip meets an inverted triangle
    (a re-triangulation from scratch would have to be global) the round relaxes on the whole
    mesh instead.  Returns the points, triangles, steps and triangulations.
    """
    local = _patch_local(relax, p, tri, touched, iterations, ring, steps)
    if local is None:
        return _patch_whole(relax, p, tri, touched, iterations, ring, steps)
    from .kernels.repair import patch_merge

    state, nodes, rows = local
    out, out_tri = patch_merge(p, np.ascontiguousarray(tri, dtype=np.int64), rows, nodes, state.p,
                               np.ascontiguousarray(state.tri, dtype=np.int64))
    return out, out_tri, state.iterations - iterations, state.retriangulations


def _patch_whole(
    relax: _Relaxation, p: FloatArray, tri: IntArray, touched: NDArray[np.int64], iterations: float,
    ring: int, steps: int,
) -> tuple[FloatArray, IntArray, float, int]:
    """:func:`_patch` on the whole mesh, for when the sub-mesh's flips met an inverted triangle:
    the nodes within ``ring`` edges of ``touched`` step, re-triangulated from scratch if need
    be.  Returns the points, triangles, steps and triangulations."""
    from .kernels.smooth import adjacency, rings

    indptr, adj, _, _ = adjacency(len(p), np.ascontiguousarray(tri, dtype=np.int32), 0)
    active = rings(indptr, adj, touched, ring)
    whole = _Relaxation(relax.domain, relax.h, p, relax.n_fixed, relax.slide, relax.walls,
                        relax.callback, relax.cap, active=active, tri=tri, project=relax.project,
                        patch=relax._patch, total=relax.total)
    whole.iterations = iterations
    whole.run("spring", steps)
    return whole.p, whole.tri, whole.iterations - iterations, whole.retriangulations


def _patch_local(
    relax: _Relaxation, p: FloatArray, tri: IntArray, touched: NDArray[np.int64], iterations: float,
    ring: int, steps: int, csr: tuple[NDArray[np.int64], NDArray[np.int32]] | None = None,
) -> tuple[_Relaxation, IntArray, IntArray] | None:
    """The sub-mesh relaxation of :func:`_patch`: its state (numbered as ``nodes``, the mesh's
    nodes it holds) and the rows of ``tri`` it replaces, or None when a flip met an inverted
    triangle.  Flips keep the number of triangles, so ``state.tri`` has as many as ``rows``.
    ``csr``: the node lists ``(indptr, adj)`` of ``tri`` when the caller has them.  The patch
    is cut in one compiled call (``kernels.repair.patch_of``)."""
    from .kernels.repair import patch_of

    indptr, adj = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32)) if csr is None else csr
    rows, nodes, t32, nbr, active, slide, walls, n_fixed = patch_of(
        np.ascontiguousarray(tri, dtype=np.int64), len(p), indptr, adj,
        np.ascontiguousarray(touched, dtype=np.int64), ring,
        np.ascontiguousarray(relax.slide, dtype=np.int64),
        np.ascontiguousarray(relax.walls, dtype=np.int64), relax.n_fixed)
    try:
        state = _Relaxation(relax.domain, relax.h, p[nodes], n_fixed, slide, walls, relax.callback,
                            relax.cap, active=active, tri=t32, project=_Renumbered(relax.project, nodes),
                            patch=True, total=relax.total, nbr=nbr)
        state.iterations = iterations
        state.run("spring", steps)
    except _PatchInverted:
        return None
    return state, nodes, rows


def _neighbours32(t32: NDArray[np.int32], n: int) -> NDArray[np.int32]:
    """The flip kernel's neighbour table (int32, -1 on the hull) of the triangles ``t32``."""
    from .kernels.mesh import neighbours

    return np.asarray(neighbours(t32, n), dtype=np.int32)


def _made_delaunay(domain: Domain, p: FloatArray, tri: IntArray, walls: IntArray,
                   patch: bool = False, near: IntArray | None = None) -> IntArray:
    """``tri`` made Delaunay by Lawson flips (exact predicates; edges with one triangle stay),
    or the domain's triangulation from scratch when ``tri`` has an inverted or flat triangle
    (``_PatchInverted`` instead when ``tri`` is only part of the mesh: ``patch``).

    With ``near`` (nodes), the flips start from the triangles of those nodes only:
    the rest of ``tri`` was Delaunay and only they moved or were made (the repair's edits).
    The neighbour table and the flips are one compiled call (``kernels.repair.flip_near``)."""
    from .kernels.repair import flip_near

    start = np.zeros(0, dtype=np.int64) if near is None else np.asarray(near, dtype=np.int64)
    res, t32 = flip_near(p, np.ascontiguousarray(tri, dtype=np.int64), start, near is None)
    if res < 0:
        if patch:
            raise _PatchInverted
        return triangulate(domain, p, walls)
    return np.asarray(t32, dtype=np.intp)


def missing_walls(tri: IntArray, walls: IntArray) -> IntArray:
    """The boundary segments ``walls (k, 2)`` that are not edges of ``tri``."""
    if len(walls) == 0:
        return walls
    return walls[~_has_edges(tri, walls)]


def _conform(
    domain: Domain,
    p: FloatArray,
    tri: IntArray,
    n_fixed: int,
    walls: IntArray,
    rounds: int = CONFORM_ROUNDS,
    pinned: IntArray | None = None,
    interior: IntArray | None = None,
) -> tuple[FloatArray, IntArray, int]:
    """Recover boundary segments that Delaunay dropped.

    A segment is missing when a node lies in its diametral circle; such free nodes are pushed
    radially to 1.05 times the circle's radius and the nodes re-triangulated (at most
    ``rounds`` times; a round is kept only if it leaves fewer missing: a segment at a sharp
    corner or across a notch stays missing however its neighbours are pushed, and each round
    re-triangulates the whole mesh, ~0.4 s at 1e5 nodes; ``_recover`` takes what is left).
    Nodes in ``pinned`` (boundary nodes added by recovery) never move.  ``interior`` segments
    (interior curves) are recovered too but do not bound the domain.
    """
    from scipy.spatial import cKDTree

    count = 0
    required = walls if interior is None else np.concatenate([walls, interior])
    miss = missing_walls(tri, required)
    for _ in range(rounds):
        if len(miss) == 0:
            break
        a, b = p[miss[:, 0]], p[miss[:, 1]]
        mid, radius = 0.5 * (a + b), 0.5 * np.hypot(*(b - a).T)
        free = np.arange(n_fixed, len(p))
        if pinned is not None:
            free = np.setdiff1d(free, pinned)
        if len(free) == 0:
            break
        tree = cKDTree(p[free])
        pushed = p.copy()
        for c, r in zip(mid, radius, strict=True):
            inside = free[tree.query_ball_point(c, r)]
            if len(inside):
                v = pushed[inside] - c
                dist = np.maximum(np.hypot(*v.T), 1e-300)
                pushed[inside] = c + v * (1.05 * r / dist)[:, None]
        after = triangulate(domain, pushed, walls)
        count += 1
        left = missing_walls(after, required)
        if len(left) >= len(miss):
            # The pushed nodes encroach other segments (a thin part): keep the mesh as it was,
            # with fewer missing, for _recover.
            break
        p, tri, miss = pushed, after, left
    return p, tri, count


def _recover(
    domain: Domain, h: SizeFn, p: FloatArray, tri: IntArray, n_fixed: int, walls: IntArray
) -> tuple[FloatArray, IntArray, IntArray, IntArray, int]:
    """Make every boundary segment an edge of the mesh.

    A missing segment that a node *inside* the domain encroaches (a thin part, under-resolved)
    and that is longer than ``SPLIT_MIN * h`` gets a new boundary node at its projected
    midpoint (Ruppert's segment splitting): its halves are shorter and Delaunay keeps them, and
    the thin part gets smaller triangles.  Free nodes inside the halves' diametral circles are
    pushed out and the nodes re-triangulated, at most ``RECOVER_ROUNDS`` times.  What is then
    still missing (a segment encroached from outside, across a narrow notch; one at a sharp
    corner, where splitting would not end) is recovered by edge flips
    (``triangulation.constrained_triangles``), which always succeeds unless a node lies on the
    segment.  Returns the points, triangles, segments, the Step 1 segment each comes from, and
    the number of triangulations.
    """
    origin = np.arange(len(walls))
    n0 = len(p)
    count = 0
    for _ in range(RECOVER_ROUNDS):
        if len(walls) == 0:
            break
        lost = np.flatnonzero(~_has_edges(tri, walls))
        k = lost[_split_worthy(h, p, walls[lost])]
        if len(k) == 0:
            break
        a, b = walls[k, 0], walls[k, 1]
        new = domain.project(0.5 * (p[a] + p[b]))
        ids = len(p) + np.arange(len(k))
        p = np.concatenate([p, new])
        # Segment k becomes (a, new) followed by (new, b): the loops keep their order.
        head = walls.copy()
        head[k, 1] = ids
        key = np.concatenate([np.arange(len(walls), dtype=float), k + 0.5])
        order = np.argsort(key, kind="stable")
        walls = np.concatenate([head, np.stack([ids, b], axis=1)])[order]
        origin = np.concatenate([origin, origin[k]])[order]
        p, tri, _ = _conform(domain, p, triangulate(domain, p, walls), n_fixed, walls, rounds=1,
                             pinned=np.arange(n0, len(p)))
        count += 2
    if len(walls) and not _has_edges(tri, walls).all():
        tri = constrained_triangles(p, domain.sdf, walls)
        count += 1
    return p, tri, walls, origin, count


def _split_worthy(h: SizeFn, p: FloatArray, seg: IntArray, either_side: bool = False,
                  alive: NDArray[np.bool_] | None = None) -> NDArray[np.bool_]:
    """Segments longer than ``SPLIT_MIN * h`` with a node inside their diametral circle on the
    domain's side (left of a -> b; on either side for an interior curve)."""
    from scipy.spatial import cKDTree

    if len(seg) == 0:
        return np.zeros(0, dtype=bool)
    a, b = p[seg[:, 0]], p[seg[:, 1]]
    mid, length = 0.5 * (a + b), np.hypot(*(b - a).T)
    # h at the end nodes, which are on the boundary: h is never asked outside the domain.
    long_ = length > SPLIT_MIN * 0.5 * (h(a) + h(b))
    worthy = np.zeros(len(seg), dtype=bool)
    tree = cKDTree(p)
    for i in np.flatnonzero(long_):
        near = np.asarray(tree.query_ball_point(mid[i], 0.5 * length[i] * (1 - 1e-9)), dtype=np.intp)
        near = near[(near != seg[i, 0]) & (near != seg[i, 1])]
        if alive is not None:
            near = near[alive[near]]
        e, c = b[i] - a[i], p[near] - a[i]
        worthy[i] = len(near) > 0 if either_side else bool(np.any(e[0] * c[:, 1] - e[1] * c[:, 0] > 0))
    return worthy


def _recover_interfaces(
    domain: Domain,
    h: SizeFn,
    p: FloatArray,
    tri: IntArray,
    n_fixed: int,
    n_pre: int,
    walls: IntArray,
    itf: Interfaces,
) -> tuple[FloatArray, IntArray, IntArray, IntArray, IntArray, int]:
    """Make every interior curve segment an edge, as :func:`_recover` does for the boundary.

    A free node inside a missing segment's diametral circle (either side) is dropped rather
    than pushed out: it is closer than half a segment to the curve, so the nodes around it are
    crowded, and a node pushed to the circle makes a sliver with them.  A missing segment still
    encroached (by curve or boundary nodes) and longer than ``SPLIT_MIN * h`` is split at its
    midpoint projected onto its own curve; at most ``RECOVER_ROUNDS`` rounds.  Then every
    segment still missing, boundary or interior, is recovered by flips.  Dropped nodes are in
    no triangle (``smooth`` removes them).  Returns the points, triangles, segments, their
    curve, every node's curve and the number of triangulations.
    """
    from scipy.spatial import cKDTree

    seg, group = itf.segments.copy(), itf.group.copy()
    node_group = np.zeros(len(p), dtype=np.intp)
    node_group[: len(itf.node_group)] = itf.node_group
    alive = np.ones(len(p), dtype=bool)
    count = 0
    for _ in range(RECOVER_ROUNDS):
        miss = missing_walls(tri, seg)
        if len(miss) == 0:
            break
        a, b = p[miss[:, 0]], p[miss[:, 1]]
        free = np.flatnonzero(alive[n_fixed:n_pre]) + n_fixed
        was = alive.copy()
        centre, radius = 0.5 * (a + b), 0.5 * np.hypot(*(b - a).T) * (1 - 1e-9)
        if len(free) and len(miss) <= FEW_MISSING:
            # A few segments (the usual case): each circle against the free nodes directly; a
            # k-d tree of every free node cost ~20 ms at 1e5 nodes for two segments.
            q = p[free]
            for c, r in zip(centre, radius, strict=True):
                inside = np.flatnonzero(np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) <= r)
                alive[free[inside]] = False
        elif len(free):
            tree = cKDTree(p[free])
            for near in tree.query_ball_point(centre, radius):
                alive[free[np.asarray(near, dtype=np.intp)]] = False
        local = _without_nodes(p, tri, np.flatnonzero(was & ~alive))
        if local is None:
            tri = _triangulate_alive(domain, p, walls, alive)
            count += 1
        else:
            tri = local
        lost = np.flatnonzero(~_has_edges(tri, seg))
        k = lost[_split_worthy(h, p, seg[lost], either_side=True, alive=alive)]
        if len(k) == 0:
            continue
        a_, b_ = seg[k, 0], seg[k, 1]
        new = itf.project(0.5 * (p[a_] + p[b_]), group[k])
        ids = len(p) + np.arange(len(k))
        p = np.concatenate([p, new])
        alive = np.r_[alive, np.ones(len(k), dtype=bool)]
        node_group = np.concatenate([node_group, group[k]])
        head = seg.copy()
        head[k, 1] = ids
        seg = np.concatenate([head, np.stack([ids, b_], axis=1)])
        group = np.concatenate([group, group[k]])
        tri = _triangulate_alive(domain, p, walls, alive)
        count += 1
    required = np.concatenate([walls, seg])
    if not _has_edges(tri, required).all():
        idx = np.flatnonzero(alive)
        inv = np.full(len(p), -1, dtype=np.intp)
        inv[idx] = np.arange(len(idx))
        tri = idx[constrained_triangles(p[idx], domain.sdf, inv[walls], inv[seg])]
        count += 1
    return p, tri, seg, group, node_group, count


#: :func:`_recover_interfaces` looks for the nodes in at most this many missing segments'
#: circles directly, in more through a k-d tree of the free nodes.
FEW_MISSING = 8
#: :func:`_without_nodes` removes at most this many nodes one by one (each a pass over the
#: rows of the dropped nodes' stars); more are left to a triangulation from scratch.
LOCAL_REMOVALS = 32


def _without_nodes(p: FloatArray, tri: IntArray, drop: IntArray) -> IntArray | None:
    """``tri`` with the interior nodes ``drop`` removed, each one's star re-triangulated; None
    when that cannot be done locally (too many nodes, a star that is not a closed ring).

    Removing a vertex from a Delaunay triangulation changes only its star: the new triangles
    are those of the Delaunay triangulation of its neighbours that lie inside the star's
    polygon.  At 1e5 nodes with regions, the interfaces' recovery dropped 3 nodes and then
    triangulated the mesh from scratch (0.17-0.25 s); this costs one pass over the triangles
    (about 15 ms there).  The neighbours' triangulation is the exact kernel's; which of its
    triangles lie inside the star is decided in floating point on their centroids, so the
    result is checked: ``deg - 2`` triangles, with every polygon side among their edges (the
    incoming mesh is not Delaunay everywhere after a boundary segment's recovery by flips),
    else None.
    """
    if len(drop) > LOCAL_REMOVALS:
        return None
    if len(drop) == 0:
        return tri
    from .kernels.mesh import rows_with

    # Only the dropped nodes' stars change: work on those rows (one compiled pass over the
    # mesh; the rest is copied once, as the slices between them: ~9 -> ~1 ms at 1e5 nodes).
    mark = np.zeros(len(p), dtype=np.bool_)
    mark[drop] = True
    touch = rows_with(np.ascontiguousarray(tri, dtype=np.int64), mark)
    sub = tri[touch]
    cuts = np.r_[-1, touch, len(tri)]
    rest = [tri[a + 1:b] for a, b in zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True) if b > a + 1]
    for v in drop.tolist():
        rows = np.flatnonzero((sub == v).any(axis=1))
        star = sub[rows]
        # Each star triangle (v, a, b) counter-clockwise gives the polygon side a -> b.
        k = np.argmax(star == v, axis=1)
        r = np.arange(len(star))
        a, b = star[r, (k + 1) % 3], star[r, (k + 2) % 3]
        link = np.unique(a)
        deg = len(star)
        if deg < 3 or len(link) != deg or not np.array_equal(link, np.unique(b)):
            return None  # not a closed ring: v is on the hull of the mesh
        local = delaunay(p[link])
        # The star is star-shaped from v: a centroid is inside it when it is inside one of
        # its triangles (v, a, b), on the left of a -> b, b -> v and v -> a.
        c = p[link][local].mean(axis=1)[:, None, :]
        pv, pa, pb = p[v], p[a][None], p[b][None]
        inside = (_left(c, pa, pb) & _left(c, pb, pv) & _left(c, pv, pa)).any(axis=1)
        new = link[local[inside]]
        if len(new) != deg - 2 or not _has_edges(new, np.stack([a, b], axis=1)).all():
            return None
        keep = np.ones(len(sub), dtype=bool)
        keep[rows] = False
        sub = np.concatenate([sub[keep], new])
    return np.concatenate([*rest, sub])


def _left(c: FloatArray, s: FloatArray, e: FloatArray) -> NDArray[np.bool_]:
    """Whether the points ``c`` lie strictly left of the lines ``s -> e`` (broadcast)."""
    d = e - s
    return np.asarray((d[..., 0] * (c[..., 1] - s[..., 1]) - d[..., 1] * (c[..., 0] - s[..., 0])) > 0)


def _triangulate_alive(domain: Domain, p: FloatArray, walls: IntArray, alive: NDArray[np.bool_]) -> IntArray:
    """:func:`triangulate` of the nodes flagged ``alive``, in the numbering of all nodes."""
    if alive.all():
        return triangulate(domain, p, walls)
    idx = np.flatnonzero(alive)
    inv = np.full(len(p), -1, dtype=np.intp)
    inv[idx] = np.arange(len(idx))
    return idx[triangulate(domain, p[idx], inv[walls])]


def _has_edges(tri: IntArray, walls: IntArray) -> NDArray[np.bool_]:
    """Whether each segment of ``walls (k, 2)`` is an edge of ``tri``."""
    from .kernels.mesh import edges_present

    if len(walls) == 0:
        return np.zeros(0, dtype=bool)
    n = int(max(tri.max(initial=0), walls.max(initial=0))) + 1
    return np.asarray(edges_present(np.ascontiguousarray(tri, dtype=np.int64),
                                    np.ascontiguousarray(walls, dtype=np.int64), n))


def _optimize(
    domain: Domain,
    p: FloatArray,
    tri: IntArray,
    movable: NDArray[np.bool_],
    on_boundary: NDArray[np.bool_],
    walls: IntArray,
    project: NodeProjector | None = None,
) -> FloatArray:
    """Move free nodes of bad triangles where their star's worst quality rises.

    The target of a node is the mean, over its triangles, of the apex of the equilateral
    triangle on the opposite edge.  A move is kept only if the minimum q over the node's star
    rises, every star triangle stays counter-clockwise and the node stays inside (sliding boundary
    nodes move to the projection of their target onto the boundary); moving nodes
    form an independent set, so each triangle changes by one node at most.  The connectivity
    is kept: the result is valid but not necessarily Delaunay.

    Only candidates are visited: each sweep works on the stars of the nodes whose star has
    q below ``OPTIMIZE_Q``, and q is recomputed only for the triangles that moved.  Since the
    moving nodes are independent, a node's star sees no other move, so this is the same
    computation as over the whole mesh.  A node whose trial failed is no candidate until a
    neighbour's move changes its star (the same trial would fail again, and it would keep
    its neighbours out of the independent set); a node moves at most ``OPTIMIZE_MOVES`` times.
    """
    from .kernels.smooth import (
        clear_stars,
        corners_by_node,
        optimize_trials,
        restar,
        star_independent,
        star_min,
        star_targets,
    )

    reach = _inside_reach(domain)
    # A projector that the kernels can stand in for (see _Relaxation): each sweep's trials
    # in one compiled call.
    compiled = getattr(_OnDomain(domain) if project is None else project, "compiled", None)
    p = p.copy()
    n = len(p)
    # Boundary neighbours: a boundary node's move must stay next to its own two segments.
    prev_b = np.arange(n)
    next_b = np.arange(n)
    if len(walls):
        next_b[walls[:, 0]] = walls[:, 1]
        prev_b[walls[:, 1]] = walls[:, 0]
    # Corners grouped by node (CSR, in increasing corner order): the star of each node.
    # Writeable too: a read-only array would compile the kernels below once more.
    t64 = np.require(tri, dtype=np.int64, requirements=["C", "W"])
    start, by_node = corners_by_node(t64, n)
    q = triangle_quality(p, tri)
    star = star_min(start, by_node, q)
    scratch = np.zeros(n, dtype=np.bool_)

    moves = np.zeros(n, dtype=np.intp)
    # Nodes whose last trial failed and whose star has not changed since: the same trial
    # would fail again, so they are not candidates (nor block a neighbour's move).
    failed = np.zeros(n, dtype=bool)

    for _ in range(OPTIMIZE_SWEEPS):
        cand = (star < OPTIMIZE_Q) & movable & (moves < OPTIMIZE_MOVES) & ~failed
        if not cand.any():
            break
        # Independent set, worst stars first (ties by index).
        order = np.flatnonzero(cand)
        order = order[np.argsort(star[order], kind="stable")]
        # Conflicts: candidates joined by a side of a triangle; the better ranked one moves.
        move = order[star_independent(order.astype(np.int64), t64, start, by_node, scratch)]
        target = star_targets(p, t64, start, by_node, move)
        on_bnd = on_boundary[move]
        kb = compiled(domain, move[on_bnd]) if compiled is not None else None
        if kb is not None:
            # The line search below in one compiled call: the same numbers.
            done = optimize_trials(p, t64, start, by_node, move, target, star, prev_b, next_b,
                                   on_bnd, reach, kb[0], *kb[1])
        else:
            done = _line_search(domain, p, t64, start, by_node, move, target, star, prev_b, next_b,
                                on_bnd, reach, project)
        if not done.any():
            break
        moved = move[done]
        moves[moved] += 1
        failed[move[~done]] = True
        # The moved nodes' triangles changed, and with them the stars of all their nodes.
        clear_stars(moved.astype(np.int64), t64, start, by_node, failed)
        # q of the triangles that changed, and the stars of their nodes.
        restar(p, t64, start, by_node, q, star, moved)
    return p


def _line_search(domain: Domain, p: FloatArray, t64: NDArray[np.int64], start: NDArray[np.int64],
                 by_node: NDArray[np.int64], move: IntArray, target: FloatArray, star: FloatArray,
                 prev_b: IntArray, next_b: IntArray, on_bnd: NDArray[np.bool_], reach: float,
                 project: NodeProjector | None) -> NDArray[np.bool_]:
    """One sweep's trials of :func:`_optimize` through the domain's and projector's methods
    (``kernels.smooth.optimize_trials`` makes them on a compiled boundary); the moves are
    taken in ``p``.  Returns which nodes of ``move`` moved."""
    from .kernels.smooth import ACROSS, star_trial

    # The depth of the free nodes, once per sweep: a trial step shorter than it (half of
    # it for a d that is not an exact distance) stays inside without asking the domain,
    # which on a detailed outline was a BVH query of every moving node per trial length.
    free = np.flatnonzero(~on_bnd)
    depth = np.zeros(len(move))
    depth[free] = -reach * domain.sdf(p[move[free]])
    # Line search: the full step to the target, then shorter ones, until the star improves.
    done = np.zeros(len(move), dtype=bool)
    for frac in (1.0, 0.5, 0.25, 0.125):
        step = p[move] + frac * (target - p[move])
        if on_bnd.any():
            step[on_bnd] = (domain.project(step[on_bnd]) if project is None
                            else project(step[on_bnd], move[on_bnd]))
            # A move across a gap to another stretch of the boundary is refused, as the
            # compiled trials refuse it (kernels.smooth._keep_off_gaps); curve nodes (inside)
            # are not asked.
            b = np.flatnonzero(on_bnd)
            b = b[np.abs(domain.sdf(step[b])) <= tol.ON_BOUNDARY * domain.diameter]
            if len(b):
                mid = 0.5 * (p[move[b]] + step[b])
                scale = np.maximum(1.0, np.abs(p[move[b]]).max(axis=1))
                across = domain.sdf(mid) > ACROSS * np.hypot(*(step[b] - p[move[b]]).T) + 1e-12 * scale
                step[b[across]] = p[move[b[across]]]
        inside = np.hypot(*(step - p[move]).T) < depth
        ask = np.flatnonzero(~inside & ~on_bnd & ~done)
        if len(ask):
            inside[ask] = domain.sdf(step[ask]) < 0
        ok = star_trial(p, t64, start, by_node, move, np.ascontiguousarray(step), star, prev_b,
                        next_b, on_bnd, inside, done)
        p[move[ok]] = step[ok]
        done |= ok
    return done


#: Edge (a, b), a < b, as the integer a * _KEY + b (node numbers fit in 31 bits).
_KEY = 1 << 31


def _edge_keys(a: IntArray, b: IntArray) -> NDArray[np.int64]:
    """The undirected edges ``a[i]-b[i]`` as integers."""
    return np.minimum(a, b).astype(np.int64) * _KEY + np.maximum(a, b)


def _keys(edges: IntArray) -> NDArray[np.int64]:
    """Sorted keys of the undirected edges ``edges (k, 2)``."""
    e = np.asarray(edges).reshape(-1, 2)
    return np.sort(_edge_keys(e[:, 0], e[:, 1]))


def _chords(p: FloatArray, tri: IntArray, n_boundary: int, seg_keys: NDArray[np.int64]) -> IntArray:
    """For each triangle of three boundary nodes (``< n_boundary``): the local index k of its
    edge ``(t[k], t[k+1])`` to split, or -1 (``kernels.repair.chords``).

    The edge must be the triangle's longest (a flat cap: splitting the longest edge is the
    classic cure of an obtuse triangle; at a sharp tip the chord is the shortest edge, and
    splitting it would halve the tip) and not a boundary or curve segment (``seg_keys``,
    :func:`_keys`).  The triangle across it is split too, so it must have a free node, which
    can move to make room.  Across a strip one triangle wide (the two triangles of a quad of
    boundary nodes, the chord their common diagonal) the new node has nowhere to go: next to
    a 5-degree tip that made the strip's trapezoids q 0.73 where they were 0.80.
    """
    from .kernels.repair import chords

    return np.asarray(chords(p, np.ascontiguousarray(tri, dtype=np.int64), n_boundary,
                             np.ascontiguousarray(seg_keys, dtype=np.int64), _KEY), dtype=np.intp)


def _choose_repairs(
    relax: _Relaxation, p: FloatArray, tri: IntArray, bad: IntArray, chord: IntArray
) -> tuple[IntArray, IntArray] | None:
    """Edge operations for the bad triangles (worst first), no two touching the same node
    (``kernels.repair.choose_edits``: the edge of each furthest from h, collapsed or split).

    ``chord``: per triangle, the edge to split of a triangle with three fixed nodes
    (:func:`_chords`).  Returns ``(collapse, split)``, or None when there is none."""
    from .kernels.repair import choose_edits, edge_midpoints

    t = np.ascontiguousarray(tri, dtype=np.int64)
    b = np.ascontiguousarray(bad, dtype=np.int64)
    h_mid = np.asarray(relax.h(edge_midpoints(p, t, b)), dtype=np.float64)
    collapse, split = choose_edits(p, t, b, np.ascontiguousarray(chord, dtype=np.int64),
                                   np.ascontiguousarray(h_mid), relax.n_fixed)
    if len(collapse) == 0 and len(split) == 0:
        return None
    return collapse, split
