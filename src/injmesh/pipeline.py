"""``generate``: the paper's Algorithm 1, and the DistMesh baseline behind the same call."""

from __future__ import annotations

import logging
import math
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _tolerances as tol
from .boundary import (
    BoundaryMesh,
    CurveMesh,
    corner_size,
    estimate_nodes,
    mesh_boundary,
    mesh_curves,
    sharp_junctions,
)
from .errors import ConvergenceWarning, MeshError, NodeBudgetError
from .geometry import BRep, Difference, Domain, GeometryError, Intersection, Union, as_domain
from .geometry.base import KernelBoundary, as_points, dedupe_points
from .geometry.regions import Constraints, CurvesLike, RegionsLike, build_constraints
from .geometry.tracing import grid_spacing
from .injection import inject_nodes
from .mesh import Mesh, MeshStats
from .progress import Callback, compile_progress
from .sizing import GriddedSize, SizeFunction, SizeLike, as_size_function, effective_size
from .sizing.features import unrestricted
from .smoothing import Interfaces, Smoothing, SmoothResult, smooth
from .triangulation import boundary_edges
from .validate import Defect, mesh_defects

FloatArray = NDArray[np.float64]

DEFAULT_MAX_NODES = 5_000_000

#: Geometry is cleaned at this fraction of the smallest h (see ``_clean``).
CLEAN = 0.01
#: By default a part of the outline beyond a pinch narrower than CLEAN * h_min is dropped only
#: when its area is at most PINCH_AREA * h_min**2 (smaller than two elements); a larger one is
#: a GeometryError naming the place (see ``_clean``).
PINCH_AREA = 1.0

logger = logging.getLogger(__name__)


def generate(
    domain: Domain | Callable[[FloatArray], FloatArray] | object,
    size: SizeLike,
    *,
    method: Literal["injection", "distmesh"] = "injection",
    bbox: ArrayLike | None = None,
    fixed_points: ArrayLike | None = None,
    max_iterations: int | None = None,
    max_nodes: int = DEFAULT_MAX_NODES,
    smoothing: Smoothing = "hybrid",
    h0: float | None = None,
    seed: int | None = None,
    feature_layers: float | None = 2.0,
    gradation: float | None = 0.2,
    target_nodes: int | None = None,
    strict: bool = True,
    callback: Callback | None = None,
    regions: RegionsLike | None = None,
    curves: CurvesLike | None = None,
    min_feature: float | None = None,
) -> Mesh:
    """Mesh a 2-D domain with triangles whose edges follow the size function h.

    With ``method="injection"`` (the default) this is Algorithm 1 of the paper: boundary meshing
    (Step 1), Advancing Node Injection (Step 2), then Delaunay triangulation and attractive
    smoothing (Step 3).  ``method="distmesh"`` runs the original Persson-Strang algorithm, the
    paper's baseline, with the same conventions.

    Parameters
    ----------
    domain : Domain, callable or shape
        A :class:`~injmesh.geometry.Domain`, a plain signed distance ``d(p) -> (n,)``
        (negative inside) for ``p`` of shape ``(n, 2)`` (a callable needs ``bbox``), or a shape
        :func:`~injmesh.geometry.as_domain` reads: a shapely geometry or anything with
        ``__geo_interface__``, a GeoJSON dict, WKT text, an ``(n, 2)`` array of vertices.
    size : float, callable or str
        Target edge length: a number, ``h(p) -> (n,)``, positive, in domain units, or a safe
        expression in ``x`` and ``y`` (``"0.02 + 0.1*x"``).  h is asked only at points inside
        the domain or on its boundary.
    method : {"injection", "distmesh"}
        The algorithm.
    bbox : (xmin, ymin, xmax, ymax), optional
        Required for a callable ``domain``; ignored for a Domain.
    fixed_points : (k, 2) array_like, optional
        Points that become mesh nodes and never move.  On the boundary they act as corners.
        A point within 1e-6 of the domain's diameter of an earlier one, or of a corner, is
        that point; where cleaning moved the outline, points within its tolerance of the
        cleaned boundary are put on it (``mesh.stats.cleaning["merged_fixed_points"]``
        counts both), so a DistMesh ``pfix`` of a GIS outline's vertices meshes.
    max_iterations : int, optional
        Cap on smoothing iterations (default 1000 for injection, 10000 for DistMesh).  Reaching it
        emits a :class:`ConvergenceWarning` and returns a mesh with ``converged=False``.  An
        iteration is a step over the whole mesh; steps that move only part of it (the repair
        rounds, the last nodes still moving) count in proportion to the nodes they move.
    max_nodes : int
        Refuse (:class:`NodeBudgetError`) a mesh that would need more nodes than this.  With
        ``target_nodes`` it is ``target_nodes`` that is checked against it (the stages' own
        checks are estimates, and the search may try a finer scale on its way).
    smoothing : {"hybrid", "attractive"}
        Injection only.  ``"hybrid"``: the paper's attractive force (Eq. 3.4) to relax the
        injected nodes, then a spring with rest length h to convergence, then local repair of
        bad triangles (see :mod:`injmesh.smoothing`).  ``"attractive"``: the paper's force alone,
        as printed, to reproduce its results.
    h0 : float, optional
        DistMesh only: the spacing of its initial grid (default: the smallest h on the domain).
    seed : int, optional
        DistMesh only: seed of its random rejection step.
    feature_layers : float or None
        Injection only.  Where the domain is thinner than ``feature_layers`` elements of size h
        (straits, channels, a hole close to the boundary, a spike), the size becomes
        ``feature_size / feature_layers`` (:func:`injmesh.sizing.feature_size`, the local
        thickness), so thin parts get small well-shaped triangles rather than slivers.  None
        turns it off.
    gradation : float or None
        Injection only.  The size actually followed grows by at most this much per unit length
        (|grad h| <= gradation, :func:`injmesh.sizing.limit_gradation`): a size that jumps still
        gives well-shaped triangles.  None turns it off.  When neither correction changes h
        anywhere, h itself is followed; ``mesh.size`` is the size followed.
    target_nodes : int, optional
        Injection only.  About this many nodes (within 3 % on the paper's cases, usually 1 %):
        ``size`` then gives the shape of h and is multiplied by the constant that meets the
        count (``generate(domain, 1.0, target_nodes=5000)`` is a uniform mesh of about 5000
        nodes).  The feature size and gradation corrections apply to the scaled h, so they
        still refine thin parts (and set the fewest nodes reachable: a smaller count warns
        with :class:`ConvergenceWarning`).  The constant comes from the size integral
        ``(2/sqrt(3)) int h^-2 dA`` (:func:`~injmesh.boundary.estimate_nodes`), then a secant in
        log-log space on the node counts of Steps 1 and 2 (cheap next to smoothing), then one
        full mesh; up to three more (retargeted by the nodes smoothing added, then secants on
        the meshes' counts) only when it misses by more than 1 %, the closest kept.  Every
        trial recomputes the feature size and gradation, most of the cost: 1.5-2.5x a plain
        call at 3000 nodes on the paper's cases, more on small or strongly graded meshes.
        Deterministic.  Must not exceed ``max_nodes``.
    strict : bool
        The mesh is checked before it is returned (:mod:`injmesh.validate`: no duplicate or
        unused node, no flat or inverted triangle, every boundary segment a boundary edge, every
        boundary node on the boundary, no triangle outside).  A mesh that fails raises
        :class:`MeshError` naming each defect and where; with ``strict=False`` it is returned
        with ``mesh.stats.valid == False`` and the list in ``mesh.stats.defects`` (and a
        warning).
    callback : callable, optional
        Called with a :class:`~injmesh.progress.Progress` event per boundary sweep, injection
        layer and smoothing iteration, and per kernel numba compiles on first use
        (:func:`~injmesh.progress.compile_progress`).
    regions : mapping name -> Domain or callable, optional
        Injection only.  Sub-regions of the domain (materials, zones), which may touch each
        other and the domain's boundary but not overlap; a plain callable ``d(p)`` uses the
        domain's bbox.  Their boundaries inside the domain are meshed like the boundary (Step
        1, points where they meet fixed), Step 2 injects from both sides of them, smoothing
        slides their nodes along them, and every one of their segments is a mesh edge.
        ``mesh.triangle_tags`` gives each triangle's region (0: the rest of the domain,
        k: the k-th region), ``mesh.region_names`` their names.
    curves : mapping name -> (k, 2) array_like, or a sequence of them, optional
        Injection only.  Polylines inside the domain that must be mesh edges (interfaces,
        cracks, faults); a polyline whose last point is its first (or misses it by less
        than ``h_min / 20``, with a warning) is closed.  End points,
        vertices where a polyline turns and crossings are fixed nodes.  ``mesh.curve_edges``
        holds every interior constraint edge, ``mesh.curve_tags`` its curve, indexing
        ``mesh.curve_names`` (the curves, then the interfaces between regions).
    min_feature : float, optional
        Injection only.  Where the outline comes back within ``min_feature`` of itself (a neck
        of the domain, an inlet's mouth, a hole or an island almost touching another ring),
        the outline is cut there and the smaller part beyond is dropped (a lobe or an island
        removed, a pocket or a hole filled), with a warning naming each place; the count is
        ``mesh.stats.cleaning["pinched_parts"]`` (:meth:`Polygon.cleaned
        <injmesh.geometry.Polygon.cleaned>`; polygonal boundaries only).  Thinner parts than
        this are not meshed; thicker ones are, with elements of about ``feature size /
        feature_layers``.  By default it is 1 % of the smallest h, the tolerance at which
        vertices are merged, and a part larger than ``h_min**2`` beyond such a pinch raises
        :class:`GeometryError` naming the place instead of being dropped; given explicitly,
        every part beyond a narrower pinch is dropped, whatever its size.  0 turns it off (a
        pinch then needs elements about as small as its width).

    Returns
    -------
    Mesh

    Raises
    ------
    MeshError
        The mesh failed its checks (only with ``strict=True``).
    RegionError, CurveError
        A region outside the domain or overlapping another, a curve leaving the domain or
        crossing itself.

    Examples
    --------
    >>> import injmesh
    >>> mesh = injmesh.generate(injmesh.Circle((0, 0), 1), 0.2)
    >>> bool(mesh.quality().min() > 0.7)
    True
    """
    # The kernels numba compiles on first use are progress events.  (A with-block adds no
    # frame: the warnings below still point at the caller.)
    with compile_progress(callback):
        dom = as_domain(domain, bbox=bbox, fixed_points=fixed_points)
        h = as_size_function(size)
        dom, fixed, merged_fixed = _user_fixed(domain, bbox, fixed_points, dom)
        if max_iterations is not None and (int(max_iterations) != max_iterations or max_iterations < 0):
            raise ValueError(f"max_iterations must be a non-negative integer, got {max_iterations!r}")
        if not (isinstance(max_nodes, (int, np.integer)) and max_nodes > 0):
            raise ValueError(f"max_nodes must be a positive integer, got {max_nodes!r}")
        if target_nodes is not None:
            if method != "injection":
                raise ValueError("target_nodes applies to method='injection' only")
            wanted = _check_target_nodes(target_nodes, int(max_nodes))
            budget = max(int(max_nodes), 2 * wanted)

            def at_scale(scale: float, full: bool) -> Mesh | int:
                # Full mesh, or only the node count of Steps 1 and 2, with h scaled by ``scale``.
                scaled: SizeLike = scale * h.constant if h.constant is not None else _Scaled(h, scale)
                if not full:
                    return len(initial_nodes(domain, scaled, bbox=bbox, fixed_points=fixed_points,
                                             max_nodes=budget, feature_layers=feature_layers,
                                             gradation=gradation, min_feature=min_feature))
                return generate(domain, scaled, bbox=bbox, fixed_points=fixed_points,
                                max_iterations=max_iterations, max_nodes=budget, smoothing=smoothing,
                                feature_layers=feature_layers, gradation=gradation, strict=strict,
                                callback=callback, regions=regions, curves=curves, min_feature=min_feature)

            return _meet_node_count(as_domain(domain, bbox=bbox, fixed_points=fixed_points), h,
                                    wanted, at_scale, budget)

        if method == "distmesh":
            from .distmesh import distmesh

            if regions is not None or curves is not None or min_feature is not None:
                raise ValueError("regions, curves and min_feature apply to method='injection' only")
            mesh = distmesh(
                dom, h, h0=h0, seed=seed, fixed_points=fixed, max_iterations=max_iterations,
                max_nodes=int(max_nodes), callback=callback,
            )
            # DistMesh has no boundary segments to hold its mesh to: the structural checks only.
            defects = tuple(mesh_defects(mesh.points, mesh.triangles, diameter=dom.diameter))
            mesh = replace(mesh, stats=replace(mesh.stats, valid=not defects, defects=defects))
        elif method == "injection":
            if h0 is not None or seed is not None:
                raise ValueError("h0 and seed apply to method='distmesh' only")
            if smoothing not in ("hybrid", "attractive"):
                raise ValueError(f"smoothing must be 'hybrid' or 'attractive', got {smoothing!r}")
            raw = dom
            dom, cleaning, known, eps = _clean(dom, h, min_feature)
            if cleaning:
                fixed, moved = _settled_fixed(dom, fixed, eps, onto=True)
                merged_fixed += moved
            constraints = None
            if regions is not None or curves is not None:
                if cleaning.get("cusps") and isinstance(regions, Mapping):
                    regions = _bridged_regions(raw, h, known, regions)
                estimate = known.of(dom, h)
                if estimate is None:
                    estimate = estimate_nodes(dom, h.restricted(dom))
                    known = _Estimate(dom, h, estimate)
                constraints = build_constraints(dom, regions, curves, estimate[0])
                if constraints.regions and feature_layers is not None:
                    h = _region_features(dom, h, constraints, feature_layers)
            cornered = corner_size(dom, h, _rate(gradation))
            target, follow = _target_size(dom, cornered, feature_layers, gradation)
            mesh = _injection(dom, follow, fixed, max_iterations, int(max_nodes), smoothing, callback,
                              constraints, known.followed(dom, cornered, target))
            if merged_fixed:
                cleaning = {**cleaning, "merged_fixed_points": merged_fixed}
            mesh = replace(mesh, size=target, stats=replace(mesh.stats, cleaning=cleaning))
        else:
            raise ValueError(f"method must be 'injection' or 'distmesh', got {method!r}")
    if not mesh.stats.converged:
        where = mesh.stats.unsettled
        at = f" (still moving most at ({where[0]:.6g}, {where[1]:.6g}))" if where else ""
        warnings.warn(
            f"{method} smoothing did not converge in {mesh.stats.iterations} iterations{at}; "
            "the mesh is returned with converged=False",
            ConvergenceWarning,
            stacklevel=2,
        )
    if not mesh.stats.valid:
        listing = "; ".join(str(d) for d in mesh.stats.defects)
        if strict:
            raise MeshError(f"the mesh failed its checks: {listing}", mesh.stats.defects)
        warnings.warn(f"the mesh is invalid (strict=False): {listing}", ConvergenceWarning, stacklevel=2)
    return mesh


def initial_nodes(
    domain: Domain | Callable[[FloatArray], FloatArray] | object,
    size: SizeLike,
    *,
    bbox: ArrayLike | None = None,
    fixed_points: ArrayLike | None = None,
    max_nodes: int = DEFAULT_MAX_NODES,
    feature_layers: float | None = 2.0,
    gradation: float | None = 0.2,
    min_feature: float | None = None,
) -> FloatArray:
    """The nodes of Steps 1 and 2 (boundary meshing and Advancing Node Injection), unsmoothed.

    This is the paper's "initial distribution" (its Figure 1b); parameters as in
    :func:`generate`.

    Returns
    -------
    (n, 2) array
        Boundary nodes first, then user fixed interior points, then injected nodes.

    Examples
    --------
    >>> import injmesh
    >>> from injmesh.pipeline import initial_nodes
    >>> initial_nodes(injmesh.Circle((0, 0), 1), 0.5).shape[1]
    2
    """
    dom = as_domain(domain, bbox=bbox, fixed_points=fixed_points)
    dom, fixed, _ = _user_fixed(domain, bbox, fixed_points, dom)
    h0 = as_size_function(size)
    dom, cleaning, known, eps = _clean(dom, h0, min_feature)
    if cleaning:
        fixed, _ = _settled_fixed(dom, fixed, eps, onto=True)
    cornered = corner_size(dom, h0, _rate(gradation))
    target, h = _target_size(dom, cornered, feature_layers, gradation)
    bnd, seeds, injected = _place_nodes(dom, h, fixed, max_nodes, None,
                                        estimate=known.followed(dom, cornered, target))
    return np.concatenate([seeds, injected])


def _place_nodes(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    fixed: FloatArray,
    max_nodes: int,
    callback: Callback | None,
    seconds: dict[str, float] | None = None,
    estimate: tuple[float, float] | None = None,
) -> tuple[BoundaryMesh, FloatArray, FloatArray]:
    """Steps 1 and 2: boundary nodes, seeds (boundary + fixed interior) and injected nodes.

    ``estimate``: :func:`~injmesh.boundary.estimate_nodes` of the domain and h, when the caller
    has it (see :class:`_Estimate`).
    """
    h = _capped(h, domain.diameter)
    t = time.perf_counter()
    # Step 1: meshing of the boundary (Eq. 3.1-3.3, Algorithms 2 and 3).
    bnd = mesh_boundary(domain, h, fixed, max_nodes=max_nodes, callback=callback, estimate=estimate)
    if seconds is not None:
        seconds["boundary"] = time.perf_counter() - t
    t = time.perf_counter()
    # Step 2: Advancing Node Injection (Algorithm 4).  Nodes are ordered boundary, user fixed
    # interior points, injected: the first n_fixed never move.
    # A point within the on-boundary tolerance of the boundary is a boundary node (Step 1's
    # corner), not an interior one as well.
    interior_fixed = fixed[domain.sdf(fixed) < -tol.ON_BOUNDARY * domain.diameter] if len(fixed) else fixed
    seeds = np.concatenate([bnd.points, interior_fixed])
    injected = inject_nodes(domain, h, bnd, seeds, max_nodes=max_nodes, callback=callback)
    if seconds is not None:
        seconds["injection"] = time.perf_counter() - t
    return bnd, seeds, injected


def _injection(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    fixed: FloatArray,
    max_iterations: int | None,
    max_nodes: int,
    smoothing: Smoothing,
    callback: Callback | None,
    constraints: Constraints | None = None,
    estimate: tuple[float, float] | None = None,
) -> Mesh:
    """Algorithm 1 of the paper (``estimate``: as in :func:`_place_nodes`)."""
    if constraints is not None:
        return _injection_with_curves(domain, h, fixed, max_iterations, max_nodes, smoothing, callback,
                                      constraints, estimate)
    seconds: dict[str, float] = {}
    # Steps 1 and 2: boundary meshing and Advancing Node Injection.
    bnd, seeds, injected = _place_nodes(domain, h, fixed, max_nodes, callback, seconds, estimate)
    points, n_fixed, remap = _merge_touching(bnd, np.concatenate([seeds, injected]), len(seeds),
                                             domain.diameter)
    t = time.perf_counter()

    # Step 3: Delaunay triangulation and attractive smoothing (Eq. 3.4).
    # Boundary nodes other than corners slide along the boundary between their neighbours.
    result = smooth(
        domain, _capped(h, domain.diameter), points, n_fixed=n_fixed, sliding=remap[_sliding(bnd)],
        walls=remap[bnd.edges], smoothing=smoothing, max_iterations=max_iterations, callback=callback,
    )
    seconds["smoothing"] = time.perf_counter() - t
    result, edges, tags, defects = _checked_boundary(domain, bnd, result)
    stats = _stats(result, len(bnd.points), len(points), seconds, defects)
    return Mesh(
        points=result.points,
        triangles=result.triangles,
        boundary_edges=edges,
        boundary_tags=tags,
        size=h,
        stats=stats,
    )


def _sliding(bnd: BoundaryMesh) -> NDArray[np.intp]:
    """Rows ``(node, previous, next)`` of the boundary nodes that slide (all but the fixed)."""
    free_b = np.flatnonzero(~bnd.fixed)
    prev = np.empty(len(bnd.points), dtype=np.intp)
    prev[bnd.edges[:, 1]] = bnd.edges[:, 0]
    return np.stack([free_b, prev[free_b], bnd.edges[free_b, 1]], axis=1)


def _bridged_regions(raw: Domain, h: SizeFunction, known: _Estimate, regions: Mapping[str, Any]
                     ) -> dict[str, Any]:
    """The regions with their cusps bridged as the domain's were (the same tolerance).

    Where the domain touches itself tangentially (a disc touching a rectangle's side), cleaning
    bridges the cusps, which adds the tip of each sliver to the domain.  A region covering both
    sides kept its own cusp there, now inside the domain, and its pieces along it were lost
    segments (found by fuzzing).  Bridged the same way, the region takes the sliver's tip too.
    """
    if h.constant is not None:
        h_min = min(h.constant, raw.diameter)
    else:
        h_min = (known.of(raw, h) or estimate_nodes(raw, h.restricted(raw)))[0]
    from .sizing.background import exact_boundary

    out: dict[str, Any] = {}
    for name, r in regions.items():
        exact = exact_boundary(r) if isinstance(r, Domain) else None
        if exact is not None:
            bridged, report = exact.cleaned(CLEAN * h_min)
            out[name] = bridged if report.get("cusps") else r
        else:
            out[name] = r
    return out


def _merge_touching(
    bnd: BoundaryMesh, points: FloatArray, n_fixed: int, diameter: float
) -> tuple[FloatArray, int, NDArray[np.intp]]:
    """The nodes for Step 3 with each point where boundary loops touch once, and the map from
    the old node numbers to the new.

    Loops that touch at a point (two rectangles corner to corner, ``a | b``) each have a
    corner node there: Step 1 and the fronts of Step 2 follow each loop on its own, but the
    triangulation keeps one of two coincident nodes, and the segments of the other loop at the
    point were lost (every such union was an invalid mesh; found by fuzzing).  The later
    duplicates of a boundary node (within ``10 * ON_BOUNDARY`` of the diameter, on another
    loop) are dropped and their segments and neighbours point at the first.
    """
    from scipy.spatial import cKDTree

    nb = len(bnd.points)
    first = np.arange(len(points))
    pairs = cKDTree(bnd.points).query_pairs(10 * tol.ON_BOUNDARY * diameter, output_type="ndarray")
    if len(pairs):
        pairs = pairs[bnd.node_loop[pairs[:, 0]] != bnd.node_loop[pairs[:, 1]]]
    if not len(pairs):
        return points, n_fixed, first
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    for a, b in sorted(zip(lo.tolist(), hi.tolist(), strict=True), key=lambda ab: ab[1]):
        first[b] = min(first[b], first[a])
    keep = first == np.arange(len(points))
    new = np.cumsum(keep) - 1
    remap = new[first]
    assert not (~keep[nb:]).any()
    return points[keep], n_fixed - int((~keep[:nb]).sum()), remap


def _checked_boundary(
    domain: Domain, bnd: BoundaryMesh, result: SmoothResult
) -> tuple[SmoothResult, NDArray[np.intp], NDArray[np.intp], list[Defect]]:
    """The result, the mesh's boundary edges, their loop tags and the mesh's defects.

    The boundary edges are Step 1's segments (some split by recovery), tagged with the loop
    each came from; a valid mesh has exactly these as its boundary edges.  When one is lost the
    mesh's actual boundary is reported instead of segments it does not have.

    A mesh whose boundary check fails while every segment is an edge may hold triangles
    outside the domain that the relaxation's flips kept (one across a slit 0.08 h wide between
    two parts of a domain, found by fuzzing): such triangles, outside by the segments' sides
    (:func:`~injmesh.triangulation.inside_mask`, as every triangulation is judged), are
    dropped, and the result is kept if it then passes.  Only a mesh that failed pays for this.
    """
    edges = result.walls
    tags = bnd.node_loop[bnd.edges[result.wall_origin, 0]]
    defects = mesh_defects(result.points, result.triangles, walls=edges, sdf=domain.sdf,
                           diameter=domain.diameter)
    if defects:
        mended = _outside_dropped(domain, result)
        if mended is not None:
            again = mesh_defects(mended.points, mended.triangles, walls=edges, sdf=domain.sdf,
                                 diameter=domain.diameter)
            if not again:
                return mended, edges, tags, []
    if any(d.kind == "lost boundary segment" for d in defects):
        edges = boundary_edges(result.triangles)
        tags = _nearest_tags(result.points, edges, result.walls, tags)
    return result, edges, tags, list(defects)


def _outside_dropped(domain: Domain, result: SmoothResult) -> SmoothResult | None:
    """``result`` without its triangles outside the domain by its segments' sides, or None when
    it has none, a segment is lost or a node would be left in no triangle."""
    from .triangulation import inside_mask

    walls = result.walls
    if len(walls) == 0 or np.any(walls < 0):
        return None
    keep = inside_mask(result.points, result.triangles, domain.sdf, walls)
    if keep.all():
        return None
    tri = result.triangles[keep]
    used = np.zeros(len(result.points), dtype=bool)
    used[tri.ravel()] = True
    if not used.all():
        return None
    return replace(result, triangles=tri)


def _stats(result: SmoothResult, boundary_nodes: int, initial_nodes: int, seconds: dict[str, float],
           defects: list[Defect]) -> MeshStats:
    return MeshStats(
        method="injection",
        iterations=result.iterations,
        converged=result.converged,
        retriangulations=result.retriangulations,
        boundary_nodes=boundary_nodes,
        initial_nodes=initial_nodes,
        seconds=seconds,
        valid=not defects,
        defects=tuple(defects),
        unsettled=result.unsettled,
    )


def _nearest_tags(points: FloatArray, edges: NDArray[np.intp], walls: NDArray[np.intp],
                  wall_tags: NDArray[np.intp]) -> NDArray[np.intp]:
    """Tags for the boundary edges of an invalid mesh: those of the nearest segment."""
    from scipy.spatial import cKDTree

    ok = np.all(walls >= 0, axis=1)
    if not ok.any():
        return np.zeros(len(edges), dtype=np.intp)
    mid = 0.5 * (points[walls[ok, 0]] + points[walls[ok, 1]])
    _, k = cKDTree(mid).query(0.5 * (points[edges[:, 0]] + points[edges[:, 1]]))
    return np.asarray(wall_tags[ok][k], dtype=np.intp)


def _capped(h: Callable[[FloatArray], FloatArray], cap: float) -> Callable[[FloatArray], FloatArray]:
    """h limited to ``cap`` (the domain's diameter): a larger size asks for nothing coarser than
    the fewest nodes the boundary needs, and keeps every length the stages compute finite.
    A constant h stays a constant :class:`SizeFunction`, so the stages can see that it is."""
    value = getattr(h, "constant", None)
    if value is not None:
        return as_size_function(min(float(value), cap))
    # Already capped as low (the stages cap what _target_size capped): min is idempotent, so
    # the same numbers without a second wrapper on every call of h (~90 per small mesh).
    if getattr(h, "cap", np.inf) <= cap:
        return h

    def capped(p: FloatArray) -> FloatArray:
        return np.minimum(h(p), cap)

    capped.cap = cap  # type: ignore[attr-defined]
    return capped


def _user_fixed(
    given: object, bbox: ArrayLike | None, fixed_points: ArrayLike | None, domain: Domain
) -> tuple[Domain, FloatArray, int]:
    """The user's fixed points as an array, those within ``ON_BOUNDARY`` of the diameter (the
    checks' own "same point") of a corner or of an earlier one merged (:func:`_settled_fixed`),
    the domain made again from a plain function with the merged ones (its corners come from
    them), and how many changed.

    A DistMesh-style ``pfix`` taken from GIS data repeats vertices 1e-7 apart; as given, each
    became a node, two nodes that close a triangle of zero area (a ``MeshError``).
    """
    fixed = np.empty((0, 2)) if fixed_points is None else as_points(fixed_points)
    fixed, merged = _settled_fixed(domain, fixed, tol.ON_BOUNDARY * domain.diameter, onto=False)
    if merged and not isinstance(given, Domain) and callable(given):
        domain = as_domain(given, bbox=bbox, fixed_points=fixed)
    return domain, fixed, merged


def _settled_fixed(domain: Domain, fixed: FloatArray, eps: float, onto: bool) -> tuple[FloatArray, int]:
    """Fixed points within ``eps`` of a corner of the domain made that corner, with ``onto``
    those within ``eps`` of its boundary projected onto it, then those within ``eps`` of an
    earlier one dropped; and how many moved or went.

    ``onto`` after cleaning, which moves the outline by up to its tolerance (merged vertices,
    dropped spikes): a ``pfix`` of the raw vertices then holds points a hair inside or
    outside the cleaned boundary, which as given became nodes that close to it (a triangle of
    zero area, a lost segment).  A plain function's corners are its fixed points (and finding
    the others traces it): only a domain with explicit corners is snapped to them.
    """
    if len(fixed) == 0:
        return fixed, 0
    from scipy.spatial import cKDTree

    from .geometry.implicit import Implicit

    out = fixed.copy()
    corners = np.empty((0, 2)) if isinstance(domain, Implicit) else domain.corners()
    snap = np.zeros(len(out), dtype=bool)
    if len(corners):
        dist, at = cKDTree(corners).query(out)
        snap = dist <= eps
        out[snap] = corners[at[snap]]
    if onto:
        d = domain.sdf(out)
        near = (np.abs(d) <= eps) & (d != 0) & ~snap
        if near.any():
            out[near] = domain.project(out[near])
    moved = int(np.count_nonzero(np.hypot(*(out - fixed).T) > 0))
    kept = dedupe_points(out, eps)
    changed = moved + len(out) - len(kept)
    if changed:
        logger.info("%d fixed point(s) within %.3g of a corner, the boundary or another settled",
                    changed, eps)
    return kept, changed


def _clean(
    domain: Domain, h: SizeFunction, min_feature: float | None = None
) -> tuple[Domain, dict[str, int], _Estimate, float]:
    """The domain cleaned at the scale of h: vertices closer than ``CLEAN * h_min`` merged,
    zero-length edges and spikes dropped, parts beyond pinches narrower than ``min_feature``
    dropped (``Domain.cleaned``), what changed, the node estimate of h on the domain
    when it was made (:class:`_Estimate`: a later stage may reuse it), and the tolerance
    (``CLEAN * h_min``, 0 when nothing is cleaned).

    GIS outlines carry vertices 1e-7 apart; meshed as given they make a duplicate node and a
    triangle of zero area.  A detailed outline also comes back within a fraction of h of itself
    (a fractal coastline: lobes on necks 1e-7 to 1e-4 wide for h = 0.02): the mesh cannot
    follow both sides of such a pinch (boundary nodes closer than the tolerances, segments that
    Delaunay cannot keep) and, as given, lost whole lobes.  Such a pinch narrower than
    ``min_feature`` (default ``CLEAN * h_min``) cuts the outline, and the smaller part beyond
    it is dropped: by default only when it is smaller than the elements (area at most
    ``PINCH_AREA * h_min**2``, else :class:`GeometryError` naming the place), whatever its size
    when ``min_feature`` is given.  Changes are logged and kept in ``mesh.stats.cleaning``;
    dropped parts are also a warning naming each place.

    Cleaning moves the boundary, by design and only within its tolerance of the outline's
    *width*: a merged vertex moves by less than ``CLEAN * h_min``; a dropped spike (a part of
    the outline narrower than that, one hundredth of the smallest element) disappears whatever
    its length, since no triangle could fill it, as does a part beyond a pinch.  The mesh is a
    mesh of the cleaned domain, and its output checks (:mod:`injmesh.validate`) hold against
    that domain; compare a mesh with the raw outline only where ``mesh.stats.cleaning`` is
    empty.
    """
    if min_feature is not None and not (
        isinstance(min_feature, (int, float, np.number)) and not isinstance(min_feature, (bool, np.bool_))
        and math.isfinite(float(min_feature)) and min_feature >= 0
    ):
        raise ValueError(f"min_feature must be a finite length >= 0, got {min_feature!r}")
    if type(domain).cleaned is Domain.cleaned:
        # The base class cleans nothing (a plain signed distance): no tolerance is needed, so
        # h_min's estimate, a quadrature of h over the domain, is left out.
        return domain, {}, _Estimate(), 0.0
    known = _Estimate()
    # A constant h (capped at the diameter, as the stages cap it) is its own minimum.
    if h.constant is not None:
        h_min = min(h.constant, domain.diameter)
    else:
        known = _Estimate(domain, h, estimate_nodes(domain, h.restricted(domain)))
        assert known.value is not None
        h_min = known.value[0]
    if min_feature is None:
        width, max_area = CLEAN * h_min, PINCH_AREA * h_min * h_min
    else:
        width, max_area = float(min_feature), None
    cleaned, report = domain.cleaned(CLEAN * h_min, min_feature=width, max_area=max_area)
    changes = {k: int(v) for k, v in report.items() if v}
    if changes:
        logger.info("geometry cleaned at %.3g: %s", CLEAN * h_min,
                    ", ".join(f"{v} {k.replace('_', ' ')}" for k, v in changes.items()))
    parts = getattr(cleaned, "dropped_parts", ())
    if parts:
        shown = "; ".join(f"({x:.6g}, {y:.6g}): gap {g:.2g}, area {a:.2g}"
                          for x, y, g, a in parts[:MAX_LISTED])
        more = f"; ... ({len(parts)} in all)" if len(parts) > MAX_LISTED else ""
        message = (f"{len(parts)} part(s) of the outline beyond pinches narrower than min_feature = "
                   f"{width:.3g} were dropped (lobes removed, pockets filled) at {shown}{more}")
        logger.info(message)
        warnings.warn(message, UserWarning, stacklevel=3)
    return cleaned, changes, known, CLEAN * h_min


@dataclass(frozen=True)
class _Estimate:
    """:func:`~injmesh.boundary.estimate_nodes` of ``size.restricted(domain)``, kept for the
    stages that ask it again: ``_clean`` needs h_min on the domain as given, regions need it on
    the cleaned domain, Step 1 needs it for the size it follows (one quadrature of h each, a
    few milliseconds on the paper's cases).  When cleaning returns the domain itself (a
    circle), or the exact boundary with which a CSG domain answers every one of the
    estimate's questions (:func:`_answers_as`: a union, difference or intersection of
    circles, rectangles and polygons with nothing to clean, no piece shorter than the
    cleaning tolerance and, for segments only, nothing :meth:`Polygon.cleaned
    <injmesh.geometry.Polygon.cleaned>` would change, which :meth:`BRep.cleaned
    <injmesh.geometry.BRep.cleaned>` returns as it is),
    and the size followed is h itself, these are one question, asked once.  The size is
    compared by identity, so the estimate is reused only for the very h it was computed for.
    """

    domain: Domain | None = None
    size: SizeFunction | None = None
    value: tuple[float, float] | None = None

    def of(self, domain: Domain, size: SizeFunction) -> tuple[float, float] | None:
        """The estimate of ``size.restricted(domain)``, if this is it."""
        if self.value is None or self.domain is None or size is not self.size:
            return None
        return self.value if domain is self.domain or _answers_as(self.domain, domain) else None

    def followed(
        self, domain: Domain, size: SizeFunction, target: SizeFunction
    ) -> tuple[float, float] | None:
        """The estimate of the size the stages follow, when :func:`_target_size` returned
        ``size`` itself for ``target`` (its test, repeated): the stages then call ``size``
        capped at the domain's diameter, which at the estimate's samples (all inside the
        domain, where the restriction asks ``size`` itself) gives the values of
        ``size.restricted(domain)``, clamped to that same diameter, bit for bit.
        """
        if target.domain is not None and target.function is size.function:
            return self.of(domain, size)
        return None


#: Places listed in a cleaning warning.
MAX_LISTED = 5


def _rate(gradation: float | None) -> float:
    """Slope at which sizes lowered next to close corners grow back (:func:`corner_size`)."""
    return 0.2 if gradation is None else float(gradation)


def _target_size(
    domain: Domain, h: SizeFunction, feature_layers: float | None, gradation: float | None
) -> tuple[SizeFunction, Callable[[FloatArray], FloatArray]]:
    """The size the mesh is made for, and the callable the stages evaluate.

    :func:`~injmesh.sizing.effective_size` lowers h where the domain is thin and limits its
    gradation on a background grid.  When it changes nothing it returns h restricted to the
    domain (evaluated only inside, one sdf call per evaluation); the stages then call h itself,
    capped at the diameter, and ask it only inside (see injection and boundary), which saves
    that sdf call at every smoothing step.  When it returns the grid's sizes lowered by h
    restricted to the domain (a grid too coarse for h), the stages likewise call h itself
    (:func:`~injmesh.sizing.features.unrestricted`).
    """
    if feature_layers is None and gradation is None:
        target = h.restricted(domain)
    else:
        try:
            target = effective_size(h, domain, layers=feature_layers, rate=gradation)
        except GeometryError:
            # The background grid saw no boundary: let the domain's own check say why (empty,
            # or spilling out of its bbox), else report what the grid found.
            domain.boundary_loops(grid_spacing(domain.bbox, np.inf))
            raise
    if target.domain is not None and target.function is h.function:
        return target, _capped(h, domain.diameter)
    # A grid too coarse for h keeps h's detail as min(grid, h restricted): the stages call h
    # itself there too, for the same reason.
    return target, unrestricted(target, h)


def _answers_as(domain: Domain, exact: Domain) -> bool:
    """Whether :func:`~injmesh.boundary.estimate_nodes` on ``domain`` computes exactly what it
    computes on ``exact``: ``domain`` is a union, difference or intersection (its own ``sdf``)
    whose exact boundary is ``exact``, a plain B-rep (not a circle or rectangle, which the
    background grid evaluates by formula), with the same bounding box.  Such a combination
    computes its d as ``exact.sdf``, and the estimate asks nothing else of the domain than its
    box, d and exact boundary (its inside test samples d on a grid from that boundary)."""
    return (isinstance(domain, (Union, Difference, Intersection)) and type(domain).sdf is Difference.sdf
            and type(exact) is BRep and domain.exact_brep() is exact  # type: ignore[attr-defined]
            and tuple(map(float, domain.bbox)) == tuple(map(float, exact.bbox)))


# --- target_nodes -----------------------------------------------------------------------------

#: ``target_nodes``: a count of Steps 1 and 2 this close (fraction, or one node) ends the search.
PROBE_TOLERANCE = 0.005
#: The full mesh is accepted this close; farther, it is made again (up to ``MAX_MESHES``).
MESH_TOLERANCE = 0.01
#: Farther than this from ``target_nodes``: ConvergenceWarning.
NODES_TOLERANCE = 0.03
#: Node counts of Steps 1 and 2 tried per search, and the largest change of scale per try.
MAX_PROBES = 8
MAX_STEP = 4.0
#: Full meshes made at most (the closest is returned).
MAX_MESHES = 4
#: The search stops when the scales giving too many and too few nodes are this close (relative).
BRACKET = 0.002


class _Scaled:
    """``scale * h(p)``: the user's h, scaled for ``target_nodes``."""

    def __init__(self, h: SizeFunction, scale: float) -> None:
        self.h, self.scale = h, scale

    def __call__(self, p: FloatArray) -> FloatArray:
        return self.scale * self.h(p)


def _check_target_nodes(target_nodes: object, max_nodes: int) -> int:
    if isinstance(target_nodes, (bool, np.bool_)) or not (
        isinstance(target_nodes, (int, np.integer))
        or isinstance(target_nodes, float) and target_nodes.is_integer()
    ):
        raise ValueError(f"target_nodes must be a whole number, got {target_nodes!r}")
    wanted = int(target_nodes)  # type: ignore[call-overload]
    if wanted < 3:
        raise ValueError(f"target_nodes must be at least 3, got {wanted}")
    if wanted > max_nodes:
        raise NodeBudgetError(f"target_nodes={wanted} is above max_nodes={max_nodes}")
    return wanted


def _meet_node_count(
    domain: Domain,
    h: SizeFunction,
    wanted: int,
    at_scale: Callable[[float, bool], Mesh | int],
    max_nodes: int,
) -> Mesh:
    """The mesh of ``scale * h`` with about ``wanted`` nodes (``generate(target_nodes=...)``).

    1. Estimate: the interior count of an equilateral packing, ``(2/sqrt(3)) int h^-2 dA``
       (:func:`~injmesh.boundary.estimate_nodes`), scales as ``scale^-2``; the first scale
       meets ``wanted`` with it.  The boundary adds about ``(1/2) int ds/h`` nodes on top
       (Euler's formula), scaling as ``scale^-1``.
    2. Search on the node count of Steps 1 and 2 (boundary and injection, without smoothing,
       a few per cent of a mesh's time): Newton steps in ``log scale`` whose first slope
       ``-(1 + interior share)`` comes from that two-term model and later slopes from the last
       two counts (a secant), each step at most ``MAX_STEP``, until within ``PROBE_TOLERANCE``;
       once counts above and below the goal are known, a safeguarded secant inside that
       bracket, stopped when it is ``BRACKET`` wide (the count is a step function of the scale).
       The feature size and gradation corrections are recomputed at every scale, so thin parts
       that do not coarsen with h are counted as they are.
    3. The full mesh.  Smoothing's local repair adds or removes a few nodes (0 to +10 % at a
       few hundred nodes, varying with the scale; < 1 % from a few thousand); if the mesh
       misses by more than ``MESH_TOLERANCE``, the search of step 2 is repeated for
       ``wanted`` divided by the ratio smoothing changed the count by, and the mesh made
       again; further meshes (``MAX_MESHES`` in all) follow the same Newton / bracketed secant
       steps on the meshes' own counts.  The closest is returned.

    Deterministic: every count and scale follows from the inputs alone.
    """
    start = time.perf_counter()
    interior = estimate_nodes(domain, h)[1]  # nodes of the interior at scale 1
    counts: dict[float, int] = {}

    def count(scale: float) -> int:
        if scale not in counts:
            try:
                counts[scale] = int(at_scale(scale, False))  # type: ignore[arg-type]
            except NodeBudgetError:
                counts[scale] = max_nodes + 1
            logger.debug("target_nodes=%d: h scaled by %.6g gives %d nodes in Steps 1-2",
                         wanted, scale, counts[scale])
        return counts[scale]

    def model_slope(scale: float, n: int) -> float:
        # d log N / d log scale of N = A/scale^2 + B/scale, with A/scale^2 the interior estimate.
        return -(1.0 + min(max(interior / (scale * scale * n), 0.0), 1.0))

    def search(goal: float, scale: float) -> float:
        tried: list[tuple[float, int]] = []
        for _ in range(MAX_PROBES):
            n = count(scale)
            tried.append((scale, n))
            if abs(n - goal) <= max(1.0, PROBE_TOLERANCE * goal):
                break
            following = _next_scale(tried, goal, model_slope(scale, n))
            if following is None:
                break
            scale = following
        return min(tried, key=lambda t: abs(t[1] - goal))[0]

    def mesh_at(scale: float) -> tuple[Mesh, list[warnings.WarningMessage]]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            mesh = at_scale(scale, True)
        assert isinstance(mesh, Mesh)
        logger.debug("target_nodes=%d: h scaled by %.6g gives a mesh of %d nodes (%d before "
                     "smoothing)", wanted, scale, mesh.n_points, mesh.stats.initial_nodes)
        return mesh, caught

    def miss(mesh: Mesh) -> float:
        return abs(mesh.n_points / wanted - 1.0)

    scale = search(wanted, math.sqrt(interior / wanted))
    meshes = {scale: mesh_at(scale)}
    # Smoothing's repair adds a few nodes, a number that varies with the scale: if the mesh
    # misses, the same search on the meshes' own counts, its first step retargeted by the ratio
    # smoothing changed the count by (the slope of Steps 1-2's counts).
    while len(meshes) < MAX_MESHES:
        scale, (mesh, _) = min(meshes.items(), key=lambda t: abs(t[1][0].n_points - wanted))
        if miss(mesh) <= MESH_TOLERANCE:
            break
        finals = [(s, m.n_points) for s, (m, _) in meshes.items()]
        ratio = mesh.n_points / mesh.stats.initial_nodes
        following = _next_scale(finals, wanted, _local_slope(counts, scale, model_slope(
            scale, mesh.stats.initial_nodes)))
        if following is None or following in meshes:
            break
        if len(meshes) == 1:
            following = search(wanted / ratio, following)
            if following in meshes:
                break
        meshes[following] = mesh_at(following)
    scale, (mesh, caught) = min(meshes.items(), key=lambda t: abs(t[1][0].n_points - wanted))
    searching = time.perf_counter() - start - sum(mesh.stats.seconds.values())
    logger.info("target_nodes=%d: h scaled by %.6g, %d nodes (%+.2f %%); %d counts of Steps 1-2",
                wanted, scale, mesh.n_points, 100.0 * (mesh.n_points / wanted - 1.0), len(counts))
    for w in caught:
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    off = mesh.n_points / wanted - 1.0
    if abs(off) > NODES_TOLERANCE:
        if off > 0 and min(counts.values()) > wanted:
            why = ("about the fewest this domain allows: thin parts keep h <= feature size / "
                   "feature_layers (feature_layers=None lifts that) and every boundary loop "
                   "needs a few segments")
        else:
            why = (f"the closest of {len(meshes)} meshes: with this h the count jumps by more "
                   "than that between nearby scales")
        warnings.warn(
            f"target_nodes={wanted}: the mesh has {mesh.n_points} nodes ({100 * off:+.1f} %), "
            f"{why}", ConvergenceWarning, stacklevel=3,
        )
    seconds = {**mesh.stats.seconds, "target_nodes": max(searching, 0.0)}
    return replace(mesh, stats=replace(mesh.stats, seconds=seconds))


def _local_slope(counts: dict[float, int], scale: float, default: float) -> float:
    """``d log N / d log scale`` near ``scale`` from the two counts nearest it, else ``default``."""
    near = sorted(counts, key=lambda s: abs(math.log(s / scale)))[:3]
    for other in near:
        if other != scale and scale in counts and counts[other] != counts[scale]:
            slope = math.log(counts[other] / counts[scale]) / math.log(other / scale)
            return min(max(slope, -3.0), -0.5)
    return default


def _next_scale(tried: list[tuple[float, int]], goal: float, slope: float) -> float | None:
    """The next scale of h to try for ``goal`` nodes, given the (scale, count) pairs so far.

    Before the goal is bracketed: a Newton step in log-log from the last pair, with the slope
    of the last two pairs (else ``slope``), at most ``MAX_STEP``.  Once scales giving too many
    and too few nodes are known: a secant between the closest two, kept inside the bracket.
    None when there is nothing better to try: the bracket is narrower than ``BRACKET`` (the
    count is a step function of the scale), or counts no longer fall as the scale grows (the
    fewest nodes the domain allows).
    """
    known = dict(tried)
    above = [s for s, n in tried if n > goal]
    below = [s for s, n in tried if n < goal]
    if above and below:
        fine, coarse = max(above), min(below)
        if fine >= coarse or coarse / fine < 1.0 + BRACKET:
            return None  # not monotone here, or as close as the steps of the count allow
        n_fine, n_coarse = known[fine], known[coarse]
        t = math.log(n_fine / goal) / math.log(n_fine / n_coarse)
        return fine * (coarse / fine) ** min(max(t, 0.1), 0.9)
    scale, n = tried[-1]
    if len(tried) > 1:
        s0, n0 = tried[-2]
        if n != n0 and scale != s0:
            slope = min(max(math.log(n / n0) / math.log(scale / s0), -3.0), -0.5)
        elif n > goal and scale > s0:
            return None  # coarser h, same count: the fewest nodes reachable
    step = math.log(goal / n) / slope
    return scale * math.exp(min(max(step, -math.log(MAX_STEP)), math.log(MAX_STEP)))


# --- regions and interior curves (issue 9) ----------------------------------------------------


def _injection_with_curves(
    domain: Domain,
    h: Callable[[FloatArray], FloatArray],
    fixed: FloatArray,
    max_iterations: int | None,
    max_nodes: int,
    smoothing: Smoothing,
    callback: Callback | None,
    cons: Constraints,
    estimate: tuple[float, float] | None = None,
) -> Mesh:
    """Algorithm 1 with interior curves: Step 1 meshes them too, Step 2 injects from both of
    their sides, Step 3 slides their nodes along them and recovers their segments as edges
    (``estimate``: as in :func:`_place_nodes`).

    Nodes are ordered boundary, curve nodes (junctions on the boundary are boundary nodes),
    user fixed interior points, injected nodes; the first ``n_fixed`` never move except by
    sliding.
    """
    seconds: dict[str, float] = {}
    hc = _capped(h, domain.diameter)
    diam = domain.diameter
    t = time.perf_counter()
    # Step 1 on the boundary, with a node wherever a curve meets it, then on the curves.
    # Where a curve leaves the boundary at a sharp angle, both walls get the same nodes near
    # the tip, as a sharp corner of the domain does.
    tip_walls, pieces = sharp_junctions(domain, hc, cons.pieces, cons.boundary_junctions)
    fixed_b = np.concatenate([fixed.reshape(-1, 2), cons.boundary_junctions, tip_walls])
    bnd = mesh_boundary(domain, hc, fixed_b, max_nodes=max_nodes, callback=callback, estimate=estimate)
    cm = mesh_curves(pieces, hc, diam)
    nb = len(bnd.points)
    ids = np.empty(len(cm.points), dtype=np.intp)
    on_b = np.zeros(len(cm.points), dtype=bool)
    if len(cm.points):
        from scipy.spatial import cKDTree

        dist, near = cKDTree(bnd.points).query(cm.points)
        on_b = cm.fixed & (dist <= 10 * tol.ON_BOUNDARY * diam)
        ids[on_b] = near[on_b]
    ids[~on_b] = nb + np.arange(int((~on_b).sum()))
    curve_pts = cm.points[~on_b]
    seconds["boundary"] = time.perf_counter() - t
    t = time.perf_counter()
    # A point within the on-boundary tolerance of the boundary is a boundary node (Step 1's
    # corner), not an interior one as well.
    interior_fixed = fixed[domain.sdf(fixed) < -tol.ON_BOUNDARY * domain.diameter] if len(fixed) else fixed
    seeds = np.concatenate([bnd.points, curve_pts, interior_fixed])
    # Step 2: the curves are fronts facing both ways.
    # Curves that meet the boundary advance with its front; the others, where h is the same on
    # every loop, first (see ``injection.inject_nodes``).
    inside, attached = _curve_fronts(domain, cm, ids, seeds)
    injected = inject_nodes(domain, hc, bnd, seeds, max_nodes=max_nodes, callback=callback,
                            curves=inside, attached=attached)
    seconds["injection"] = time.perf_counter() - t
    points = np.concatenate([seeds, injected])
    t = time.perf_counter()

    # Step 3: boundary and curve nodes other than fixed ones slide between their neighbours.
    rows = [_sliding(bnd)]
    node_group = np.zeros(len(seeds), dtype=np.intp)
    for chain, closed in cm.chains:
        g = ids[chain]
        k = np.arange(len(g)) if closed else np.arange(1, len(g) - 1)
        k = k[~cm.fixed[chain[k]]]
        rows.append(np.stack([g[k], g[(k - 1) % len(g)], g[(k + 1) % len(g)]], axis=1))
    node_group[ids[~on_b]] = cm.node_piece[~on_b] + 1
    # Pieces of one region share its projection: one call per region (or curve) in a step,
    # none of the grouping when there is only one (a single inclusion).
    projectors: list[Callable[[FloatArray], FloatArray]] = []
    which = np.empty(len(cons.pieces), dtype=np.intp)
    for j, piece in enumerate(cons.pieces):
        same = [i for i, f in enumerate(projectors) if f == piece.project]
        if not same:
            projectors.append(piece.project)
        which[j] = same[0] if same else len(projectors) - 1

    # The grouping of the last group list: a relaxation asks for the same nodes at every step.
    last: list[Any] = []

    def project(q: FloatArray, group: NDArray[np.intp]) -> FloatArray:
        if len(projectors) == 1:
            return projectors[0](q)
        if not (last and len(last[0]) == len(group) and np.array_equal(last[0], group)):
            pid = which[group - 1]
            last[:] = [group.copy(), [(i, np.flatnonzero(pid == i)) for i in np.unique(pid).tolist()]]
        out = np.empty_like(q)
        for i, sel in last[1]:
            out[sel] = projectors[i](q[sel])
        return out

    # The projectors as compiled boundaries, when each is a domain's own projection with one:
    # then the relaxation projects curve nodes in its compiled steps.
    kernels: list[KernelBoundary] = []
    for f in projectors:
        owner = getattr(f, "__self__", None)
        kb = owner.kernel_boundary() if isinstance(owner, Domain) and f == owner.project else None
        if kb is None:
            kernels = []
            break
        kernels.append(kb)
    points, n_fixed, remap = _merge_touching(bnd, points, len(seeds), diam)
    group = np.zeros(n_fixed, dtype=np.intp)
    group[remap[:len(seeds)]] = node_group
    itf = Interfaces(remap[ids[cm.edges]], cm.edge_piece + 1, group, project, tuple(kernels), which)
    result = smooth(
        domain, hc, points, n_fixed=n_fixed, sliding=remap[np.concatenate(rows)], walls=remap[bnd.edges],
        smoothing=smoothing, max_iterations=max_iterations, callback=callback, interfaces=itf,
    )
    seconds["smoothing"] = time.perf_counter() - t
    result, edges, tags, defects = _checked_boundary(domain, bnd, result)
    lost = _lost_interfaces(result.triangles, result.interfaces)
    if lost.any():
        from .validate import _defect

        seg = result.interfaces[lost]
        seg = np.where(seg < 0, seg.max(axis=1, keepdims=True), seg)
        defects.append(_defect("lost interior curve segment",
                               0.5 * (result.points[seg[:, 0]] + result.points[seg[:, 1]])))
    iseg = result.interfaces[~lost]
    igroup = result.interface_group[~lost]
    tri_tags, left_tri, right_tri = _region_tags(result.points, result.triangles, iseg, cons)
    curve_tags, curve_names = _curve_tags(iseg, igroup, tri_tags, left_tri, right_tri, cons)

    stats = _stats(result, nb, len(points), seconds, defects)
    return Mesh(
        points=result.points,
        triangles=result.triangles,
        boundary_edges=edges,
        boundary_tags=tags,
        size=h,
        stats=stats,
        triangle_tags=tri_tags,
        region_names=cons.region_names,
        curve_edges=iseg,
        curve_tags=curve_tags,
        curve_names=curve_names,
    )


def _curve_fronts(domain: Domain, cm: CurveMesh, ids: NDArray[np.intp],
                  seeds: FloatArray) -> tuple[BoundaryMesh, BoundaryMesh]:
    """The interior curves as fronts of Step 2, every curve facing both ways: those that do
    not meet the domain's boundary (``inject_nodes``' ``curves``), and those that do
    (``attached``: they advance with the boundary's own front: in the wedge between a wall and
    a curve leaving it, the two fronts meet as a corner's do).

    A closed curve is two loops, one each way round.  An open curve is one flat loop, there and
    back; at an end inside the domain the loop goes round the end point (two copies a hair
    apart across the curve), so Step 2 sees a reflex vertex of 360 degrees and fans nodes
    round the tip, as it does at a re-entrant corner.
    """
    diam = domain.diameter
    loops: tuple[list[FloatArray], list[FloatArray]] = ([], [])
    for chain, closed in cm.chains:
        p = seeds[ids[chain]]
        if closed:
            loops[0].extend([p, p[::-1]])
            continue
        tips = []
        meets = False
        for end, before in ((p[-1], p[-2]), (p[0], p[1])):
            t = end - before
            t = t / max(float(np.hypot(*t)), 1e-300)
            eps = 1e-6 * float(np.hypot(*(end - before)))
            nrm = np.array([-t[1], t[0]])
            inside = abs(float(domain.sdf(end[None, :])[0])) > 10 * tol.ON_BOUNDARY * diam
            meets = meets or not inside
            tips.append(np.stack([end + eps * nrm, end - eps * nrm]) if inside else end[None, :])
        # Out along the curve (its left side), round the far end, back (its right side),
        # round the near end.
        loops[meets].append(np.concatenate([tips[1][-1:] if len(tips[1]) == 2 else p[:1], p[1:-1], tips[0],
                                            p[-2:0:-1], tips[1][:1] if len(tips[1]) == 2 else p[:0]]))
    return _as_loops(loops[0]), _as_loops(loops[1])


def _as_loops(seqs: list[FloatArray]) -> BoundaryMesh:
    """Closed loops of the point sequences ``seqs``, numbered from 0."""
    if not seqs:
        return BoundaryMesh(np.empty((0, 2)), np.empty((0, 2), dtype=np.intp), np.empty(0, dtype=np.intp),
                            np.zeros(0, dtype=bool))
    points = np.concatenate(seqs)
    node_loop = np.repeat(np.arange(len(seqs)), [len(q) for q in seqs])
    start = np.flatnonzero(np.r_[True, node_loop[1:] != node_loop[:-1]])
    end = np.r_[start[1:], len(node_loop)] - 1
    idx = np.arange(len(points))
    nxt = np.where(idx == np.repeat(end, end - start + 1), np.repeat(start, end - start + 1), idx + 1)
    return BoundaryMesh(points, np.stack([idx, nxt], axis=1), node_loop, np.zeros(len(points), dtype=bool))


def _lost_interfaces(tri: NDArray[np.intp], seg: NDArray[np.intp]) -> NDArray[np.bool_]:
    """Interior curve segments that are not mesh edges (or lost a node)."""
    if len(seg) == 0:
        return np.zeros(0, dtype=bool)
    from .kernels.mesh import edges_present

    gone = np.any(seg < 0, axis=1)
    n = int(max(tri.max(initial=0), seg.max(initial=0))) + 1
    found = np.zeros(len(seg), dtype=bool)
    found[~gone] = edges_present(np.ascontiguousarray(tri, dtype=np.int64),
                                 np.ascontiguousarray(seg[~gone], dtype=np.int64), n)
    return ~found | gone


def _region_tags(
    points: FloatArray, tri: NDArray[np.intp], seg: NDArray[np.intp], cons: Constraints
) -> tuple[NDArray[np.intp], NDArray[np.int64], NDArray[np.int64]]:
    """Region of each triangle, and the triangles on the left and right of each curve segment
    (-1 where there is none).

    The triangles are grouped by flood fill across every edge that is not an interior curve
    segment (``kernels.mesh.curve_groups``); each group takes the region that holds most of its
    area by the triangles' centroids, so a triangle whose centroid falls a hair outside a curved
    region (between a chord and its arc) still takes its group's region.  A group of
    ``VOTE_ALL`` triangles or more votes with every ``VOTE_EVERY``-th of them (by number): it
    lies in one region up to such slivers, and asking every centroid's region took a fifth of
    the tagging on a 1e5-node mesh.
    """
    from .kernels.mesh import curve_groups, neighbours, signed_areas

    m = len(tri)
    if m == 0 or not cons.regions:
        none = np.full(len(seg), -1, dtype=np.int64)
        return np.zeros(m, dtype=np.intp), none, none.copy()
    t64 = np.ascontiguousarray(tri, dtype=np.int64)
    n = len(points)
    nbr = neighbours(t64, n)
    segments = np.ascontiguousarray(seg, dtype=np.int64).reshape(-1, 2)
    label, groups, left, right = curve_groups(t64, nbr, segments, n)
    size = np.bincount(label, minlength=groups)
    ask = (size[label] < VOTE_ALL) | (np.arange(m) % VOTE_EVERY == 0)
    # A large group none of whose triangles is a multiple of VOTE_EVERY asks them all.
    unasked = np.bincount(label[ask], minlength=groups) == 0
    ask |= unasked[label]
    rows = np.flatnonzero(ask)
    sub = tri[rows]
    centroid_tag = cons.region_of((points[sub[:, 0]] + points[sub[:, 1]] + points[sub[:, 2]]) / 3.0)
    area = np.abs(signed_areas(np.ascontiguousarray(points, dtype=np.float64),
                               np.ascontiguousarray(sub, dtype=np.int64)))
    r = len(cons.regions) + 1
    votes = np.bincount(label[rows] * r + centroid_tag, weights=area, minlength=groups * r)
    winner = np.argmax(votes.reshape(-1, r), axis=1)
    return np.asarray(winner[label], dtype=np.intp), left, right


#: :func:`_region_tags` asks every centroid's region in groups of fewer triangles, and every
#: VOTE_EVERY-th in the others.
VOTE_ALL = 512
VOTE_EVERY = 8


def _curve_tags(
    seg: NDArray[np.intp],
    group: NDArray[np.intp],
    tri_tags: NDArray[np.intp],
    left_tri: NDArray[np.int64],
    right_tri: NDArray[np.int64],
    cons: Constraints,
) -> tuple[NDArray[np.intp], tuple[str, ...]]:
    """Tag of each interior curve edge: its user curve, or the interface between the regions on
    its two sides (``"a/b"``, in tag order); ``left_tri`` / ``right_tri``: the triangles holding
    a -> b and b -> a (:func:`_region_tags`)."""
    names = list(cons.curve_names)
    if len(seg) == 0:
        return np.zeros(0, dtype=np.intp), tuple(names)
    owner = np.array([p.owner for p in cons.pieces], dtype=np.intp)[group - 1]
    tags = np.where(owner < 0, -1 - owner, 0)
    left = np.where(left_tri >= 0, tri_tags[np.maximum(left_tri, 0)], 0)
    right = np.where(right_tri >= 0, tri_tags[np.maximum(right_tri, 0)], 0)
    lo, hi = np.minimum(left, right), np.maximum(left, right)
    region = owner > 0
    pairs = sorted(set(zip(lo[region].tolist(), hi[region].tolist(), strict=True)))
    base = len(names)
    for a, b in pairs:
        names.append(f"{cons.region_names[a]}/{cons.region_names[b]}")
    index = {pair: base + k for k, pair in enumerate(pairs)}
    for i in np.flatnonzero(region).tolist():
        tags[i] = index[(int(lo[i]), int(hi[i]))]
    return np.asarray(tags, dtype=np.intp), tuple(names)


def _region_features(domain: Domain, h: SizeFunction, cons: Constraints, layers: float) -> SizeFunction:
    """h lowered to ``feature_size / layers`` of each region and of the rest of the domain.

    An inclusion a few h across, or a gap between an inclusion and the boundary, is a thin part
    of the mesh just as a strait is: measured on the paper's cases, an inclusion one h from the
    boundary gave q_min 0.61 without this.  The domain's own feature size and the gradation
    limit are applied afterwards, as without regions.

    When every part (each region, and the domain minus the regions) has an exact boundary, the
    thin parts are measured on the boundary polylines alone (:func:`_gap_cones`): no feature
    grid per part (each cost ~30-60 ms on the paper's cases, most of the cost of regions
    there).  Otherwise each part's feature size comes from its own feature grid
    (:func:`~injmesh.sizing.features.thin_feature_size`).
    """
    from .sizing.background import exact_boundary
    from .sizing.features import thin_feature_size

    # Regions strictly inside the domain and apart from each other (inclusions): the rest's
    # boundary is the domain's loops and the regions' reversed, without the set difference
    # (its B-rep cost ~1 ms of the paper's cases' ~10).
    breps = [exact_boundary(r) for r in cons.regions]
    outer = exact_boundary(domain)
    if outer is not None and all(b is not None for b in breps) and _apart(domain, cons.regions, breps):
        return _gap_cones(domain, h, (*breps, _Holed(outer, breps)), float(layers))  # type: ignore[arg-type]
    rest: Domain = domain
    for r in cons.regions:
        rest = rest - r
    # Regions that cover the whole domain (a partition into materials) leave no rest: an empty
    # set operation, which as a domain of its own would be refused.
    parts = (*cons.regions, *(() if getattr(rest, "is_empty", False) is True else (rest,)))
    exact = [*breps, *(exact_boundary(part) for part in parts[len(breps):])]
    if all(b is not None for b in exact):
        return _gap_cones(domain, h, tuple(exact), float(layers))  # type: ignore[arg-type]
    # A part on which no two walls face each other within a few h (a circle several h across)
    # needs no feature grid: it would change nothing, and costs ~50 ms per part.
    sizes = [thin_feature_size(part, h, float(layers)) for part in parts]
    if all(fs is None for fs in sizes):
        return h
    lowered = _LowerInParts(h, list(cons.regions), sizes, float(layers))
    # Where no part is thinner than layers * h (probed on each feature grid inside the domain),
    # h is kept as it is: evaluated at every smoothing step, it should cost no more than h.
    for fs in sizes:
        if fs is None:
            continue
        gx, gy = np.meshgrid(fs.x, fs.y)
        q = np.stack([gx.ravel(), gy.ravel()], axis=1)
        q = q[domain.sdf(q) < 0]
        if len(q) and np.any(lowered(q) < h(q) * (1 - 1e-12)):
            return as_size_function(lowered)
    return h


#: Points sampled along each chord between facing walls (:func:`_gap_cones`); between two of
#: them the cones' minimum is at most ``rate * chord / (2 (GAP_SAMPLES - 1))`` above the gap.
GAP_SAMPLES = 9


def _gap_cones(domain: Domain, h: SizeFunction, parts: tuple[Any, ...], layers: float) -> SizeFunction:
    """h lowered where a region's wall and another wall of the same part face each other closer
    than about ``layers * h``.

    Each loop of a part's exact boundary is sampled every ``s``, the least h on it over
    ``GAP_COARSE``, or finer for a loop only a few h across (:func:`_gap_loops`).  Where a chord
    found is narrower than ``TIGHT`` spacings (every chord that lowers h, and towards a wedge's
    tip or a near-tangency), the part is searched again near it at the spacing a feature grid
    would have, ``min(h_min / CELLS_PER_H, diameter / FEATURE_CELLS)``.  (Sampled at that
    spacing everywhere, the paper's cases spent 4-11 ms here; at h / 4 alone, 1000 fuzzed
    regions lost up to 0.48 of q_min at wedge tips, which the second search restores.)  For
    every vertex a, the compiled
    search (:func:`~injmesh.kernels.gaps.thinnest_chords`) judges the segments of the same part
    starting within ``r = PROBE_SLACK * layers * h + s`` (a's r or the partner's), one of the
    two on a region's wall, as :func:`~injmesh.sizing.thick_everywhere` judges them: the foot f
    of a on the segment, the direction e from a to f within ``corner_angle + FACING_SLACK`` of
    a's inward normal and of the segment's outward one.  Across such a chord the part is about
    ``w = |f - a| / cos(e, normal of a)`` thick (exact across a disc, every chord of which
    faces; its shortest facing chord is 1.5 R); each vertex keeps its thinnest chord.  The
    result is ``min(h, min_c (w_c / layers + (2 / layers) |p - c|))`` over points c sampled
    along the chords (``GAP_SAMPLES`` each): ``w / layers`` across the gap, growing back at the
    feature size's own slope (2) over ``layers`` (the gradation limit then smooths it),
    computed as the corner cap's cones are (:func:`~injmesh.kernels.outline.corner_cones`).
    The width is floored at two spacings (its loop's, and at least the fine one), as the
    feature grid's is, so a wedge's tip (a region touching the boundary at an angle) does not
    ask for vanishing elements.

    Chords with both ends on the domain's own boundary are never looked at: the domain's own
    thin parts are the feature size's (:func:`_target_size`), as without regions.  A chord
    whose h is more than ``PROBE_SLACK`` times its ends' somewhere along it may be missed.  h
    is returned unchanged when no cone is below it.
    """
    from .kernels.gaps import thinnest_chords
    from .sizing.background import CELLS_PER_H, probe_min
    from .sizing.features import FACING_SLACK, FEATURE_CELLS, PROBE_SLACK, loop_frames

    corner_angle = 30.0  # effective_size's default
    diam = float(domain.diameter)
    lo = min(h.constant, diam) if h.constant is not None else probe_min(h, domain)
    step = lo / GAP_COARSE
    cos = math.cos(math.radians(min(corner_angle + FACING_SLACK, 89.0)))
    eps = tol.ON_BOUNDARY * diam
    hr = h.restricted(domain)
    # Where a chord is only a few samples wide (towards a wedge's tip, a near-tangency), the
    # samples' spacing sets its width's floor: there the part is searched again at the
    # spacing a feature grid would have.
    fine = min(lo / CELLS_PER_H, diam / FEATURE_CELLS)

    def search(loops: list[FloatArray], steps: FloatArray, centres: FloatArray | None = None,
               reach: FloatArray | None = None) -> tuple[FloatArray, ...] | None:
        """The chords thinner than their search radius from the loops' vertices: starts, feet,
        widths and spacings; with ``centres``, only from and to the vertices within ``reach``
        of one of them (vertices away from them neither search nor are searched)."""
        v, _, prv, seg, seg_len, v_n, seg_n = loop_frames(loops)
        spacing = np.repeat(steps, [len(lp) for lp in loops])
        near = np.ones(len(v), dtype=bool) if centres is None or reach is None else \
            _near_chords(v, centres, reach)
        # Region walls: the vertices off the domain's boundary.
        wall = near & (np.abs(domain.sdf(v)) > eps)
        if not wall.any():
            return None
        radius = np.where(near, PROBE_SLACK * layers * hr(v) + 2.0 * spacing, 0.0)
        w, foot = thinnest_chords(v, prv, seg, seg_len, v_n, seg_n, wall, radius, cos)
        keep = near & (w < radius)
        return v[keep], foot[keep], w[keep], spacing[keep]

    found = []
    for brep in parts:
        loops, steps = _gap_loops(brep, step, hr)
        coarse = search(loops, steps) if loops else None
        if coarse is None:
            continue
        found.append(coarse)
        a, f, w, s = coarse
        tight = (w < TIGHT * s) & (s > fine * (1.0 + 1e-9))
        if tight.any():
            loops, steps = _gap_loops(brep, fine, None)
            reach = w[tight] + TIGHT * 2.0 * np.maximum(s[tight], fine)
            local = search(loops, steps, np.concatenate([a[tight], f[tight]]), np.tile(reach, 2))
            if local is not None:
                found.append(local)
    if not found:
        return h
    a, f, w, s = (np.concatenate(x) for x in zip(*found, strict=True))
    floor = 2.0 * np.maximum(s, fine)
    own = (np.abs(domain.sdf(a)) <= eps) & (np.abs(domain.sdf(f)) <= eps) if len(a) else \
        np.zeros(0, dtype=bool)
    a, f, w, floor = a[~own], f[~own], w[~own], floor[~own]
    if not len(a):
        return h
    t = np.linspace(0.0, 1.0, GAP_SAMPLES)
    c = (a[:, None, :] + t[None, :, None] * (f - a)[:, None, :]).reshape(-1, 2)
    apex = np.repeat(np.maximum(w, floor) / layers, GAP_SAMPLES)
    low = apex < hr(c) * (1.0 - 1e-9)
    if not low.any():
        return h
    c, apex = _thinned(c[low], apex[low], 2.0 / layers)
    return SizeFunction(_Cones(h, c, apex, 2.0 / layers))


#: :func:`_apart`: regions closer than this fraction of the diameter to the boundary or to
#: each other go through the set difference (they may touch).
APART = 2.0 / 256


def _apart(domain: Domain, regions: tuple[Domain, ...], breps: list[Any]) -> bool:
    """Whether every region lies inside the domain, and outside every other region, by more
    than ``APART`` of the diameter at samples of its boundary that far apart (a tangency
    between samples is closer than that at the nearest sample)."""
    margin = APART * domain.diameter
    loops = [np.concatenate([np.asarray(lp, dtype=np.float64).reshape(-1, 2)
                             for lp in b.boundary_loops(margin)]) for b in breps]
    boxes = [np.r_[lp.min(axis=0) - margin, lp.max(axis=0) + margin] for lp in loops]
    for i, lp in enumerate(loops):
        if not np.all(domain.sdf(lp) < -margin):
            return False
        for j, other in enumerate(regions):
            if j == i or boxes[i][0] > boxes[j][2] or boxes[j][0] > boxes[i][2] \
                    or boxes[i][1] > boxes[j][3] or boxes[j][1] > boxes[i][3]:
                continue
            if not np.all(other.sdf(lp) > margin):
                return False
    return True


class _Holed:
    """The boundary of a domain minus regions strictly inside it and apart from each other:
    its loops, then each region's reversed (domain on the left, as a B-rep's)."""

    def __init__(self, outer: Any, holes: list[Any]) -> None:
        self.outer, self.holes = outer, holes

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        out = [np.asarray(lp, dtype=np.float64) for lp in self.outer.boundary_loops(spacing)]
        for b in self.holes:
            out += [np.asarray(lp, dtype=np.float64)[::-1].copy() for lp in b.boundary_loops(spacing)]
        return out


#: :func:`_gap_cones`' first search samples the walls GAP_COARSE times per h; it only finds
#: where the walls come close: the chords it finds narrower than TIGHT samples (every chord
#: that lowers h, with two layers) are measured by a second search at the fine spacing.
GAP_COARSE = 2.0
#: :func:`_gap_cones` searches a part again at the fine spacing near its chords narrower than
#: TIGHT of their vertices' spacings (and within that many floors of them).
TIGHT = 4.0


def _near_chords(v: FloatArray, centres: FloatArray, reach: FloatArray) -> NDArray[np.bool_]:
    """Which of the points ``v`` lie within ``reach`` of one of ``centres`` (of one of the
    nearest eight, which on chords' ends along a few walls is one of all)."""
    from scipy.spatial import cKDTree

    k = min(8, len(centres))
    dist, idx = cKDTree(centres).query(v, k=k)
    dist, idx = dist.reshape(len(v), k), idx.reshape(len(v), k)
    return np.asarray(np.any(dist <= reach[idx], axis=1))


#: :func:`_gap_cones` samples a loop at least this many times across its extent, however
#: large h is: a disc a fraction of h across still gets its diameter's chords right.
LOOP_CELLS = 16


def _gap_loops(brep: Any, step: float, h: Callable[[FloatArray], FloatArray] | None
               ) -> tuple[list[FloatArray], FloatArray]:
    """The loops of ``brep`` sampled for :func:`_gap_cones`, and each one's spacing.

    A loop is sampled every ``min(h_loop / GAP_COARSE, extent / LOOP_CELLS)`` with ``h_loop``
    the least h at its samples ``step`` apart (``step``: the least h over the domain over
    ``GAP_COARSE``), rounded down to ``step`` times a power of two so that the loops of one spacing
    are sampled in one call; without h (the second, local search), every ``step`` or finer
    for a small loop.  The chord search costs the square of a loop's
    samples: an inclusion where h is four times the domain's least took 16x the pairs it
    needs at the least h's spacing (2.3 ms of the unit disc's 11 ms).
    """
    from .sizing.background import densify

    loops = [np.asarray(lp, dtype=np.float64) for lp in brep.boundary_loops(step)]
    k = np.zeros(len(loops), dtype=np.intp)
    for i, lp in enumerate(loops):
        if len(lp) < 2:
            continue
        extent = float(np.ptp(lp, axis=0).max())
        wanted = extent / LOOP_CELLS
        if h is not None:
            wanted = min(float(np.min(h(lp))) / GAP_COARSE, wanted)
        if wanted > 0.0:
            k[i] = int(math.floor(math.log2(wanted / step) + 1e-9))
            if h is None:
                k[i] = min(k[i], 0)
    steps = step * np.exp2(k)
    for level in np.unique(k[k != 0]).tolist():
        other = brep.boundary_loops(step * 2.0**level)
        for i in np.flatnonzero(k == level).tolist():
            loops[i] = np.asarray(other[i], dtype=np.float64)
    keep = [i for i, lp in enumerate(loops) if len(lp) >= 2]
    return [densify(loops[i], float(steps[i])) for i in keep], steps[keep]


#: :func:`_thinned` keeps one cone per cell ``apex / CONE_THIN`` wide among cones of about the
#: same apex (within a factor ``2 ** (1 / CONE_THIN)``).
CONE_THIN = 8


def _thinned(centres: FloatArray, apex: FloatArray, rate: float) -> tuple[FloatArray, FloatArray]:
    """The lowest cone of each cell of a grid ``apex / CONE_THIN`` wide, per band of apexes.

    The chords across a disc all pass near its centre: thousands of cones of one apex in a
    few cells, each costing the cones' index as much as a distinct one.  A cone dropped for a
    lower one at most a cell's diagonal away raises the minimum by at most ``rate`` times that
    (``sqrt(2) / CONE_THIN`` of its apex, with ``rate = 1``: two layers).
    """
    band = np.floor(np.log2(apex) * CONE_THIN)
    cell = np.exp2(band / CONE_THIN) / CONE_THIN
    ix = np.floor(centres[:, 0] / cell)
    iy = np.floor(centres[:, 1] / cell)
    order = np.lexsort((apex, iy, ix, band))
    key = np.stack([band, ix, iy], axis=1)[order]
    first = np.r_[True, np.any(key[1:] != key[:-1], axis=1)]
    pick = np.sort(order[first])
    return centres[pick], apex[pick]


#: Cells of :class:`_Cones`' grid of lower bounds per cone (the corner caps' ``CONE_CELLS`` is
#: 2).  The index gives the brute-force minimum bit for bit at any count; with a quarter of the
#: cells it is built in 1.3 ms rather than 3.0 (the square with a hole and an inclusion, 1304
#: cones), and 3.7 million evaluations (a 1e5-node square with inclusions near the walls) take
#: the same 31 ms.
GAP_CONE_CELLS = 0.5


class _Cones:
    """``min(h(p), min_c (s_c + rate |p - c|))`` over the points c (the brute-force minimum bit
    for bit, :func:`~injmesh.kernels.outline.corner_cones`)."""

    def __init__(self, h: SizeFunction, centres: FloatArray, apex: FloatArray, rate: float) -> None:
        from .boundary import CONE_LEAF
        from .kernels.outline import cone_index

        self.h, self.rate = h, rate
        centres = np.ascontiguousarray(centres, dtype=np.float64)
        apex = np.ascontiguousarray(apex, dtype=np.float64)
        # Meaningful anywhere when h is (a uniform size): see sizing.features.unrestricted.
        self.everywhere = h.constant is not None
        h_max = float(np.max(h(centres)))
        reach = (h_max - float(apex.min())) / rate
        extent = float(np.ptp(centres, axis=0).max())
        margin = min(reach, extent) if extent > 0.0 else reach
        self.index = cone_index(centres, apex, float(rate), CONE_LEAF, margin, GAP_CONE_CELLS * len(centres),
                                h_max)

    def __call__(self, p: FloatArray) -> FloatArray:
        from .kernels.outline import threaded_corner_cones

        hp = self.h(p)
        if len(p) == 0:
            return hp
        out: FloatArray = threaded_corner_cones(np.ascontiguousarray(p, dtype=np.float64),
                                                np.ascontiguousarray(hp, dtype=np.float64), self.index)
        return out


class _LowerInParts:
    """``min(h, fs_k / layers)`` with ``fs_k`` the feature size of the region holding the point,
    or (the last) of the rest of the domain; only the regions' d are evaluated, since h is asked
    inside the domain only."""

    def __init__(self, h: SizeFunction, regions: list[Domain], sizes: list[GriddedSize | None],
                 layers: float) -> None:
        self.h, self.regions, self.sizes, self.layers = h, regions, sizes, layers

    def __call__(self, p: FloatArray) -> FloatArray:
        out = np.array(self.h(p), dtype=float)
        rest = np.ones(len(p), dtype=bool)
        for region, fs in zip(self.regions, self.sizes, strict=False):
            inside = region.sdf(p) <= 0
            rest &= ~inside
            if fs is not None and inside.any():
                out[inside] = np.minimum(out[inside], fs(p[inside]) / self.layers)
        last = self.sizes[-1]
        if last is not None and rest.any():
            out[rest] = np.minimum(out[rest], last(p[rest]) / self.layers)
        return out
