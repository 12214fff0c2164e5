"""The original DistMesh of Persson and Strang (2004): the paper's baseline, Section 2.2.

DistMesh places nodes on an equilateral grid of spacing ``h0`` over the bounding box, keeps
those inside the domain, thins them by rejection with probability proportional to ``1/h(p)^2``,
and then moves them as the joints of a truss whose bars push apart (Eq. 2.4-2.7) until the
interior nodes stop moving.  Nodes that leave the domain are pulled back onto the boundary by
Eq. (2.8).  The connectivity is the Delaunay triangulation of the nodes, recomputed whenever a
node has moved more than ``TTOL * h0`` since the last triangulation.

This module follows the algorithm as published (written from the equations, not from the GPL
ports), with the same constants, so that the comparison of the paper's Section 5 is against the
real baseline.  It shares injmesh's conventions: points ``(n, 2)`` float64, triangles ``(m, 3)``
counter-clockwise, and the result is a :class:`~injmesh.mesh.Mesh`.  The random rejection
step draws from ``numpy.random.default_rng(seed)``, so a seed fixes the mesh bit for bit.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .geometry import Domain, GeometryError
from .geometry.base import as_points
from .mesh import Mesh, MeshStats
from .progress import Callback, report
from .sizing import as_size_function
from .triangulation import TriangulationError, boundary_edges, delaunay

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

# The constants of DistMesh (Persson & Strang 2004); they are part of the algorithm's definition.

#: Desired bar lengths are scaled up by this factor so that most bars push (Eq. 2.7).
FSCALE = 1.2
#: Forward-Euler time step of Eq. (2.4).
DELTAT = 0.2
#: A point belongs to the domain when ``d < GEPS_FACTOR * h0`` (and a triangle is kept when the
#: signed distance of its centroid is below ``-GEPS_FACTOR * h0``).
GEPS_FACTOR = 1e-3
#: Retriangulate when some node has moved more than ``TTOL * h0`` since the last triangulation.
TTOL = 0.1
#: Stop when no interior node moves more than ``DPTOL * h0`` in one step.
DPTOL = 1e-3
#: Step of the one-sided difference that estimates grad d in Eq. (2.8), as a fraction of h0.
DEPS_FACTOR = math.sqrt(float(np.finfo(float).eps))

#: Default cap on the number of iterations.
DEFAULT_MAX_ITERATIONS = 10_000
#: Points per side of the grid on which the default h0 (the smallest h) is sought.
H0_SAMPLES = 201


def distmesh(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    *,
    h0: float | None = None,
    seed: int | None = None,
    fixed_points: ArrayLike | None = None,
    max_iterations: int | None = None,
    max_nodes: int = 5_000_000,
    callback: Callback | None = None,
) -> Mesh:
    """Mesh ``domain`` with the original DistMesh algorithm (the paper's Section 2.2).

    1. An equilateral grid of spacing ``h0`` covers the bounding box (rows ``h0 * sqrt(3)/2``
       apart, every other row shifted by ``h0/2``); points with ``d >= GEPS_FACTOR * h0`` go.
    2. Rejection: with ``r0 = 1/h(p)^2``, a point is kept when a uniform draw is below
       ``r0 / max(r0)``.  The domain's corners and the user's ``fixed_points`` (deduplicated,
       those outside dropped) are put first; they never move.
    3. Loop: when some node has moved more than ``TTOL * h0`` since the last triangulation,
       retriangulate (Delaunay; triangles whose centroid has ``d >= -GEPS_FACTOR * h0`` are
       dropped).  For every bar of current length ``L``, the desired length is
       ``L0 = FSCALE * s * h(midpoint)`` with ``s = sqrt(sum L^2 / sum h^2)`` (Eq. 2.7) and the
       repulsive force is ``F = max(L0 - L, 0)`` (Eq. 2.6).  Nodes move by ``DELTAT`` times
       the sum of their bar forces (Eq. 2.4-2.5); fixed nodes do not move (not even by the
       projection); nodes that end up outside (``d > 0``) are projected back by Eq. (2.8),
       ``p - d grad d / |grad d|^2``, with a one-sided difference of step ``DEPS_FACTOR * h0``
       for the gradient.
    4. Stop when every interior node (``d < -GEPS_FACTOR * h0``) moved less than ``DPTOL * h0``
       in the last step, or after ``max_iterations`` steps (then ``converged`` is False).

    The returned mesh is the Delaunay triangulation of the final nodes (filtered as in step 3),
    without unused nodes.

    Notes
    -----
    The listing in Persson and Strang's paper writes the stopping test as
    ``max(sqrt(sum(deltat*Ftot.^2, 2))) / h0 < dptol``, with ``DELTAT`` inside the square root,
    i.e. ``sqrt(DELTAT) |F|`` rather than the step ``DELTAT |F|`` its text describes.  This
    function tests the step.  The listing's test is ``1/sqrt(DELTAT)`` (about 2.2) times stricter:
    on the paper's unit disc at ``h0 = 0.01`` it takes about 1.6 times more iterations (2300-3100
    instead of 1300-2200) for the same nodes.  Density control (deleting nodes of much too short
    bars, found in later versions of the MATLAB code) is not part of the published algorithm and
    is not done.

    Parameters
    ----------
    domain : Domain
        The region to mesh; its :meth:`~injmesh.geometry.Domain.corners` become fixed nodes.
    h : callable
        Relative size function ``h(p) -> (n,)`` for ``p`` of shape ``(n, 2)``.  DistMesh uses
        only ratios of h: the absolute edge length is set by the number of nodes, hence by h0.
    h0 : float, optional
        Spacing of the initial grid, in domain units.  Default: the smallest h over the points
        of a ``H0_SAMPLES x H0_SAMPLES`` grid of the bounding box that lie in the domain
        (``d <= 0``), which makes the edges near the smallest h about h long.
    seed : int, optional
        Seed of :func:`numpy.random.default_rng` for the rejection step.  The same seed gives
        the bit-identical mesh; None draws fresh entropy.
    fixed_points : (k, 2) array_like, optional
        Extra nodes that never move (in addition to the domain's corners).
    max_iterations : int, optional
        Cap on iterations, default ``DEFAULT_MAX_ITERATIONS`` (10000).
    max_nodes : int
        Raise :class:`~injmesh.errors.NodeBudgetError` when the initial grid over the bounding
        box would hold more points than this.
    callback : callable, optional
        Receives a :class:`~injmesh.progress.Progress` with stage ``"distmesh"`` every
        iteration; its info holds ``nodes`` and ``max_move`` (the largest interior step, in
        domain units).

    Returns
    -------
    Mesh
        With ``stats.method == "distmesh"``; ``stats.initial_nodes`` counts the nodes after
        rejection, ``stats.boundary_nodes`` the nodes on the final boundary.

    Raises
    ------
    NodeBudgetError
        The initial grid would exceed ``max_nodes`` points.
    ValueError
        ``h0`` is not a positive finite number, or fewer than three nodes survive rejection.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Circle
    >>> h = lambda p: 0.2 * np.hypot(p[:, 0] - 1, p[:, 1]) + 0.04
    >>> mesh = distmesh(Circle((0, 0), 1), h, h0=0.04, seed=1)
    >>> 90 < mesh.n_points < 130 and bool(mesh.quality().min() > 0.5)
    True
    """
    h = as_size_function(h)
    if h0 is None:
        h0 = default_h0(domain, h)
    if not (isinstance(h0, (int, float, np.integer, np.floating)) and math.isfinite(h0) and h0 > 0):
        raise ValueError(f"h0 must be a positive finite length, got {h0!r}")
    h0 = float(h0)
    max_iterations = DEFAULT_MAX_ITERATIONS if max_iterations is None else int(max_iterations)
    _check_budget(domain, h0, max_nodes)
    geps = GEPS_FACTOR * h0
    deps = DEPS_FACTOR * h0
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()

    rng = np.random.default_rng(seed)
    p, n_fixed = _initial(domain, h, h0, rng, fixed_points)
    if len(p) < 3:
        raise TriangulationError(
            f"DistMesh kept only {len(p)} nodes with h0={h0:g}; use a smaller h0"
        )
    n_initial = len(p)
    seconds["initial"] = time.perf_counter() - t0
    t0 = time.perf_counter()

    pold = np.full_like(p, np.inf)
    bars = np.empty((0, 2), dtype=np.intp)
    retriangulations = 0
    converged = False
    iterations = 0
    for iterations in range(1, max_iterations + 1):
        # Retriangulate when the nodes have moved enough since the last Delaunay.
        if np.max(np.sum((p - pold) ** 2, axis=1)) > (TTOL * h0) ** 2:
            pold = p.copy()
            bars = _bars(_triangulate(domain, p, geps), len(p))
            retriangulations += 1

        # Bar forces, Eq. (2.6)-(2.7).
        barvec = p[bars[:, 0]] - p[bars[:, 1]]
        length = np.hypot(barvec[:, 0], barvec[:, 1])
        hbars = h(0.5 * (p[bars[:, 0]] + p[bars[:, 1]]))
        l0 = hbars * FSCALE * math.sqrt(float(np.sum(length**2) / np.sum(hbars**2)))
        force = np.maximum(l0 - length, 0.0)
        fvec = (force / length)[:, None] * barvec

        # Sum over the bars at each node, Eq. (2.5); fixed nodes do not move.
        n = len(p)
        ftot = np.stack(
            [
                np.bincount(bars[:, 0], fvec[:, 0], n) - np.bincount(bars[:, 1], fvec[:, 0], n),
                np.bincount(bars[:, 0], fvec[:, 1], n) - np.bincount(bars[:, 1], fvec[:, 1], n),
            ],
            axis=1,
        )
        ftot[:n_fixed] = 0.0
        p = p + DELTAT * ftot  # Eq. (2.4)

        # Bring the nodes that left the domain back to the boundary, Eq. (2.8).
        d = domain.sdf(p)
        out = d > 0
        out[:n_fixed] = False  # fixed nodes stay exactly where they were given
        if out.any():
            p[out] = _project(domain, p[out], d[out], deps)

        # Termination: every interior node moved less than DPTOL * h0.
        interior = d < -geps
        step2 = np.sum(ftot[interior] ** 2, axis=1)
        max_move = DELTAT * math.sqrt(float(step2.max())) if len(step2) else 0.0
        report(callback, "distmesh", iterations, max_iterations, nodes=n, max_move=max_move)
        if max_move < DPTOL * h0:
            converged = True
            break

    # The mesh is the Delaunay triangulation of the final nodes.
    triangles = _triangulate(domain, p, geps)
    retriangulations += 1
    points, triangles = _compact(p, triangles)
    edges = boundary_edges(triangles)
    seconds["smoothing"] = time.perf_counter() - t0

    stats = MeshStats(
        method="distmesh",
        iterations=iterations,
        converged=converged,
        retriangulations=retriangulations,
        boundary_nodes=int(len(np.unique(edges))),
        initial_nodes=n_initial,
        seconds=seconds,
    )
    return Mesh(
        points=points,
        triangles=triangles,
        boundary_edges=edges,
        boundary_tags=boundary_components(points, edges),
        size=h,
        stats=stats,
    )


def initial_points(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    h0: float,
    rng: np.random.Generator,
    *,
    fixed_points: ArrayLike | None = None,
) -> FloatArray:
    """DistMesh's initial nodes: fixed points, then the grid thinned by rejection.

    This is steps 1-2 of :func:`distmesh` (the nodes of the paper's Figure 1a).  Given a
    generator in the same state (``numpy.random.default_rng(seed)``), it returns exactly the
    nodes :func:`distmesh` starts from with that seed.

    Parameters
    ----------
    domain : Domain
        The region; its corners come first.
    h : callable
        Relative size function ``h(p) -> (n,)``.
    h0 : float
        Spacing of the equilateral grid.
    rng : numpy.random.Generator
        Source of the rejection draws (one draw per grid point in the domain).
    fixed_points : (k, 2) array_like, optional
        Extra fixed nodes.

    Returns
    -------
    (n, 2) float64 array

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Rectangle
    >>> p = initial_points(Rectangle((0, 0), (1, 1)), lambda p: np.ones(len(p)), 0.25,
    ...                    np.random.default_rng(0))
    >>> p[:4].tolist()  # the corners, then the grid
    [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    """
    return _initial(domain, as_size_function(h), float(h0), rng, fixed_points)[0]


def default_h0(domain: Domain, h: Callable[[FloatArray], FloatArray]) -> float:
    """The default h0: the smallest h over a grid of sample points in the domain.

    The samples are the ``H0_SAMPLES x H0_SAMPLES`` grid of the bounding box (edges included)
    with ``d <= 0``.

    Raises
    ------
    GeometryError
        No sample lies in the domain.
    """
    x0, y0, x1, y1 = domain.bbox
    x, y = np.meshgrid(np.linspace(x0, x1, H0_SAMPLES), np.linspace(y0, y1, H0_SAMPLES))
    p = np.stack([x.ravel(), y.ravel()], axis=1)
    p = p[domain.sdf(p) <= 0]
    if len(p) == 0:
        raise GeometryError(f"no point of a {H0_SAMPLES}x{H0_SAMPLES} grid of the box lies inside")
    return float(np.min(h(p)))


def boundary_components(points: FloatArray, edges: IntArray) -> IntArray:
    """Label each boundary edge with its connected component (boundary loop).

    Components are numbered by decreasing extent (the diagonal of their bounding box): 0 is the
    largest (the outer boundary of a domain with holes), ties keep the order of discovery.

    Parameters
    ----------
    points : (n, 2) float64 array
    edges : (k, 2) int array
        Boundary edges.

    Returns
    -------
    (k,) int array

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0, 0], [1, 0], [0, 1], [0.2, 0.2], [0.3, 0.2], [0.2, 0.3]], float)
    >>> e = np.array([[3, 4], [4, 5], [5, 3], [0, 1], [1, 2], [2, 0]])
    >>> boundary_components(p, e).tolist()
    [1, 1, 1, 0, 0, 0]
    """
    if len(edges) == 0:
        return np.zeros(0, dtype=np.intp)
    n = len(points)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    comp = label[edges[:, 0]]
    used, comp = np.unique(comp, return_inverse=True)
    k = len(used)
    nodes = edges.ravel()
    node_comp = np.repeat(comp, 2)
    lo = np.full((k, 2), np.inf)
    hi = np.full((k, 2), -np.inf)
    np.minimum.at(lo, node_comp, points[nodes])
    np.maximum.at(hi, node_comp, points[nodes])
    extent = np.hypot(*(hi - lo).T)
    order = np.argsort(-extent, kind="stable")
    rank = np.empty(k, dtype=np.intp)
    rank[order] = np.arange(k)
    return rank[comp].astype(np.intp)


# --- internals -------------------------------------------------------------------------------


def _check_budget(domain: Domain, h0: float, max_nodes: int) -> None:
    """Raise NodeBudgetError before allocating a grid with more than ``max_nodes`` points."""
    from .errors import NodeBudgetError

    nx, ny = _grid_shape(domain.bbox, h0)
    if nx * ny > max_nodes:
        raise NodeBudgetError(
            f"DistMesh's initial grid with h0={h0:g} has {nx * ny} points over the bounding box, "
            f"more than max_nodes={max_nodes}; use a larger h0 or raise max_nodes"
        )


def _grid_shape(bbox: tuple[float, float, float, float], h0: float) -> tuple[int, int]:
    """Columns and rows of the equilateral grid covering ``bbox``."""
    x0, y0, x1, y1 = bbox
    dy = h0 * math.sqrt(3) / 2
    return int(math.floor((x1 - x0) / h0)) + 1, int(math.floor((y1 - y0) / dy)) + 1


def _initial(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    h0: float,
    rng: np.random.Generator,
    fixed_points: ArrayLike | None,
) -> tuple[FloatArray, int]:
    """Steps 1-2 of DistMesh: ``(points, n_fixed)``, fixed points first."""
    geps = GEPS_FACTOR * h0
    x0, y0, _, _ = domain.bbox
    nx, ny = _grid_shape(domain.bbox, h0)
    x = x0 + h0 * np.arange(nx)
    y = y0 + (h0 * math.sqrt(3) / 2) * np.arange(ny)
    xx, yy = np.meshgrid(x, y)  # rows of constant y
    xx[1::2] += h0 / 2  # shift every other row: equilateral triangles
    p = np.stack([xx.ravel(), yy.ravel()], axis=1)
    p = p[domain.sdf(p) < geps]
    if len(p):
        r0 = 1.0 / h(p) ** 2
        p = p[rng.random(len(p)) < r0 / r0.max()]

    fixed = _fixed(domain, fixed_points, geps)
    if len(fixed) and len(p):
        near, _ = cKDTree(fixed).query(p, distance_upper_bound=geps)
        p = p[~np.isfinite(near)]
    return np.concatenate([fixed, p]), len(fixed)


def _fixed(domain: Domain, fixed_points: ArrayLike | None, geps: float) -> FloatArray:
    """The domain's corners and the user's fixed points in the domain, without duplicates."""
    parts = [as_points(domain.corners())]
    if fixed_points is not None:
        parts.append(as_points(fixed_points))
    fixed = np.concatenate(parts) if parts else np.empty((0, 2))
    if len(fixed) == 0:
        return np.empty((0, 2))
    fixed = fixed[domain.sdf(fixed) < geps]
    if len(fixed) > 1:
        pairs = cKDTree(fixed).query_pairs(geps, output_type="ndarray")
        keep = np.ones(len(fixed), dtype=bool)
        keep[pairs.max(axis=1)] = False
        fixed = fixed[keep]
    return fixed


def _triangulate(domain: Domain, p: FloatArray, geps: float) -> IntArray:
    """Delaunay triangles of ``p`` whose centroid is inside, ``d < -geps``."""
    t = delaunay(p)
    centroids = p[t].mean(axis=1)
    t = t[domain.sdf(centroids) < -geps]
    if len(t) == 0:
        raise TriangulationError("no triangle of the DistMesh nodes lies inside the domain")
    return t


def _bars(triangles: IntArray, n: int) -> IntArray:
    """The distinct edges of ``triangles`` as ``(k, 2)`` with ``i < j``, sorted."""
    e = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    lo = np.minimum(e[:, 0], e[:, 1]).astype(np.int64)
    hi = np.maximum(e[:, 0], e[:, 1]).astype(np.int64)
    key = np.unique(lo * n + hi)
    return np.stack([key // n, key % n], axis=1).astype(np.intp)


def _project(domain: Domain, p: FloatArray, d: FloatArray, deps: float) -> FloatArray:
    """Eq. (2.8): ``p - d grad d / |grad d|^2``, grad d by a forward difference of step deps."""
    gx = (domain.sdf(p + [deps, 0.0]) - d) / deps
    gy = (domain.sdf(p + [0.0, deps]) - d) / deps
    g2 = gx**2 + gy**2
    g2 = np.where(g2 > 0, g2, 1.0)
    return p - (d / g2)[:, None] * np.stack([gx, gy], axis=1)


def _compact(p: FloatArray, triangles: IntArray) -> tuple[FloatArray, IntArray]:
    """Drop the nodes no triangle uses and renumber the triangles."""
    used = np.zeros(len(p), dtype=bool)
    used[triangles.ravel()] = True
    new = np.cumsum(used) - 1
    return p[used], new[triangles].astype(np.intp)
