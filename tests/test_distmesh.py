"""The DistMesh baseline: determinism, validity on the paper's cases, agreement with the reference."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import injmesh
from conftest import assert_valid_mesh
from injmesh import Circle, ConvergenceWarning, NodeBudgetError, Rectangle
from injmesh.cases import CASES
from injmesh.distmesh import default_h0, distmesh, initial_points
from injmesh.mesh import Mesh

DISC = CASES["unit_disc"]
#: Boundary loops of each case: outer boundary plus holes.
LOOPS = {
    "unit_disc": 1,
    "square_with_hole": 2,
    "circle_with_hole": 2,
    "square_with_four_holes": 5,
    "two_circles_and_square": 1,
    "l_shape": 1,
}


def disc_mesh(seed: int, h0: float = 0.04) -> Mesh:
    return injmesh.generate(DISC.geometry, DISC.size, method="distmesh", h0=h0, seed=seed)


def assert_valid(mesh: Mesh, domain, h0: float) -> None:
    """The invariants every mesh satisfies (conftest), and no node outside the domain."""
    assert_valid_mesh(mesh, domain)
    sdf = domain.sdf if hasattr(domain, "sdf") else domain
    assert np.all(sdf(np.asarray(mesh.points)) < 1e-6 * h0), "no node outside"


def test_same_seed_gives_identical_arrays():
    a, b = disc_mesh(7), disc_mesh(7)
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.triangles, b.triangles)
    assert np.array_equal(a.boundary_edges, b.boundary_edges)
    assert a.stats.iterations == b.stats.iterations


def test_different_seeds_give_different_meshes():
    a, b = disc_mesh(1), disc_mesh(2)
    assert a.n_points != b.n_points or not np.array_equal(a.points, b.points)


def test_unit_disc_agrees_with_the_reference():
    """PyDistMesh gives 102-119 nodes and q_min around 0.7-0.8 over six seeds at h0 = 0.04.

    A single seed can be poor (the paper's Table 2 spans 0.69-0.81 at h0 = 0.01): the typical
    run is asserted by the median, every run by a floor.
    """
    qmins = []
    for seed in range(1, 7):
        mesh = disc_mesh(seed)
        assert 95 <= mesh.n_points <= 125, (seed, mesh.n_points)
        assert mesh.quality().min() > 0.5, seed
        assert mesh.converged
        assert mesh.stats.method == "distmesh"
        assert mesh.stats.retriangulations >= 1
        qmins.append(mesh.quality().min())
    assert 0.65 <= np.median(qmins) <= 0.85, qmins


@pytest.mark.parametrize("name", sorted(CASES))
def test_valid_on_every_case(name):
    case = CASES[name]
    h0 = max(case.h0, 0.04)  # the paper's h0, coarsened to keep the test fast
    mesh = injmesh.generate(case.geometry, case.size, method="distmesh", h0=h0, seed=3)
    assert_valid(mesh, case.geometry, h0)
    assert mesh.converged
    assert mesh.quality().min() > 0.3
    tags = np.asarray(mesh.boundary_tags)
    assert sorted(set(tags.tolist())) == list(range(LOOPS[name]))
    outer = np.asarray(mesh.points)[np.asarray(mesh.boundary_edges)[tags == 0]]
    x0, y0, x1, y1 = case.geometry.bbox
    assert np.ptp(outer[:, :, 0]) > 0.9 * (x1 - x0), "tag 0 is the outer boundary"
    for corner in case.geometry.corners():
        assert np.any(np.all(np.asarray(mesh.points) == corner, axis=1)), "corners stay put"


def test_plain_distance_function_with_an_interior_zero_line():
    """Table 10's L-shape d vanishes on an interior segment; the mesh must not split there."""
    case = CASES["l_shape"]
    mesh = injmesh.generate(
        case.sdf, case.size, method="distmesh", bbox=case.bbox, fixed_points=case.fixed_points,
        h0=0.04, seed=1,
    )
    assert_valid(mesh, case.geometry, 0.04)
    assert np.isclose(mesh.areas().sum(), 0.4 + 0.4 * 0.6, rtol=0.02)
    for corner in case.fixed_points:
        assert np.any(np.all(np.asarray(mesh.points) == corner, axis=1))


def test_user_fixed_points_never_move():
    fixed = np.array([[0.3, 0.3], [-0.2, 0.5], [5.0, 5.0]])  # the last is outside: ignored
    mesh = distmesh(Circle((0, 0), 1), lambda p: np.full(len(p), 0.15), h0=0.15, seed=0,
                    fixed_points=fixed)
    for f in fixed[:2]:
        assert np.any(np.all(np.asarray(mesh.points) == f, axis=1))
    assert np.all(np.abs(mesh.points).max(axis=1) <= 1 + 1e-9)


def test_initial_points_are_where_distmesh_starts():
    square = Rectangle((0, 0), (1, 1))
    h = lambda p: 0.05 + 0.3 * p[:, 0]  # noqa: E731
    p = initial_points(square, h, 0.05, np.random.default_rng(4))
    mesh = distmesh(square, h, h0=0.05, seed=4)
    assert mesh.stats.initial_nodes == len(p)
    assert np.array_equal(p[:4], square.corners())
    assert np.all(square.sdf(p) < 1e-3 * 0.05)
    # Rejection thins the grid where h is large.
    left, right = np.count_nonzero(p[:, 0] < 0.3), np.count_nonzero(p[:, 0] > 0.7)
    assert left > 3 * right


def test_default_h0_is_the_smallest_h():
    assert default_h0(DISC.geometry, DISC.size) == pytest.approx(0.04, rel=1e-3)
    mesh = injmesh.generate(DISC.geometry, DISC.size, method="distmesh", seed=2)
    assert 95 <= mesh.n_points <= 125


def test_node_budget():
    with pytest.raises(NodeBudgetError, match=r"h0=0\.0001.*\d+ points"):
        injmesh.generate(DISC.geometry, 0.1, method="distmesh", h0=1e-4, seed=0)
    with pytest.raises(NodeBudgetError, match="max_nodes=100"):
        injmesh.generate(DISC.geometry, 0.1, method="distmesh", h0=0.1, seed=0, max_nodes=100)


def test_bad_h0():
    for h0 in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="h0"):
            distmesh(DISC.geometry, DISC.size, h0=h0, seed=0)
    with pytest.raises(ValueError, match="only"):
        distmesh(DISC.geometry, DISC.size, h0=5.0, seed=0)


def test_iteration_cap_and_progress():
    events = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mesh = injmesh.generate(DISC.geometry, DISC.size, method="distmesh", h0=0.04, seed=1,
                                max_iterations=5, callback=events.append, strict=False)
    assert not mesh.converged and mesh.stats.iterations == 5
    # Five steps leave slivers: strict=False returns the mesh flagged, naming them and where.
    assert not mesh.stats.valid
    assert {d.kind for d in mesh.stats.defects} == {"degenerate triangle (q < 0.001)"}
    assert all(len(d.where) == min(d.count, 10) for d in mesh.stats.defects)
    with pytest.raises(injmesh.MeshError, match="degenerate triangle"):
        injmesh.generate(DISC.geometry, DISC.size, method="distmesh", h0=0.04, seed=1, max_iterations=5)
    assert any(issubclass(w.category, ConvergenceWarning) for w in caught)
    assert [e.step for e in events] == [1, 2, 3, 4, 5]
    assert {e.stage for e in events} == {"distmesh"}
    assert events[0].total == 5 and events[0].info["nodes"] > 90 and events[0].info["max_move"] > 0
    # Still a valid triangulation, though its boundary nodes have not reached the circle yet.
    assert mesh.areas().min() > 0
    assert np.array_equal(np.unique(mesh.triangles), np.arange(mesh.n_points))
