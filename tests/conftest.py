"""Shared helpers and fixtures: the mesh validity check and cached meshes of the paper's cases.

``assert_valid_mesh`` states what every mesh injmesh returns must satisfy, whatever the domain:
tests assert these invariants rather than coordinates (STYLE.md, habit 10).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from functools import cache

import numpy as np
import pytest
from hypothesis import settings

import injmesh
from injmesh import Domain, Mesh
from injmesh.cases import CASES
from injmesh.quality import signed_areas

# CI draws the same examples every run (HYPOTHESIS_PROFILE=ci, set by .ci/run): a landing is
# not refused by an unlucky draw, and a failure there reproduces.  Local runs explore anew.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

#: A boundary node is on the boundary when |d| is below this fraction of the domain's diameter.
ON_BOUNDARY = 1e-6

CASE_NAMES = sorted(CASES)
FORMS = ("geometry", "sdf")


def _diameter(domain: Domain | Callable, points: np.ndarray, diameter: float | None) -> float:
    if diameter is not None:
        return float(diameter)
    if isinstance(domain, Domain):
        return domain.diameter
    return float(np.hypot(*np.ptp(points, axis=0)))


def assert_valid_mesh(mesh: Mesh, domain: Domain | Callable, *, diameter: float | None = None) -> None:
    """Assert the invariants of a mesh of ``domain`` (a Domain or a plain signed distance d(p)).

    * arrays of the documented shapes and dtypes;
    * triangles counter-clockwise with positive area, no duplicates, every node used;
    * every triangle centroid inside (``d <= 0``: the paper's L-shape is 0 on an interior line);
    * every edge in one or two triangles; ``boundary_edges`` are exactly the edges in one
      triangle, oriented as in it (domain on the left), and enclose the mesh's area;
    * every node of a boundary edge on the boundary, ``|d| < ON_BOUNDARY * diameter``;
    * one boundary tag per boundary edge.
    """
    sdf = domain.sdf if isinstance(domain, Domain) else domain
    p, t = mesh.points, mesh.triangles
    assert p.ndim == 2 and p.shape[1] == 2 and p.dtype == np.float64
    assert t.ndim == 2 and t.shape[1] == 3 and np.issubdtype(t.dtype, np.integer)
    assert np.all(np.isfinite(p))
    assert len(t) > 0
    assert t.min() >= 0 and t.max() < len(p)

    areas = signed_areas(p, t)
    assert areas.min() > 0, f"{np.sum(areas <= 0)} triangles are clockwise or flat"
    canon = np.sort(t, axis=1)
    assert len(np.unique(canon, axis=0)) == len(t), "duplicate triangles"
    assert np.array_equal(np.unique(t), np.arange(len(p))), "some nodes are not used by any triangle"

    centroids = p[t].mean(axis=1)
    d_cent = np.asarray(sdf(centroids))
    assert d_cent.max() <= 0, f"a triangle centroid is outside: d = {d_cent.max():.3g}"

    # Directed half-edges: each appears once (consistent orientation), each undirected edge in
    # one or two triangles.
    half = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    assert len(np.unique(half, axis=0)) == len(half), "a directed edge occurs twice (fold or overlap)"
    _, count = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    assert count.max() <= 2, "an edge is shared by more than two triangles"

    be = mesh.boundary_edges
    assert be.ndim == 2 and be.shape[1] == 2
    assert len(be) == int(np.sum(count == 1)), "boundary_edges are not the edges of one triangle"
    half_set = {tuple(e) for e in half.tolist()}
    assert all(tuple(e) in half_set for e in be.tolist()), "a boundary edge is not oriented as its triangle"
    # Green's theorem: with the domain on the left, the edges enclose exactly the mesh's area.
    # Coordinates relative to a node: far from the origin the cross products would cancel.
    a, b = p[be[:, 0]] - p[0], p[be[:, 1]] - p[0]
    enclosed = 0.5 * np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    assert enclosed == pytest.approx(areas.sum(), rel=1e-9)

    diam = _diameter(domain, p, diameter)
    nodes = np.unique(be)
    resid = np.abs(np.asarray(sdf(p[nodes])))
    assert resid.max() < ON_BOUNDARY * diam, f"a boundary node is off the boundary: |d| = {resid.max():.3g}"

    assert mesh.boundary_tags.shape == (len(be),)
    if mesh.stats.method == "injection":
        # Every boundary edge joins two nodes of Step 1's boundary: the mesh conforms to it.
        assert np.all(mesh.boundary_tags >= 0), "a boundary edge is not a boundary segment"


def canonical_triangles(triangles: np.ndarray) -> np.ndarray:
    """Triangles with each row rotated to start at its smallest index (orientation kept), sorted."""
    t = np.asarray(triangles)
    k = np.argmin(t, axis=1)
    rows = np.arange(len(t))[:, None]
    rot = t[rows, (k[:, None] + np.arange(3)) % 3]
    return rot[np.lexsort(rot.T[::-1])]


@cache
def paper_mesh(name: str, form: str) -> Mesh:
    """The mesh of a paper case, as composed geometry or as the plain sdf; computed once."""
    case = CASES[name]
    if form == "geometry":
        return injmesh.generate(case.geometry, case.size)
    return injmesh.generate(case.sdf, case.size, bbox=case.bbox, fixed_points=case.fixed_points)


@pytest.fixture(params=CASE_NAMES)
def case(request: pytest.FixtureRequest):
    """Each of the paper's six cases."""
    return CASES[request.param]
