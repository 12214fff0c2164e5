"""The checks every mesh passes before ``generate`` returns it.

A mesh is *valid* when it is a conforming triangulation of the domain as meshed by Step 1:

* every node is used by a triangle, and no two nodes coincide;
* every triangle is counter-clockwise and not degenerate (``q >= DEGENERATE_Q``);
* no two triangles overlap (each directed edge occurs once, each edge in at most two triangles);
* the mesh's boundary edges are exactly the boundary segments of Step 1, with the domain on
  their left: none lost, none extra (an extra one is a gap in the mesh or a triangle that bridges
  a notch outside the domain);
* every boundary node lies on the domain's boundary (``|d| <= ON_BOUNDARY * diameter``).

The last two make "every triangle inside" exact: the triangles fill the polygon bounded by the
boundary segments and nothing else.  Each failed check becomes one :class:`Defect` naming what
failed, how often, and where (coordinates), so a user can find it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import _tolerances as tol
from .quality import signed_areas, triangle_quality

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: A triangle with q below this is degenerate: an angle under about 0.03 degrees, or two nodes
#: closer than about 5e-4 of its longest edge.  Even a 1-degree input corner allows q = 0.035,
#: so no mesh injmesh should make comes near it; such triangles are useless to a solver.
DEGENERATE_Q = 1e-3

#: Two nodes closer than this fraction of the domain diameter are duplicates.
DUPLICATE = 1e-9
#: Comparisons per node above which the duplicate search sorts instead of binning (measured:
#: binning pays on the 20:1 graded disc, 9 per node, not on the 20,000-vertex outline, 33).
DUPLICATE_WORK = 16

#: Locations listed per defect.
MAX_WHERE = 10


@dataclass(frozen=True)
class Defect:
    """One kind of failure found in a mesh.

    Attributes
    ----------
    kind : str
        What failed, e.g. ``"lost boundary segment"``.
    count : int
        How many times.
    where : tuple of (x, y)
        Coordinates of the first ``MAX_WHERE`` occurrences.
    """

    kind: str
    count: int
    where: tuple[tuple[float, float], ...]

    def __str__(self) -> str:
        at = ", ".join(f"({x:.6g}, {y:.6g})" for x, y in self.where)
        more = ", ..." if self.count > len(self.where) else ""
        return f"{self.count} x {self.kind} at {at}{more}"


def _defect(kind: str, locations: FloatArray) -> Defect:
    loc = np.asarray(locations, dtype=float).reshape(-1, 2)
    where = tuple((float(x), float(y)) for x, y in loc[:MAX_WHERE])
    return Defect(kind, int(len(loc)), where)


def mesh_defects(
    points: FloatArray,
    triangles: IntArray,
    *,
    walls: IntArray | None = None,
    sdf: Callable[[FloatArray], FloatArray] | None = None,
    diameter: float | None = None,
) -> list[Defect]:
    """Everything wrong with a mesh; an empty list for a valid one.

    Parameters
    ----------
    points : (n, 2) float array
    triangles : (m, 3) int array
        Should be counter-clockwise.
    walls : (k, 2) int array, optional
        The boundary segments the mesh must have as boundary edges, domain on their left.
    sdf : callable, optional
        Signed distance of the domain; with it, boundary nodes must lie on the boundary.
    diameter : float, optional
        Scale of the relative tolerances (default: the diagonal of the points' box).

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [5.0, 5.0]])
    >>> [d.kind for d in mesh_defects(p, np.array([[0, 1, 2]]))]
    ['unused node']
    """
    p = np.asarray(points, dtype=float)
    t = np.asarray(triangles, dtype=np.intp).reshape(-1, 3)
    out: list[Defect] = []
    if len(t) == 0:
        return [_defect("empty mesh", p[:1])]
    if diameter is None:
        diameter = float(np.hypot(*np.ptp(p, axis=0))) if len(p) else 1.0

    used = np.zeros(len(p), dtype=bool)
    used[t.ravel()] = True
    if not used.all():
        out.append(_defect("unused node", p[~used]))
    pairs = _duplicates(p, DUPLICATE * diameter)
    if len(pairs):
        out.append(_defect("duplicate node", p[pairs[:, 0]]))

    area = signed_areas(p, t)
    if np.any(area <= 0):
        out.append(_defect("inverted or flat triangle", p[t[area <= 0]].mean(axis=1)))
    q = triangle_quality(p, t)
    degenerate = (area > 0) & (q < DEGENERATE_Q)
    if degenerate.any():
        out.append(_defect(f"degenerate triangle (q < {DEGENERATE_Q:g})", p[t[degenerate]].mean(axis=1)))

    from .kernels.mesh import unusual_edges

    n = len(p)
    # Only the edges not run along once each way (boundary and faulty ones), sorted.
    edges, forward, backward = unusual_edges(np.ascontiguousarray(t, dtype=np.int64), n)
    both = forward + backward
    if np.any((forward > 1) | (backward > 1)):
        e = edges[(forward > 1) | (backward > 1)]
        out.append(_defect("overlapping triangles", 0.5 * (p[e[:, 0]] + p[e[:, 1]])))
    if np.any(both > 2):
        e = edges[both > 2]
        out.append(_defect("edge in more than two triangles", 0.5 * (p[e[:, 0]] + p[e[:, 1]])))
    # Edges in one triangle, oriented as there.
    once = both == 1
    boundary = np.where((forward[once] == 1)[:, None], edges[once], edges[once][:, ::-1])
    if walls is not None:
        w = np.asarray(walls, dtype=np.intp).reshape(-1, 2)
        # A segment with a dropped node (index -1) is lost; it is located at its other node.
        w = np.where(w < 0, w.max(axis=1, keepdims=True), w)
        wkey = w[:, 0].astype(np.int64) * n + w[:, 1]
        bkey = boundary[:, 0].astype(np.int64) * n + boundary[:, 1]
        lost = ~np.isin(wkey, bkey) | (w[:, 0] == w[:, 1])
        if lost.any():
            out.append(_defect("lost boundary segment", 0.5 * (p[w[lost, 0]] + p[w[lost, 1]])))
        extra = ~np.isin(bkey, wkey)
        if extra.any():
            e = boundary[extra]
            out.append(_defect("boundary edge not on the domain boundary", 0.5 * (p[e[:, 0]] + p[e[:, 1]])))
    if sdf is not None and len(boundary):
        nodes = np.unique(boundary)
        off = np.abs(np.asarray(sdf(p[nodes]), dtype=float)) > tol.ON_BOUNDARY * diameter
        if off.any():
            out.append(_defect("boundary node off the boundary", p[nodes[off]]))
    return out


def _duplicates(p: FloatArray, eps: float) -> NDArray[np.int64]:
    """Pairs of nodes within ``eps`` of each other.

    Found in bins about one node wide (:func:`~injmesh.kernels.mesh.close_pairs_binned`, no
    sort: 0.3 s less at 1e6 nodes); where the nodes crowd into a few bins, by a scan of cells
    of eps in x, then y (:func:`~injmesh.kernels.mesh.close_pairs`).  Either way the pairs are
    those of the scan, in its order: by (cell of eps in x, y, index) of the first node, then
    of the second.
    """
    from .kernels.mesh import close_pairs, close_pairs_binned

    if len(p) < 2 or not eps > 0:
        return np.zeros((0, 2), dtype=np.int64)
    pts = np.ascontiguousarray(p, dtype=np.float64)
    x_min = p[:, 0].min()

    def cell_of(i: NDArray[np.int64]) -> NDArray[np.int64]:
        # Cells of eps along x (capped: a far point just shares the last cell with its neighbours).
        return np.floor(np.minimum((p[i, 0] - x_min) / eps, 2.0**62)).astype(np.int64)

    pairs, binned = close_pairs_binned(pts, float(eps), DUPLICATE_WORK * len(p))
    if binned:
        a, b = pairs[:, 0], pairs[:, 1]
        ca, cb = cell_of(a), cell_of(b)
        # The scan pairs a node with the rest of its cell and the next cell only.
        near = np.abs(ca - cb) <= 1
        a, b, ca, cb = a[near], b[near], ca[near], cb[near]
        ya, yb = p[a, 1], p[b, 1]
        swap = (cb < ca) | ((cb == ca) & ((yb < ya) | ((yb == ya) & (b < a))))
        a, b = np.where(swap, b, a), np.where(swap, a, b)
        ca, cb = np.where(swap, cb, ca), np.where(swap, ca, cb)
        rank = np.lexsort((b, p[b, 1], cb, a, p[a, 1], ca))
        pairs = np.stack([a[rank], b[rank]], axis=1).astype(np.int64).reshape(-1, 2)
    else:
        cell = cell_of(np.arange(len(p)))
        order = np.lexsort((p[:, 1], cell)).astype(np.int64)
        pairs = close_pairs(pts, cell, order, eps)
    d = np.hypot(*(p[pairs[:, 0]] - p[pairs[:, 1]]).T)
    out: NDArray[np.int64] = pairs[d <= eps]
    return out
