"""Adaptive meshing: from an error estimate or a solution to a better mesh.

injmesh follows a size function h faithfully and deterministically, so adapting a mesh is
"estimate, derive h, mesh again":

* :func:`size_from_indicator` turns per-triangle error indicators eta_T into a size function by
  equidistribution;
* :func:`size_from_solution` does the same from a nodal field's recovered Hessian (the P1
  interpolation error), for users without an estimator;
* :func:`interpolate` carries nodal fields from one mesh to points of another;
* :func:`adapt` runs the loop ``mesh -> solve -> size -> mesh`` and keeps boundary tags.

Size from an indicator (equidistribution)
-----------------------------------------
For elements of polynomial order p measured in the energy norm, the local error behaves like
``eta_T = D_T h_T^m`` with ``m = p + 1`` (``m = p + 2`` for an L2-norm indicator), where D_T is a
local derivative of u that does not depend on the mesh and ``h_T = sqrt(4 |T| / sqrt(3))`` is
the side of the equilateral triangle of T's area.  The old mesh therefore measures
``D_T = eta_T / h_T^m``.  A mesh following h has about ``1 / (sqrt(3)/4 h^2)`` triangles per
unit area, so its total error is ``sum eta^2 ~ (4/sqrt(3)) int D^2 h^(2m-2) dA`` and its node
count ``N ~ (2/sqrt(3)) int h^-2 dA``.  Minimising the first at fixed N (a Lagrange multiplier)
gives ``D^2 h^(2m) = const``: every new element carries the same error (equidistribution), and

    h(x) = K D(x)^(-1/m).

* ``target_nodes=N``: K is the root of ``N_est(h_K) = N`` (below), solved numerically because the
  bounds and the gradation limit make N_est nonlinear in K.
* ``tolerance=tau`` (a bound on ``sqrt(sum eta_T^2)`` of the next mesh):
  ``K = (sqrt(3) tau^2 / (4 int D^(2/m) dA))^(1 / (2m - 2))``.

The per-triangle density ``rho_T = D_T^(2/m)`` (proportional to h^-2, i.e. to nodes per area)
is averaged to the nodes (area-weighted), smoothed by ``smoothing`` Jacobi passes in log space
(indicators are noisy element by element), turned into nodal ``h_i = K rho_i^(-1/2)``, clipped
to ``[h_min, h_max]`` (and to 1/``MIN_LOOP_SEGMENTS`` of its loop's perimeter on the boundary, so
no hole or island is coarsened away), and gradation-limited on the old mesh's edge graph,
``h_i <= h_j + gradation * |path(i, j)|``, by one Dijkstra pass from a virtual source joined to
every node j with weight ``h_j / gradation``.  The result is a :class:`NodalSize`: the nodal h
interpolated linearly on the old mesh, the nearest boundary value outside it.

Node count
----------
A triangulation with T triangles and B boundary nodes has ``N = T/2 + B/2 + 1 - holes`` nodes
(Euler), so for h linear on each old triangle

    N_est = AREA_FACTOR (2/sqrt(3)) int h^-2 dA + BOUNDARY_FACTOR int ds / h,

both integrals exact for the piecewise-linear h (Hermite-Genocchi: ``int_T h^-2 dA = 2 |T|
F[a, b, c]`` with F = -log and a, b, c the vertex values).  Euler's factors (1 and 1/2) are
kept: a least-squares fit on the paper's six cases gives 0.985 and 0.57, no better, and the
estimate lands within -4.2 % ... +2.3 % of injmesh's node count on those cases and within 2.3 %
on the adaptive sequences of ``benchmarks/adaptive.py`` (README, "Adaptive meshing").

Examples
--------
>>> import numpy as np, injmesh
>>> from injmesh import adapt
>>> mesh = injmesh.generate(injmesh.Rectangle((0, 0), (1, 1)), 0.1)
>>> u = np.tanh(20 * (mesh.points[:, 0] - 0.5))
>>> h = adapt.size_from_solution(mesh, u, target_nodes=400)
>>> new = injmesh.generate(injmesh.Rectangle((0, 0), (1, 1)), h)
>>> bool(abs(new.n_points / 400 - 1) < 0.1)
True
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import distance_transform_edt
from scipy.optimize import brentq
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from .errors import ConvergenceWarning
from .geometry import Domain
from .mesh import Mesh
from .pipeline import generate
from .quality import signed_areas, unique_edges
from .sizing import SizeLike

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
Norm = Literal["energy", "L2"]

logger = logging.getLogger(__name__)

#: Default gradation: h grows by at most this much per unit of distance (h_i <= h_j + g |x_i - x_j|).
GRADATION = 0.2
#: Default Jacobi passes smoothing the nodal log-density.
SMOOTHING = 1
#: Default largest h, as a fraction of the mesh's bounding-box diagonal.
H_MAX_FRACTION = 0.25
#: Default smallest h, as a fraction of the mesh's bounding-box diagonal.
H_MIN_FRACTION = 1e-5
#: A boundary loop keeps at least this many segments (no hole is coarsened away).
MIN_LOOP_SEGMENTS = 8
#: adapt() meshes again, once, when a mesh misses its target_nodes by more than this fraction.
RETRY_MISS = 0.05
#: adapt() with a tolerance aims at this fraction of it: equidistribution predicts the next
#: total to within a few percent, and landing just above the goal would cost a whole step.
TOLERANCE_MARGIN = 0.9
#: Factors of the node-count estimate N_est (module docstring): Euler's, confirmed on injmesh meshes.
AREA_FACTOR = 1.0
BOUNDARY_FACTOR = 0.5
#: Indicator densities below this fraction of the largest are raised to it (log-smoothing needs
#: a positive floor; such regions get h_max anyway).
DENSITY_FLOOR = 1e-12
#: Constants of the P1 interpolation error of a quadratic with Hessian eigenvalues of RMS
#: lambda on an equilateral triangle of side h: |e|_H1 = C_H1 lambda h^2, |e|_L2 = C_L2 lambda h^3.
C_H1 = math.sqrt(math.sqrt(3) / 48)
C_L2 = 0.08494
#: Point location: barycentric coordinates down to -BARY_TOL count as inside; a walk takes at
#: most WALK_STEPS steps, then CANDIDATES nearest triangle centroids are tested.
BARY_TOL = 1e-12
WALK_STEPS = 64
CANDIDATES = 24
#: Cells of the background grid of walk starts, per triangle.
GRID_CELLS = 1
#: A point closer than this (in barycentric coordinates) to a side of the triangle a hinted
#: walk found is located again from scratch (see _Locator.locate).
CANONICAL = 1e-9


class AdaptError(ValueError):
    """Bad input to adaptive meshing: an indicator, a field, a target or a solve result."""


class SolveError(AdaptError):
    """The user's ``solve(mesh)`` raised; the message names the step and the mesh."""


# --------------------------------------------------------------------------------------------
# Point location and interpolation on an existing mesh
# --------------------------------------------------------------------------------------------


def _neighbours(triangles: IntArray) -> IntArray:
    """``nbr[t, k]``: the triangle across the side opposite vertex k of t, or -1 on the boundary."""
    m = len(triangles)
    a = triangles[:, [1, 2, 0]].ravel()  # side k joins vertices k+1 and k+2
    b = triangles[:, [2, 0, 1]].ravel()
    n = int(triangles.max()) + 1
    key = np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])
    nbr = np.full(3 * m, -1, dtype=np.intp)
    nbr[order[same]] = order[same + 1] // 3
    nbr[order[same + 1]] = order[same] // 3
    return nbr.reshape(m, 3)


class _Locator:
    """Finds the triangle of an old mesh that contains each query point (vectorised).

    Each point starts at the triangle nearest to its cell of a background grid (a pure function
    of the point, so results never depend on earlier queries) and walks towards itself across
    the side with the most negative barycentric coordinate.  Walks that leave the mesh (a
    non-convex domain) or exceed WALK_STEPS (a walk can cycle on a non-Delaunay mesh) fall back
    to testing the CANDIDATES triangles with the nearest centroids; points in none of them are
    outside the mesh and take the value at the nearest point of the boundary.
    """

    def __init__(self, points: FloatArray, triangles: IntArray, boundary_edges: IntArray) -> None:
        self.p = np.asarray(points, dtype=float)
        self.t = np.asarray(triangles, dtype=np.intp)
        self.nbr = _neighbours(self.t)
        # Per triangle: vertex a and the inverse of [b - a, c - a], so that the barycentric
        # coordinates of q are one gather and four multiplications away.
        v = self.p[self.t]
        self.origin = v[:, 0].copy()
        ab, ac = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
        det = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]
        self.inverse = np.stack([ac[:, 1], -ac[:, 0], -ab[:, 1], ab[:, 0]], axis=1) / det[:, None]
        centroids = v.mean(axis=1)
        self.tree = cKDTree(centroids)
        lo, hi = self.p.min(axis=0), self.p.max(axis=0)
        span = np.maximum(hi - lo, 1e-300)
        cells = max(1, GRID_CELLS * len(self.t))
        side = math.sqrt(span[0] * span[1] / cells) or float(span.max())
        self.shape = np.maximum(np.ceil(span / side).astype(np.intp), 1)
        self.lo, self.cell = lo, span / self.shape
        # Each cell starts at a triangle whose centroid lies in it; an empty cell borrows the
        # triangle of the nearest non-empty cell (a Euclidean distance transform, linear time).
        start = np.full(tuple(self.shape), -1, dtype=np.intp)
        cx, cy = self._cells(centroids)
        np.maximum.at(start, (cx, cy), np.arange(len(self.t)))  # ties: the last triangle, always
        empty = start < 0
        if empty.any():
            near = distance_transform_edt(empty, return_distances=False, return_indices=True)
            start = start[near[0], near[1]]
        self.start = start.ravel()
        self.be = np.asarray(boundary_edges, dtype=np.intp)
        self.btree = cKDTree(0.5 * (self.p[self.be[:, 0]] + self.p[self.be[:, 1]]))

    def _bary(self, q: FloatArray, tri: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Barycentric coordinates of points q in triangles tri, as three columns."""
        o, inv = self.origin[tri], self.inverse[tri]
        dx, dy = q[:, 0] - o[:, 0], q[:, 1] - o[:, 1]
        l1 = inv[:, 0] * dx + inv[:, 1] * dy
        l2 = inv[:, 2] * dx + inv[:, 3] * dy
        return 1.0 - l1 - l2, l1, l2

    def _cells(self, q: FloatArray) -> tuple[IntArray, IntArray]:
        cx = ((q[:, 0] - self.lo[0]) / self.cell[0]).astype(np.intp)
        cy = ((q[:, 1] - self.lo[1]) / self.cell[1]).astype(np.intp)
        np.clip(cx, 0, self.shape[0] - 1, out=cx)
        np.clip(cy, 0, self.shape[1] - 1, out=cy)
        return cx, cy

    def _grid_start(self, q: FloatArray) -> IntArray:
        cx, cy = self._cells(q)
        return self.start[cx * self.shape[1] + cy]

    def locate(self, q: FloatArray, hint: IntArray | None = None) -> tuple[IntArray, FloatArray]:
        """Triangle (-1 outside) and barycentric coordinates ``(k, 3)`` of every query point.

        ``hint`` (optional, one triangle per point) only changes where walks start: a point
        found closer than CANONICAL to a side of its triangle (where two triangles could claim
        it, with values equal up to rounding) is located again from its grid start, so the
        result is a function of the point alone, hint or no hint.
        """
        k = len(q)
        found = np.full(k, -1, dtype=np.intp)
        bary = np.zeros((k, 3))
        if hint is not None:
            start = np.where(hint >= 0, hint, 0)
            found, bary = self._walk(q, start, found, bary)
            redo = (found < 0) | (bary.min(axis=1) < CANONICAL)
            if redo.any():
                sub = np.flatnonzero(redo)
                f, b = self.locate(q[sub])
                found[sub], bary[sub] = f, b
            return found, bary
        return self._walk(q, self._grid_start(q), found, bary)

    def _walk(
        self, q: FloatArray, tri: IntArray, found: IntArray, bary: FloatArray
    ) -> tuple[IntArray, FloatArray]:
        k = len(q)
        idx = np.arange(k)
        lost = []
        for _ in range(WALK_STEPS):
            l0, l1, l2 = self._bary(q[idx], tri)
            # Columns, not reductions over an (n, 3) axis: several times faster in NumPy.
            ok = (l0 >= -BARY_TOL) & (l1 >= -BARY_TOL) & (l2 >= -BARY_TOL)
            hit = idx[ok]
            found[hit] = tri[ok]
            bary[hit, 0], bary[hit, 1], bary[hit, 2] = l0[ok], l1[ok], l2[ok]
            miss = ~ok
            idx, tri, l0, l1, l2 = idx[miss], tri[miss], l0[miss], l1[miss], l2[miss]
            if not len(idx):
                break
            # Cross the side opposite the most negative coordinate.
            side = np.where((l0 <= l1) & (l0 <= l2), 0, np.where(l1 <= l2, 1, 2))
            nxt = self.nbr[tri, side]
            out = nxt < 0
            lost.append(idx[out])
            idx, tri = idx[~out], nxt[~out]
            if not len(idx):
                break
        rest = np.concatenate([*lost, idx])
        if len(rest):
            nc = min(CANDIDATES, len(self.t))
            cand = self.tree.query(q[rest], k=nc)[1].reshape(len(rest), nc)
            c0, c1, c2 = self._bary(np.repeat(q[rest], nc, axis=0), cand.ravel())
            lam = np.stack([c0, c1, c2], axis=1).reshape(len(rest), nc, 3)
            worst = lam.min(axis=2)
            best = np.argmax(worst, axis=1)  # the most interior candidate (deterministic)
            ok = worst[np.arange(len(rest)), best] >= -BARY_TOL
            found[rest[ok]] = cand[ok, best[ok]]
            bary[rest[ok]] = lam[np.flatnonzero(ok), best[ok]]
        return found, bary

    def interpolate(self, values: FloatArray, q: FloatArray) -> FloatArray:
        """Linear interpolation of nodal ``values`` (n, ...) at ``q``; nearest boundary value outside."""
        tri, lam = self.locate(q)
        return self.combine(values, q, tri, lam)

    def combine(self, values: FloatArray, q: FloatArray, tri: IntArray, lam: FloatArray) -> FloatArray:
        """The interpolant from :meth:`locate`'s output."""
        # Points found within the tolerance may have a coordinate of -1e-12: clip, renormalise.
        np.clip(lam, 0.0, None, out=lam)
        lam /= np.maximum(lam[:, :1] + lam[:, 1:2] + lam[:, 2:], 1e-300)
        inside = tri >= 0
        shape = (-1, *([1] * (values.ndim - 1)))
        if inside.all():
            nodes = self.t[tri]
            return (
                values[nodes[:, 0]] * lam[:, 0].reshape(shape)
                + values[nodes[:, 1]] * lam[:, 1].reshape(shape)
                + values[nodes[:, 2]] * lam[:, 2].reshape(shape)
            )
        out = np.empty((len(q), *values.shape[1:]))
        nodes, w = self.t[tri[inside]], lam[inside]
        out[inside] = (
            values[nodes[:, 0]] * w[:, 0].reshape(shape)
            + values[nodes[:, 1]] * w[:, 1].reshape(shape)
            + values[nodes[:, 2]] * w[:, 2].reshape(shape)
        )
        out[~inside] = self._boundary_value(values, q[~inside])
        return out

    def _boundary_value(self, values: FloatArray, q: FloatArray) -> FloatArray:
        """Values at the nearest point of the mesh boundary (linear along the boundary edge)."""
        nc = min(8, len(self.be))
        cand = self.btree.query(q, k=nc)[1].reshape(len(q), nc)
        a, b = self.p[self.be[cand, 0]], self.p[self.be[cand, 1]]
        ab = b - a
        t = np.clip(np.sum((q[:, None] - a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=2), 1e-300), 0, 1)
        dist = np.hypot(*(a + t[..., None] * ab - q[:, None]).transpose(2, 0, 1))
        j = np.argmin(dist, axis=1)
        rows = np.arange(len(q))
        e, s = self.be[cand[rows, j]], t[rows, j].reshape(-1, *([1] * (values.ndim - 1)))
        return (1 - s) * values[e[:, 0]] + s * values[e[:, 1]]


def _as_query(points: ArrayLike, what: str = "points") -> FloatArray:
    q = np.asarray(points, dtype=float)
    if q.ndim == 1 and q.shape == (2,):
        q = q[None]
    if q.ndim != 2 or q.shape[1] != 2:
        raise AdaptError(f"{what} must have shape (k, 2), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise AdaptError(f"{what} must be finite; row {int(np.argmax(~np.isfinite(q).all(axis=1)))} is not")
    return q


def _check_mesh(mesh: object) -> Mesh:
    if not isinstance(mesh, Mesh):
        raise TypeError(f"expected an injmesh.Mesh, got {type(mesh).__name__}")
    return mesh


def interpolate(mesh: Mesh, values: ArrayLike, points: ArrayLike) -> FloatArray:
    """Carry a nodal field of ``mesh`` to arbitrary points (linear on each triangle).

    Points inside the mesh are located in their triangle (a vectorised walk from a background
    grid, then a nearest-centroid candidate test; the mesh need not be Delaunay) and get the
    P1 interpolant.  Points outside it (for instance on a curved boundary that the old mesh
    cut with chords) get the value at the nearest point of the mesh boundary.

    Parameters
    ----------
    mesh : Mesh
        The mesh the values live on.
    values : (n,) or (n, k) array_like
        One value (or row) per node of ``mesh``.
    points : (m, 2) array_like
        Where to evaluate.

    Returns
    -------
    (m,) or (m, k) array

    Raises
    ------
    AdaptError
        Values of the wrong length or not finite, points of the wrong shape.

    Examples
    --------
    >>> import numpy as np, injmesh
    >>> from injmesh.adapt import interpolate
    >>> mesh = injmesh.generate(injmesh.Rectangle((0, 0), (1, 1)), 0.2)
    >>> u = 2 * mesh.points[:, 0] + mesh.points[:, 1]      # linear: reproduced exactly
    >>> interpolate(mesh, u, [[0.3, 0.4], [2.0, 0.5]]).round(12)   # second point is outside
    array([1. , 2.5])
    """
    mesh = _check_mesh(mesh)
    v = np.asarray(values, dtype=float)
    if v.ndim not in (1, 2) or len(v) != mesh.n_points:
        raise AdaptError(
            f"values must have one entry (or row) per node: expected shape ({mesh.n_points},) or "
            f"({mesh.n_points}, k), got {v.shape}"
        )
    if not np.all(np.isfinite(v)):
        bad = np.flatnonzero(~np.isfinite(v).reshape(len(v), -1).all(axis=1))
        raise AdaptError(f"values must be finite; {len(bad)} nodes are not, first node {int(bad[0])}")
    q = _as_query(points)
    return _Locator(mesh.points, mesh.triangles, mesh.boundary_edges).interpolate(v, q)


class NodalSize:
    """A size function h(p) given by nodal values on a mesh, interpolated linearly.

    Made by :func:`size_from_indicator` and :func:`size_from_solution`; pass it to
    :func:`injmesh.generate` as ``size``.  Outside the mesh h takes the value at the nearest
    boundary point.

    Attributes
    ----------
    mesh : Mesh
        The mesh the values live on (the "old" mesh of an adaptive step).
    values : (n,) array
        Nodal h, positive and gradation-limited.
    expected_nodes : float
        Estimated node count of a mesh following this h (module docstring).
    """

    def __init__(self, mesh: Mesh, values: FloatArray, expected_nodes: float) -> None:
        self.mesh = mesh
        self.values = np.array(values, dtype=float)
        self.values.setflags(write=False)
        self.expected_nodes = float(expected_nodes)
        self._locator = _Locator(mesh.points, mesh.triangles, mesh.boundary_edges)
        self._last: IntArray | None = None

    def __call__(self, p: FloatArray) -> FloatArray:
        q = np.asarray(p, dtype=float).reshape(-1, 2)
        # The mesher evaluates h at the same number of slowly moving points many times in a
        # row: the triangles of the last call are the walks' starts.  Results do not depend on
        # them (see _Locator.locate), so the output stays a pure function of p.
        last = self._last
        hint = last if last is not None and len(last) == len(q) else None
        tri, lam = self._locator.locate(q, hint)
        self._last = tri
        return self._locator.combine(self.values, q, tri, lam)

    def __repr__(self) -> str:
        return (
            f"<NodalSize on {self.mesh.n_points} nodes: h in [{self.values.min():.3g}, "
            f"{self.values.max():.3g}], about {self.expected_nodes:.0f} nodes>"
        )


# --------------------------------------------------------------------------------------------
# Nodal sizes: density -> h, bounds, gradation, calibration
# --------------------------------------------------------------------------------------------


def _mean_inverse(x: FloatArray, y: FloatArray) -> FloatArray:
    """``int_0^1 dt / (x + t (y - x)) = log(y/x) / (y - x)``, stable when y is close to x."""
    d = (y - x) / x
    small = np.abs(d) < 1e-8
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.log1p(d) / (x * d)
    return np.where(small, (1.0 - 0.5 * d) / x, g)


def _integral_inverse_square(h: FloatArray, triangles: IntArray, areas: FloatArray) -> FloatArray:
    """``int_T h^-2 dA`` on each triangle for h linear between its vertex values."""
    v = np.sort(h[triangles], axis=1)
    a, b, c = v[:, 0], v[:, 1], v[:, 2]
    spread = (c - a) / a
    near = spread < 1e-3
    with np.errstate(divide="ignore", invalid="ignore"):
        # Second divided difference of F = -log (Hermite-Genocchi); ill-conditioned when the
        # three values nearly agree, where the vertex mean of h^-2 is accurate to O(spread^2).
        f = (_mean_inverse(a, b) - _mean_inverse(b, c)) / (c - a)
    mean = np.mean(v**-2.0, axis=1) / 2.0
    return 2.0 * areas * np.where(near, mean, f)


@dataclass(frozen=True)
class _Graph:
    """What sizing needs from the old mesh, computed once."""

    mesh: Mesh
    areas: FloatArray
    edges: IntArray
    lengths: FloatArray
    node_area: FloatArray
    boundary_cap: FloatArray
    diagonal: float
    be_lengths: FloatArray = field(repr=False)

    @classmethod
    def of(cls, mesh: Mesh) -> _Graph:
        p, t = mesh.points, mesh.triangles
        areas = signed_areas(p, t)
        edges = unique_edges(t)
        lengths = np.hypot(*(p[edges[:, 0]] - p[edges[:, 1]]).T)
        n = len(p)
        node_area = np.bincount(t.ravel(), np.repeat(areas, 3), minlength=n).astype(float)
        be = mesh.boundary_edges
        be_len = np.hypot(*(p[be[:, 0]] - p[be[:, 1]]).T)
        # Each boundary loop keeps MIN_LOOP_SEGMENTS segments: h <= perimeter / that.
        cap = np.full(n, np.inf)
        if len(be):
            tags = np.asarray(mesh.boundary_tags)
            uniq, inv = np.unique(tags, return_inverse=True)
            perimeter = np.bincount(inv, be_len, minlength=len(uniq))
            per_edge = perimeter[inv] / MIN_LOOP_SEGMENTS
            np.minimum.at(cap, be[:, 0], per_edge)
            np.minimum.at(cap, be[:, 1], per_edge)
        diagonal = float(np.hypot(*np.ptp(p, axis=0)))
        return cls(mesh, areas, edges, lengths, node_area, cap, diagonal, be_len)

    def limit(self, h: FloatArray, rate: float) -> FloatArray:
        """Gradation limit on the edge graph: ``h_i = min_j (h_j + rate * path(i, j))``."""
        n = len(h)
        e = self.edges
        rows = np.concatenate([e[:, 0], e[:, 1], np.full(n, n)])
        cols = np.concatenate([e[:, 1], e[:, 0], np.arange(n)])
        data = np.concatenate([self.lengths, self.lengths, h / rate])
        graph = csr_matrix((data, (rows, cols)), shape=(n + 1, n + 1))
        dist = dijkstra(graph, directed=True, indices=n)
        return np.minimum(h, rate * dist[:n])

    def expected_nodes(self, h: FloatArray) -> float:
        """N_est of the module docstring for nodal h."""
        interior = float(np.sum(_integral_inverse_square(h, self.mesh.triangles, self.areas)))
        be = self.mesh.boundary_edges
        boundary = float(np.sum(self.be_lengths * _mean_inverse(h[be[:, 0]], h[be[:, 1]])))
        return AREA_FACTOR * 2.0 / math.sqrt(3.0) * interior + BOUNDARY_FACTOR * boundary

    def boundary_nodes(self, h: FloatArray) -> float:
        """Estimated boundary node count ``int ds / h`` for nodal h."""
        be = self.mesh.boundary_edges
        return float(np.sum(self.be_lengths * _mean_inverse(h[be[:, 0]], h[be[:, 1]])))


def _positive_option(value: float | None, name: str) -> float | None:
    if value is None:
        return None
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise AdaptError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _nodal_sizes(
    graph: _Graph,
    rho_t: FloatArray,
    *,
    target_nodes: float | None,
    tolerance_scale: float | None,
    gradation: float,
    h_min: float | None,
    h_max: float | None,
    smoothing: int,
) -> tuple[FloatArray, float]:
    """Nodal h from per-triangle densities rho_T (proportional to h^-2); see the module docstring.

    ``tolerance_scale`` is K of the tolerance formula, computed by the caller.
    """
    mesh = graph.mesh
    n = mesh.n_points
    lo = h_min if h_min is not None else H_MIN_FRACTION * graph.diagonal
    hi = h_max if h_max is not None else H_MAX_FRACTION * graph.diagonal
    if lo > hi:
        raise AdaptError(f"h_min={lo:.6g} is larger than h_max={hi:.6g}")
    cap = np.minimum(graph.boundary_cap, hi)
    top = float(rho_t.max())
    if top <= 0:
        rho_t = np.ones_like(rho_t)  # an indicator that is zero everywhere: no preference
        top = 1.0
    rho_t = np.maximum(rho_t, DENSITY_FLOOR * top)
    t = mesh.triangles
    rho = np.bincount(t.ravel(), np.repeat(rho_t * graph.areas, 3), minlength=n) / graph.node_area
    logr = np.log(rho)
    e = graph.edges
    deg = np.bincount(e.ravel(), minlength=n)
    for _ in range(smoothing):
        s = np.bincount(e[:, 0], logr[e[:, 1]], n) + np.bincount(e[:, 1], logr[e[:, 0]], n)
        logr = 0.5 * logr + 0.5 * s / np.maximum(deg, 1)
    # h = K rho^(-1/2) = (K scale) base with base >= 1: the largest density gives base 1.
    base = np.exp(-0.5 * (logr - logr.max()))
    scale = math.exp(-0.5 * float(logr.max()))

    def sizes(k: float) -> FloatArray:
        return graph.limit(np.clip(k * base, lo, cap), gradation)

    if tolerance_scale is not None:
        h = sizes(tolerance_scale * scale)
        return h, graph.expected_nodes(h)

    assert target_nodes is not None
    coarsest = graph.limit(np.minimum(np.full(n, hi), cap), gradation)
    n_coarse = graph.expected_nodes(coarsest)
    b_coarse = graph.boundary_nodes(coarsest)
    if target_nodes < n_coarse:
        raise AdaptError(
            f"target_nodes={target_nodes:g} is below what the domain needs at the coarsest "
            f"allowed size (h_max={hi:.4g}, at least {MIN_LOOP_SEGMENTS} segments per boundary "
            f"loop): about {n_coarse:.0f} nodes, {b_coarse:.0f} of them on the boundary"
        )
    finest = graph.limit(np.full(n, lo), gradation)
    n_fine = graph.expected_nodes(finest)
    if target_nodes > n_fine:
        raise AdaptError(
            f"target_nodes={target_nodes:g} needs sizes below h_min={lo:.4g} (about {n_fine:.0f} "
            "nodes at h_min everywhere); lower the target or pass a smaller h_min"
        )

    def excess(logk: float) -> float:
        return math.log(graph.expected_nodes(sizes(math.exp(logk)))) - math.log(target_nodes)

    # N_est ~ K^-2 without bounds: a first guess, then a bracket widened by factors of 4.
    unbounded = AREA_FACTOR * 2 / math.sqrt(3) * float(np.sum(rho_t * graph.areas))
    k0 = math.log(math.sqrt(unbounded / target_nodes) / scale)
    a, b = k0 - math.log(2), k0 + math.log(2)
    fa, fb = excess(a), excess(b)
    for _ in range(60):
        if fa >= 0 >= fb:
            break
        if fa < 0:
            a, fa = a - math.log(4), excess(a - math.log(4))
        if fb > 0:
            b, fb = b + math.log(4), excess(b + math.log(4))
    if fa == 0:
        logk = a
    elif fb == 0:
        logk = b
    else:
        logk = brentq(excess, a, b, xtol=1e-4)
    h = sizes(math.exp(logk))
    return h, graph.expected_nodes(h)


def _check_count(target_nodes: float | None, tolerance: float | None) -> tuple[float | None, float | None]:
    if (target_nodes is None) == (tolerance is None):
        raise AdaptError("pass exactly one of target_nodes and tolerance")
    if target_nodes is not None:
        if isinstance(target_nodes, (bool, np.bool_)) or not isinstance(
            target_nodes, (int, float, np.integer, np.floating)
        ):
            raise AdaptError(f"target_nodes must be a number of nodes, got {target_nodes!r}")
        if not (math.isfinite(float(target_nodes)) and target_nodes >= 3):
            raise AdaptError(f"target_nodes must be a finite number >= 3, got {target_nodes!r}")
        return float(target_nodes), None
    return None, _positive_option(tolerance, "tolerance")


def _check_common(gradation: float, smoothing: int) -> None:
    if not (isinstance(gradation, (int, float, np.integer, np.floating)) and 0 < gradation < math.inf):
        raise AdaptError(f"gradation must be a positive number, got {gradation!r}")
    if not (isinstance(smoothing, (int, np.integer)) and smoothing >= 0):
        raise AdaptError(f"smoothing must be a non-negative integer, got {smoothing!r}")


def _exponent(order: int, norm: Norm) -> int:
    if isinstance(order, (bool, np.bool_)) or not isinstance(order, (int, np.integer)) or order < 1:
        raise AdaptError(f"order must be a positive integer (the elements' polynomial degree), got {order!r}")
    if norm == "energy":
        return int(order) + 1
    if norm == "L2":
        return int(order) + 2
    raise AdaptError(f"norm must be 'energy' or 'L2', got {norm!r}")


def _element_sizes(areas: FloatArray) -> FloatArray:
    """h_T: side of the equilateral triangle of T's area."""
    return np.sqrt(4.0 * areas / math.sqrt(3.0))


def _size_from_density(
    mesh: Mesh,
    eta: FloatArray,
    m: int,
    *,
    target_nodes: float | None,
    tolerance: float | None,
    gradation: float,
    h_min: float | None,
    h_max: float | None,
    smoothing: int,
) -> NodalSize:
    graph = _Graph.of(mesh)
    d = eta / _element_sizes(graph.areas) ** m  # D_T = eta_T / h_T^m
    rho_t = d ** (2.0 / m)  # proportional to h^-2
    k_tol = None
    if tolerance is not None:
        integral = float(np.sum(rho_t * graph.areas))
        if integral <= 0:
            integral = float(np.sum(graph.areas)) * DENSITY_FLOOR
        # tau^2 = (4/sqrt 3) K^(2m-2) int D^(2/m) dA; h = K D^(-1/m) = K rho^(-1/2).
        k_tol = (math.sqrt(3.0) * tolerance**2 / (4.0 * integral)) ** (1.0 / (2 * m - 2))
    h, expected = _nodal_sizes(
        graph, rho_t, target_nodes=target_nodes, tolerance_scale=k_tol, gradation=gradation,
        h_min=_positive_option(h_min, "h_min"), h_max=_positive_option(h_max, "h_max"), smoothing=smoothing,
    )
    return NodalSize(mesh, h, expected)


def _check_indicator(mesh: Mesh, eta: ArrayLike) -> FloatArray:
    try:
        e = np.asarray(eta, dtype=float)
    except (TypeError, ValueError) as exc:
        raise AdaptError(f"the indicator must be an array of numbers: {exc}") from exc
    if e.shape != (mesh.n_triangles,):
        raise AdaptError(
            f"the indicator must have one value per triangle: expected shape ({mesh.n_triangles},), "
            f"got {e.shape}"
            + (" (one per node? pass it to size_from_solution)" if e.shape == (mesh.n_points,) else "")
        )
    bad = ~np.isfinite(e)
    if bad.any():
        raise AdaptError(
            f"the indicator must be finite: {int(bad.sum())} values are NaN or infinite "
            f"(first at triangle {int(np.argmax(bad))})"
        )
    neg = e < 0
    if neg.any():
        i = int(np.argmax(neg))
        raise AdaptError(
            f"the indicator must be non-negative (the local error, not a signed quantity): "
            f"{int(neg.sum())} values are negative, e.g. eta[{i}] = {e[i]:.6g}"
        )
    return e


def size_from_indicator(
    mesh: Mesh,
    eta: ArrayLike,
    *,
    target_nodes: float | None = None,
    tolerance: float | None = None,
    order: int = 1,
    norm: Norm = "energy",
    gradation: float = GRADATION,
    h_min: float | None = None,
    h_max: float | None = None,
    smoothing: int = SMOOTHING,
) -> NodalSize:
    """A size function for the next mesh from per-triangle error indicators (equidistribution).

    With ``eta_T = D_T h_T^m`` (``m = order + 1`` in the energy norm, ``order + 2`` in L2), the
    new size is ``h = K D^(-1/m)``: every element of the next mesh carries the same error.  K
    gives ``target_nodes`` nodes or a total error ``sqrt(sum eta_T^2)`` of ``tolerance``; the
    derivation, the smoothing and the gradation limit are in the module docstring.

    Parameters
    ----------
    mesh : Mesh
        The mesh the indicators were computed on.
    eta : (n_triangles,) array_like
        Local error of each triangle (the error itself, not its square), non-negative and finite.
    target_nodes : float, optional
        Node count of the next mesh (it lands within about 10 %).
    tolerance : float, optional
        Total error ``sqrt(sum eta_T^2)`` the next mesh should reach.  Exactly one of
        ``target_nodes`` and ``tolerance``.
    order : int
        Polynomial degree of the elements the indicator measures.
    norm : {"energy", "L2"}
        Norm of the indicator.
    gradation : float
        Largest growth of h per unit length: ``h_i <= h_j + gradation * |x_i - x_j|``.
    h_min, h_max : float, optional
        Bounds on h (defaults: 1e-5 and 0.25 of the mesh's bounding-box diagonal).
    smoothing : int
        Jacobi passes smoothing the nodal log-density (0 for none).

    Returns
    -------
    NodalSize
        Callable ``h(p)``, valid everywhere in the domain; ``expected_nodes`` is its estimate.

    Raises
    ------
    AdaptError
        An indicator of the wrong length, negative, NaN or infinite; not exactly one of
        ``target_nodes`` and ``tolerance``; a target below what the boundary alone needs at
        ``h_max``, or above what ``h_min`` allows.

    Examples
    --------
    >>> import numpy as np, injmesh
    >>> from injmesh.adapt import size_from_indicator
    >>> mesh = injmesh.generate(injmesh.Circle((0, 0), 1), 0.2)
    >>> eta = np.hypot(*mesh.points[mesh.triangles].mean(axis=1).T)   # larger error outside
    >>> h = size_from_indicator(mesh, eta, target_nodes=300)
    >>> bool(h([[0.0, 0.0]])[0] > h([[0.95, 0.0]])[0])
    True
    """
    mesh = _check_mesh(mesh)
    e = _check_indicator(mesh, eta)
    m = _exponent(order, norm)
    target, tol = _check_count(target_nodes, tolerance)
    _check_common(gradation, smoothing)
    return _size_from_density(
        mesh, e, m, target_nodes=target, tolerance=tol, gradation=float(gradation), h_min=h_min,
        h_max=h_max, smoothing=int(smoothing),
    )


def recovered_hessian(mesh: Mesh, u: ArrayLike) -> FloatArray:
    """Nodal Hessians of a P1 field by two rounds of gradient recovery.

    The P1 gradient of each triangle is averaged to the nodes (area-weighted), the same is done
    for each component of that recovered gradient, and the result is symmetrised.  At boundary
    nodes, where one-sided averages are only first order, the Hessian is the mean of those of
    the node's interior neighbours (when it has any).

    Returns
    -------
    (n, 2, 2) array
    """
    mesh = _check_mesh(mesh)
    v = _check_field(mesh, u)
    p, t = mesh.points, mesh.triangles
    n = len(p)
    areas = signed_areas(p, t)
    node_area = np.bincount(t.ravel(), np.repeat(areas, 3), minlength=n)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    # Gradients of the barycentric basis functions: rotated opposite sides over 2|T|.
    sides = np.stack([c - b, a - c, b - a], axis=1)  # opposite vertex 0, 1, 2
    gphi = np.stack([sides[..., 1], -sides[..., 0]], axis=-1) / (2.0 * areas)[:, None, None]

    def recover(f: FloatArray) -> FloatArray:
        g = np.einsum("tk,tkd->td", f[t], gphi)
        weighted = [np.bincount(t.ravel(), np.repeat(g[:, d] * areas, 3), minlength=n) for d in range(2)]
        return np.stack(weighted, axis=1) / node_area[:, None]

    g = recover(v)
    hess = np.stack([recover(g[:, 0]), recover(g[:, 1])], axis=1)  # hess[i, r, s] = d_s (d_r u)
    hess = 0.5 * (hess + hess.transpose(0, 2, 1))
    bnodes = mesh.boundary_nodes
    on_b = np.zeros(n, dtype=bool)
    on_b[bnodes] = True
    e = unique_edges(t)
    i, j = np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])
    use = on_b[i] & ~on_b[j]
    count = np.bincount(i[use], minlength=n)
    has = count > 0
    for r in range(2):
        for s in range(2):
            sums = np.bincount(i[use], hess[j[use], r, s], minlength=n)
            hess[has, r, s] = sums[has] / count[has]
    return hess


def _check_field(mesh: Mesh, u: ArrayLike) -> FloatArray:
    try:
        v = np.asarray(u, dtype=float)
    except (TypeError, ValueError) as exc:
        raise AdaptError(f"the solution must be an array of numbers: {exc}") from exc
    if v.shape != (mesh.n_points,):
        raise AdaptError(
            f"the solution must have one value per node: expected shape ({mesh.n_points},), got {v.shape}"
        )
    bad = ~np.isfinite(v)
    if bad.any():
        raise AdaptError(
            f"the solution must be finite: {int(bad.sum())} values are NaN or infinite "
            f"(first at node {int(np.argmax(bad))})"
        )
    return v


def size_from_solution(
    mesh: Mesh,
    u: ArrayLike,
    *,
    target_nodes: float | None = None,
    tolerance: float | None = None,
    norm: Norm = "energy",
    gradation: float = GRADATION,
    h_min: float | None = None,
    h_max: float | None = None,
    smoothing: int = SMOOTHING,
) -> NodalSize:
    """A size function from a nodal field's recovered Hessian (P1 interpolation error).

    The P1 interpolation error of u on a triangle of side h is ``C lambda h^2`` in the H1
    seminorm (``norm="energy"``) and ``C lambda h^3`` in L2, where lambda is the root mean square
    of the eigenvalues of u's Hessian (see :func:`recovered_hessian`) and C the equilateral
    triangle's constant (``C_H1``, ``C_L2``).  These per-triangle estimates are equidistributed
    exactly as in :func:`size_from_indicator`; ``tolerance`` bounds their l2 sum.

    Parameters
    ----------
    mesh : Mesh
    u : (n_points,) array_like
        A nodal field (a finite element solution, or the exact function sampled at the nodes).
    target_nodes, tolerance, norm, gradation, h_min, h_max, smoothing
        As in :func:`size_from_indicator`.

    Returns
    -------
    NodalSize

    Examples
    --------
    >>> import numpy as np, injmesh
    >>> from injmesh.adapt import size_from_solution
    >>> mesh = injmesh.generate(injmesh.Circle((0, 0), 1), 0.1)
    >>> r = np.hypot(*mesh.points.T)
    >>> h = size_from_solution(mesh, np.arctan(20 * (r - 0.5)), target_nodes=1000)
    >>> bool(h([[0.5, 0.0]])[0] < h([[0.0, 0.0]])[0])     # fine on the layer at r = 0.5
    True
    """
    mesh = _check_mesh(mesh)
    hess = recovered_hessian(mesh, u)
    m = _exponent(1, norm)
    target, tol = _check_count(target_nodes, tolerance)
    _check_common(gradation, smoothing)
    lam = np.sqrt(0.5 * np.sum(hess**2, axis=(1, 2)))  # RMS eigenvalue = |H|_F / sqrt 2
    areas = signed_areas(mesh.points, mesh.triangles)
    hs = _element_sizes(areas)
    const = C_H1 if norm == "energy" else C_L2
    eta = const * lam[mesh.triangles].mean(axis=1) * hs**m
    return _size_from_density(
        mesh, eta, m, target_nodes=target, tolerance=tol, gradation=float(gradation), h_min=h_min,
        h_max=h_max, smoothing=int(smoothing),
    )


# --------------------------------------------------------------------------------------------
# The loop
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class AdaptStep:
    """One mesh of an adaptive sequence and what ``solve`` returned on it.

    Attributes
    ----------
    mesh : Mesh
        The mesh (boundary tags numbered as on the first mesh).
    solution : (n,) array or None
        The nodal field ``solve`` returned, if any.
    indicator : (m,) array or None
        The per-triangle indicator ``solve`` returned, if any.
    total : float
        ``sqrt(sum eta_T^2)``: of the returned indicator, or of the Hessian estimate when ``solve``
        returned ``(u, None)``.
    target_nodes : float or None
        The node count this mesh was made for (None for the first mesh).
    """

    mesh: Mesh
    solution: FloatArray | None
    indicator: FloatArray | None
    total: float
    target_nodes: float | None

    @property
    def nodes(self) -> int:
        """Node count of the mesh."""
        return self.mesh.n_points


@dataclass(frozen=True, eq=False)
class AdaptResult:
    """The sequence of meshes of :func:`adapt`, first (from ``size``) to last.

    Attributes
    ----------
    steps : tuple of AdaptStep
    """

    steps: tuple[AdaptStep, ...]

    @property
    def meshes(self) -> list[Mesh]:
        """The meshes, in order."""
        return [s.mesh for s in self.steps]

    @property
    def nodes(self) -> list[int]:
        """Node count of each mesh."""
        return [s.nodes for s in self.steps]

    @property
    def totals(self) -> list[float]:
        """Indicator total ``sqrt(sum eta_T^2)`` on each mesh."""
        return [s.total for s in self.steps]

    @property
    def mesh(self) -> Mesh:
        """The last mesh."""
        return self.steps[-1].mesh

    def __len__(self) -> int:
        return len(self.steps)

    def __repr__(self) -> str:
        return f"<AdaptResult: {len(self.steps)} meshes, nodes {self.nodes}>"


SolveResult = Any  # eta, or (u, eta), or (u, None)


def _split_result(mesh: Mesh, out: SolveResult, step: int) -> tuple[FloatArray | None, FloatArray | None]:
    where = f"solve returned on mesh {step} ({mesh.n_points} nodes, {mesh.n_triangles} triangles)"
    if isinstance(out, tuple):
        if len(out) != 2:
            raise AdaptError(f"{where} a tuple of {len(out)} items; expected eta or (u, eta)")
        u_raw, eta_raw = out
        try:
            u = _check_field(mesh, u_raw) if u_raw is not None else None
            eta = _check_indicator(mesh, eta_raw) if eta_raw is not None else None
        except AdaptError as exc:
            raise AdaptError(f"{where} a bad value: {exc}") from exc
        if u is None and eta is None:
            raise AdaptError(f"{where} (None, None); expected eta or (u, eta)")
        return u, eta
    try:
        return None, _check_indicator(mesh, out)
    except AdaptError as exc:
        raise AdaptError(f"{where} a bad indicator: {exc}") from exc


def _loop_tags(reference: Mesh, mesh: Mesh) -> Mesh:
    """Renumber ``mesh``'s boundary tags so that each loop has the tag it has on ``reference``.

    Tags number loops by enclosed area; two loops of (nearly) equal area could swap between
    meshes of different resolution.  Each new loop takes the tag of the reference boundary
    edges nearest to its edge midpoints (majority vote).
    """
    rp, rbe = reference.points, reference.boundary_edges
    loc = _Locator(rp, reference.triangles, rbe)
    mid = 0.5 * (mesh.points[mesh.boundary_edges[:, 0]] + mesh.points[mesh.boundary_edges[:, 1]])
    ref_tags = np.asarray(reference.boundary_tags)
    # Each reference boundary node carries its loop's tag (loops are disjoint, so both ends of
    # an edge agree); the value at the nearest boundary point is the nearest loop's tag.
    node_tag = np.zeros(len(rp))
    node_tag[rbe[:, 0]] = ref_tags
    nearest = np.rint(loc._boundary_value(node_tag, mid)).astype(np.intp)
    new_tags = np.asarray(mesh.boundary_tags)
    mapping = {}
    for tag in np.unique(new_tags):
        votes = np.bincount(nearest[new_tags == tag])
        mapping[int(tag)] = int(np.argmax(votes))
    if len(set(mapping.values())) != len(mapping) or len(mapping) != len(np.unique(ref_tags)):
        warnings.warn(
            f"the boundary loops changed between meshes ({len(np.unique(ref_tags))} loops, tags "
            f"{sorted(np.unique(reference.boundary_tags).tolist())} before; {len(mapping)} after): "
            "a boundary curve was lost or merged; tags follow the nearest original loop",
            ConvergenceWarning,
            stacklevel=3,
        )
    if all(k == v for k, v in mapping.items()):
        return mesh
    renamed = np.array([mapping[int(k)] for k in new_tags], dtype=np.intp)
    return replace(mesh, boundary_tags=renamed)


def adapt(
    domain: Domain | Callable[[FloatArray], FloatArray],
    solve: Callable[[Mesh], SolveResult],
    size: SizeLike,
    *,
    steps: int,
    target_nodes: float | Sequence[float] | None = None,
    tolerance: float | None = None,
    order: int = 1,
    norm: Norm = "energy",
    gradation: float = GRADATION,
    h_min: float | None = None,
    h_max: float | None = None,
    smoothing: int = SMOOTHING,
    bbox: ArrayLike | None = None,
    max_nodes: int | None = None,
    callback: Callable[[AdaptStep], None] | None = None,
) -> AdaptResult:
    """Adaptive meshing: mesh, solve, derive h, mesh again, ``steps`` times.

    The first mesh follows ``size``; each next one follows :func:`size_from_indicator` of the
    indicator ``solve`` returned (or :func:`size_from_solution` of its field when it returned
    ``(u, None)``).  A mesh that misses its target by more than 5 % is made once more with the
    target rescaled by the miss, and the closer of the two is kept.  ``solve`` runs on every
    mesh, the last included, so every step reports its error.  Boundary tags keep the numbering
    of the first mesh.

    Parameters
    ----------
    domain : Domain or callable
        As in :func:`injmesh.generate` (a callable needs ``bbox``).
    solve : callable
        ``solve(mesh)`` returns the per-triangle indicator ``eta`` (the local error, not its
        square), or ``(u, eta)`` with a nodal solution ``u``, or ``(u, None)`` to adapt to u's
        recovered Hessian.
    size : float or callable
        Size function of the first mesh.
    steps : int
        Number of remeshes (``steps + 1`` meshes, ``steps + 1`` solves).
    target_nodes : float or sequence of float, optional
        Node count of each new mesh: one number for every step, or one per step.
    tolerance : float, optional
        Instead of ``target_nodes``: the indicator total to reach; each remesh aims at
        ``TOLERANCE_MARGIN`` (0.9) times it, and the loop stops early once a mesh reaches it.
    order, norm, gradation, h_min, h_max, smoothing
        As in :func:`size_from_indicator`.
    bbox : optional
        Passed to :func:`injmesh.generate`.
    max_nodes : int, optional
        Passed to :func:`injmesh.generate`.
    callback : callable, optional
        Called with each :class:`AdaptStep` once its solve has run.

    Returns
    -------
    AdaptResult

    Raises
    ------
    SolveError
        ``solve`` raised (the message names the step and the mesh; the original is chained).
    AdaptError
        ``solve`` returned something malformed, or a bad option or target.

    Warns
    -----
    ConvergenceWarning
        A mesh misses its ``target_nodes`` by more than 10 % even after the retry (the mesher
        did not follow the size function), or a boundary loop was lost between meshes.

    Examples
    --------
    >>> import numpy as np, injmesh
    >>> from injmesh import adapt
    >>> def solve(mesh):     # the interpolation error of a steep tanh, from its Hessian
    ...     return np.tanh(30 * (mesh.points[:, 0] - 0.3)), None
    >>> res = adapt.adapt(injmesh.Rectangle((0, 0), (1, 1)), solve, 0.1, steps=2, target_nodes=500)
    >>> res.nodes[0] < res.nodes[-1] and abs(res.nodes[-1] / 500 - 1) < 0.1
    True
    """
    if isinstance(steps, (bool, np.bool_)) or not isinstance(steps, (int, np.integer)) or steps < 0:
        raise AdaptError(f"steps must be a non-negative integer, got {steps!r}")
    if (target_nodes is None) == (tolerance is None):
        raise AdaptError("pass exactly one of target_nodes and tolerance")
    targets: list[float | None]
    if target_nodes is None:
        targets = [None] * steps
        _positive_option(tolerance, "tolerance")
    elif isinstance(target_nodes, (int, float, np.integer, np.floating, bool)):
        targets = [float(target_nodes)] * steps
    else:
        try:
            targets = [float(x) for x in target_nodes]  # type: ignore[union-attr]
        except (TypeError, ValueError) as exc:
            raise AdaptError(f"target_nodes must be a number or a sequence of numbers: {exc}") from exc
        if len(targets) != steps:
            raise AdaptError(f"target_nodes has {len(targets)} entries for steps={steps}")
    for tn in targets:
        _check_count(tn, None if tn is not None else tolerance)
    _exponent(order, norm)
    _check_common(gradation, smoothing)
    if not callable(solve):
        raise TypeError(f"solve must be a callable solve(mesh), got {type(solve).__name__}")

    options: dict[str, Any] = {"bbox": bbox}
    if max_nodes is not None:
        options["max_nodes"] = max_nodes
    mesh = generate(domain, size, **options)
    reference = mesh
    history: list[AdaptStep] = []
    target: float | None = None
    for k in range(steps + 1):
        try:
            out = solve(mesh)
        except Exception as exc:
            raise SolveError(
                f"solve raised on mesh {k} ({mesh.n_points} nodes, {mesh.n_triangles} triangles): "
                f"{type(exc).__name__}: {exc}"
            ) from exc
        u, eta = _split_result(mesh, out, k)
        if eta is not None:
            total = float(np.sqrt(np.sum(eta**2)))
        else:
            assert u is not None
            total = _hessian_total(mesh, u, norm)
        step = AdaptStep(mesh, u, eta, total, target)
        history.append(step)
        logger.info("adapt step %d: %d nodes, target %s, indicator total %.4g",
                    k, mesh.n_points, target, total)
        if callback is not None:
            callback(step)
        if k == steps or (tolerance is not None and total <= tolerance):
            break
        target = targets[k]
        common: dict[str, Any] = dict(
            tolerance=None if target is not None or tolerance is None else TOLERANCE_MARGIN * tolerance,
            norm=norm, order=order,
            gradation=gradation, h_min=h_min, h_max=h_max, smoothing=smoothing,
        )

        def sized(goal: float | None, old: Mesh = mesh, u: FloatArray | None = u,
                  eta: FloatArray | None = eta, common: dict[str, Any] = common) -> NodalSize:
            return _next_size(old, u, eta, goal, common)

        new = generate(domain, sized(target), **options)
        if target is not None and abs(new.n_points / target - 1) > RETRY_MISS:
            # The estimate assumes the mesher's edges follow h on average; where they do not
            # (around strongly refined interior points edges come out up to 8 % long), rescale
            # the target by the miss once and keep the closer mesh.
            retry = generate(domain, sized(target * target / new.n_points), **options)
            logger.info("adapt step %d: %d nodes for target %.0f, remeshed: %d nodes",
                        k + 1, new.n_points, target, retry.n_points)
            if abs(retry.n_points - target) < abs(new.n_points - target):
                new = retry
            if abs(new.n_points / target - 1) > 2 * RETRY_MISS:
                warnings.warn(
                    f"adapt step {k + 1}: the mesh has {new.n_points} nodes for target_nodes="
                    f"{target:.0f} ({100 * (new.n_points / target - 1):+.0f} %): the mesher does not "
                    "follow this size function closely (see the mesh's size_report())",
                    ConvergenceWarning,
                    stacklevel=2,
                )
        mesh = _loop_tags(reference, new)
    return AdaptResult(tuple(history))


def _next_size(
    mesh: Mesh, u: FloatArray | None, eta: FloatArray | None, target: float | None, options: dict[str, Any]
) -> NodalSize:
    """The size for the next mesh of :func:`adapt`: from eta when given, else from u."""
    if eta is not None:
        return size_from_indicator(mesh, eta, target_nodes=target, **options)
    assert u is not None  # _split_result returns at least one of them
    options = {k: v for k, v in options.items() if k != "order"}
    return size_from_solution(mesh, u, target_nodes=target, **options)


def _hessian_total(mesh: Mesh, u: FloatArray, norm: Norm) -> float:
    hess = recovered_hessian(mesh, u)
    lam = np.sqrt(0.5 * np.sum(hess**2, axis=(1, 2)))
    hs = _element_sizes(signed_areas(mesh.points, mesh.triangles))
    m = _exponent(1, norm)
    const = C_H1 if norm == "energy" else C_L2
    return float(np.sqrt(np.sum((const * lam[mesh.triangles].mean(axis=1) * hs**m) ** 2)))


__all__ = [
    "AdaptError",
    "AdaptResult",
    "AdaptStep",
    "NodalSize",
    "SolveError",
    "adapt",
    "interpolate",
    "recovered_hessian",
    "size_from_indicator",
    "size_from_solution",
]
