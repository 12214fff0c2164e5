"""``generate`` end to end: bad input, determinism, scale and translation invariance, progress,
the immutable Mesh, and the quality metrics it reports."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

import injmesh
from conftest import assert_valid_mesh, canonical_triangles
from injmesh import (
    Circle,
    ConvergenceWarning,
    GeometryError,
    Mesh,
    NodeBudgetError,
    Polygon,
    Progress,
    Rectangle,
)
from injmesh.cases import CASES
from injmesh.quality import triangle_quality, unique_edges

DISC = Circle((0, 0), 1)
L_VERTICES = np.array([(0, 0), (1, 0), (1, 0.5), (0.5, 0.5), (0.5, 1), (0, 1)], dtype=float)


def _disc_sdf(p):
    return np.hypot(p[:, 0], p[:, 1]) - 1


def _circles(scale: float = 1.0, offset=(0.0, 0.0)):
    o = np.asarray(offset, dtype=float)
    a = Circle(o + scale * np.array([0.0, 0.0]), scale)
    b = Circle(o + scale * np.array([1.0, 0.0]), 0.7 * scale)
    return (a | b) - Circle(o + scale * np.array([0.2, 0.1]), 0.3 * scale)


@pytest.fixture(scope="module")
def disc_mesh() -> Mesh:
    return injmesh.generate(DISC, 0.2)


# --- bad input: clear exceptions, never a SciPy traceback ---------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        (dict(domain=_disc_sdf, size=0.1, bbox=None), TypeError, "needs bbox"),
        (dict(domain=3, size=0.1), TypeError, "Domain or a callable"),
        (dict(domain=lambda p: np.ones((len(p), 2)), size=0.1, bbox=(-1, -1, 1, 1)), ValueError, "shape"),
        (dict(domain=lambda p: 1.0, size=0.1, bbox=(-1, -1, 1, 1)), ValueError, "shape"),
        (dict(domain=lambda p: np.ones(len(p)), size=0.1, bbox=(-1, -1, 1, 1)), GeometryError, "empty"),
        (dict(domain=_disc_sdf, size=0.1, bbox=(-0.5, -0.5, 0.5, 0.5)), GeometryError,
         "does not contain the domain"),
        (dict(domain=_disc_sdf, size=0.1, bbox=(1, 1, -1, -1)), GeometryError, "xmin < xmax"),
        (dict(domain=DISC, size=0.01, max_nodes=1000), NodeBudgetError, "max_nodes=1000"),
        (dict(domain=DISC, size=0.1, fixed_points=[[2.0, 2.0]]), ValueError, "outside the domain"),
        (dict(domain=_disc_sdf, size=0.1, bbox=(-1, -1, 1, 1), fixed_points=[[0, 3.0]]), ValueError,
         "outside the domain"),
        (dict(domain=DISC, size=0.1, fixed_points=[1.0, 2.0, 3.0]), ValueError, r"\(n, 2\)"),
        (dict(domain=DISC, size=0.1, method="delaunay"), ValueError, "method must be"),
        (dict(domain=DISC, size=0.1, smoothing="laplace"), ValueError, "smoothing must be"),
        (dict(domain=DISC, size=0.1, max_iterations=-1), ValueError, "max_iterations"),
        (dict(domain=DISC, size=0.1, max_iterations=2.5), ValueError, "max_iterations"),
        (dict(domain=DISC, size=0.1, max_nodes=0), ValueError, "max_nodes"),
        (dict(domain=DISC, size=0.1, h0=0.1), ValueError, "distmesh"),
        (dict(domain=DISC, size=0.1, seed=1), ValueError, "distmesh"),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_bad_input(kwargs, exc, match) -> None:
    kwargs = dict(kwargs)
    domain, size = kwargs.pop("domain"), kwargs.pop("size")
    with pytest.raises(exc, match=match) as info:
        injmesh.generate(domain, size, **kwargs)
    assert "scipy" not in type(info.value).__module__
    assert "Qhull" not in str(info.value)


def test_budget_error_is_a_value_error() -> None:
    assert issubclass(NodeBudgetError, ValueError)
    assert issubclass(GeometryError, ValueError)


def test_fixed_point_message_is_readable() -> None:
    """Under NumPy 2 a tuple of array items would print as ``(np.float64(2.0), ...)``."""
    with pytest.raises(ValueError, match=r"fixed point \(2\.0, 2\.0\) lies outside"):
        injmesh.generate(DISC, 0.1, fixed_points=[[2.0, 2.0]])


def test_iteration_cap_warns_and_still_returns_a_valid_mesh() -> None:
    with pytest.warns(ConvergenceWarning, match="did not converge"):
        mesh = injmesh.generate(DISC, 0.2, max_iterations=2)
    assert mesh.converged is False
    assert mesh.stats.iterations == 2
    assert_valid_mesh(mesh, DISC)


def test_converged_mesh_does_not_warn() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mesh = injmesh.generate(DISC, 0.2)
    assert mesh.converged is True


# --- options --------------------------------------------------------------------------------


def test_attractive_smoothing_gives_a_valid_mesh() -> None:
    case = CASES["l_shape"]
    mesh = injmesh.generate(case.geometry, case.size, smoothing="attractive")
    assert_valid_mesh(mesh, case.geometry)


def test_interior_fixed_point_is_a_node() -> None:
    fixed = np.array([[0.1, 0.2], [1.0, 0.0]])
    mesh = injmesh.generate(DISC, 0.2, fixed_points=fixed)
    assert_valid_mesh(mesh, DISC)
    for f in fixed:
        assert np.hypot(*(mesh.points - f).T).min() == 0.0


def test_fixed_points_input_not_modified() -> None:
    fixed = np.array([[0.1, 0.2]])
    injmesh.generate(DISC, 0.2, fixed_points=fixed)
    assert np.array_equal(fixed, [[0.1, 0.2]])


def test_plain_callable_domain() -> None:
    mesh = injmesh.generate(_disc_sdf, 0.2, bbox=(-1, -1, 1, 1))
    assert_valid_mesh(mesh, _disc_sdf, diameter=2 * math.sqrt(2))
    assert mesh.areas().sum() == pytest.approx(math.pi, rel=0.02)


def test_graded_hexagon_keeps_its_boundary() -> None:
    """Regression: an interior node once settled 0.5 % of h inside a boundary edge, Delaunay
    dropped the segment and the node became a boundary node (tag -1)."""
    hexagon = Polygon([(0.01, 0.9), (-0.34, 0.38), (-0.96, -0.06), (-0.55, -0.62), (0.38, -0.29),
                       (0.66, 0.0)])
    mesh = injmesh.generate(hexagon, lambda p: 0.03 + 0.3 * np.hypot(p[:, 0] - 0.5, p[:, 1]))
    assert_valid_mesh(mesh, hexagon)
    assert np.all(mesh.boundary_tags >= 0)
    assert mesh.areas().sum() == pytest.approx(hexagon.area, rel=1e-6)


def test_plate_with_a_triangular_hole_keeps_its_boundary() -> None:
    """Regression: a repair split once left a node in a boundary segment's diametral circle."""
    plate = (Polygon([[0, 0], [4, 0], [4, 3], [0, 3]]) - Polygon([[1, 1], [1, 2], [2, 2], [2, 1]])
             - Polygon([[2.5, 0.5], [3.5, 0.5], [3, 1.5]]))
    mesh = injmesh.generate(plate, 0.3)
    assert_valid_mesh(mesh, plate)
    assert np.array_equal(np.unique(mesh.boundary_tags), [0, 1, 2])
    assert mesh.areas().sum() == pytest.approx(12 - 1 - 0.5, rel=1e-9)


def test_domain_with_hole_is_meshed_around_it() -> None:
    ring = Circle((0, 0), 1) - Circle((0.3, 0.1), 0.3)
    mesh = injmesh.generate(ring, 0.1)
    assert_valid_mesh(mesh, ring)
    assert np.array_equal(np.unique(mesh.boundary_tags), [0, 1])
    assert mesh.areas().sum() == pytest.approx(math.pi * (1 - 0.09), rel=0.01)


# --- determinism, scale, translation --------------------------------------------------------


def test_same_call_gives_bit_identical_mesh() -> None:
    case = CASES["two_circles_and_square"]
    a = injmesh.generate(case.geometry, case.size)
    b = injmesh.generate(case.geometry, case.size)
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.triangles, b.triangles)
    assert np.array_equal(a.boundary_edges, b.boundary_edges)
    assert np.array_equal(a.boundary_tags, b.boundary_tags)


def _assert_same_mesh_scaled(small: Mesh, big: Mesh, scale: float, offset=(0.0, 0.0), diameter=1.0) -> None:
    assert big.n_points == small.n_points
    mapped = (big.points - np.asarray(offset)) / scale
    assert np.abs(mapped - small.points).max() <= 1e-6 * diameter
    # The same triangles; Qhull's output order may differ between the two runs.
    assert np.array_equal(canonical_triangles(big.triangles), canonical_triangles(small.triangles))


def _graded(scale: float, base: float = 0.05):
    """h = base + 0.1 x on the unit polygon, for the polygon scaled by ``scale``."""
    return lambda p: scale * (base + 0.1 * p[:, 0] / scale)


# Scaling by 1000 perturbs every coordinate by rounding (1000 is not a power of two).  Where the
# injected nodes are exactly cocircular, the choice of diagonal depends on that rounding and
# smoothing can then settle elsewhere (h = 0.05 + 0.1 x on this polygon: 159 vs 162 nodes with
# the exact Delaunay kernel; 0.045 + 0.1 x: 186 vs 183, and 185 vs 182 with Qhull once).
# If one of these two tests fails, look at the power-of-two test below first: if that passes,
# no absolute tolerance is involved, only a Delaunay tie.


def test_scale_invariance_polygon() -> None:
    """x1000 is not exact in floating point, and the injected lattice has exactly cocircular
    nodes: Qhull may break a tie differently (see the note above).  The figures must agree."""
    small = injmesh.generate(Polygon(L_VERTICES), _graded(1.0))
    big = injmesh.generate(Polygon(1000 * L_VERTICES), _graded(1000.0))
    assert abs(big.n_points - small.n_points) <= 0.02 * small.n_points
    assert min(big.quality().min(), small.quality().min()) > 0.75
    assert big.quality().mean() == pytest.approx(small.quality().mean(), abs=0.005)
    assert big.areas().sum() / 1e6 == pytest.approx(small.areas().sum(), rel=1e-9)
    assert big.size_report().relative == pytest.approx(small.size_report().relative, abs=0.01)


def test_scale_invariance_csg_of_circles() -> None:
    """Bit for bit at 1024; at 1000 the figures (Step 2 fills this uniform-h domain with a
    lattice inside the loops' strips, whose ties follow the rounding, see the note above)."""
    small = injmesh.generate(_circles(), 0.12)
    exact = injmesh.generate(_circles(1024.0), 0.12 * 1024.0)
    assert np.array_equal(exact.points / 1024.0, small.points)
    assert np.array_equal(exact.triangles, small.triangles)
    big = injmesh.generate(_circles(1000.0), 120.0)
    assert abs(big.n_points - small.n_points) <= 0.02 * small.n_points
    assert big.quality().min() == pytest.approx(small.quality().min(), abs=0.03)
    assert big.quality().mean() == pytest.approx(small.quality().mean(), abs=0.005)
    # Chords of the arcs: the area moves with the boundary nodes (1.7e-8 here).
    assert big.areas().sum() / 1e6 == pytest.approx(small.areas().sum(), rel=1e-6)


@pytest.mark.parametrize("scale", [1024.0, 1 / 8])
def test_power_of_two_scaling_is_bit_exact(scale: float) -> None:
    """Scaling by 2^k is exact in floating point: the mesh must scale bit for bit (no absolute
    tolerance anywhere in the pipeline)."""
    # base 0.045 is the polygon case that a scale of 1000 breaks by a Delaunay tie.
    small = injmesh.generate(Polygon(L_VERTICES), _graded(1.0, 0.045))
    big = injmesh.generate(Polygon(scale * L_VERTICES), _graded(scale, 0.045))
    assert np.array_equal(big.points / scale, small.points)
    assert np.array_equal(big.triangles, small.triangles)
    c_small = injmesh.generate(_circles(), 0.1)
    c_big = injmesh.generate(_circles(scale), 0.1 * scale)
    assert np.array_equal(c_big.points / scale, c_small.points)
    assert np.array_equal(c_big.triangles, c_small.triangles)


def _same_figures(moved: Mesh, small: Mesh) -> None:
    """A translated mesh is the same mesh by its figures: translation is not exact in floating
    point (1e4 from the origin a coordinate keeps 1e-12 of its digits), and the relaxation and
    the repair's choices carry such differences on; the strips' rings kept in step
    (``injection.RING_WINDOW``) gave 340 nodes at the origin, 339 at (1e4, -3e4).  What this
    guards against (Qhull dropping most points far from the origin) loses hundreds."""
    assert abs(moved.n_points - small.n_points) <= max(2, 0.01 * small.n_points)
    assert abs(moved.quality().min() - small.quality().min()) < 0.03
    assert moved.quality().mean() == pytest.approx(small.quality().mean(), abs=2e-3)


@pytest.mark.parametrize("offset", [(1e3, -2e3), (1e4, -3e4)])
def test_translation_keeps_the_mesh(offset) -> None:
    small = injmesh.generate(_circles(), 0.12)
    moved = injmesh.generate(_circles(offset=offset), 0.12)
    _same_figures(moved, small)
    assert_valid_mesh(moved, _circles(offset=offset))


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_translation_far_from_origin() -> None:
    """Regression: Qhull on raw coordinates 1e6 from the origin dropped most points, and the
    nodes left in no triangle then turned to NaN in smoothing."""
    offset = (1e6, -3e6)
    small = injmesh.generate(_circles(), 0.12)
    moved = injmesh.generate(_circles(offset=offset), 0.12)
    _same_figures(moved, small)
    assert_valid_mesh(moved, _circles(offset=offset))


# --- progress and side effects ---------------------------------------------------------------


def test_callback_receives_each_stage_and_nothing_is_printed(capsys) -> None:
    events: list[Progress] = []
    case = CASES["circle_with_hole"]
    injmesh.generate(case.geometry, case.size, callback=events.append)
    assert all(isinstance(e, Progress) for e in events)
    stages = [e.stage for e in events]
    assert set(stages) == {"boundary", "injection", "smoothing"}
    # Stages come in the order of Algorithm 1.
    assert stages.index("injection") > max(i for i, s in enumerate(stages) if s == "boundary")
    assert stages.index("smoothing") > max(i for i, s in enumerate(stages) if s == "injection")
    assert all(e.step >= 1 and (e.total is None or e.step <= e.total)
               for e in events if e.step != 0 or e.stage != "smoothing")
    # Smoothing announces its start before its first triangulation, once.
    assert [e.step for e in events if e.stage == "smoothing"][0] == 0
    assert sum(e.step == 0 for e in events) == 1
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""


def test_nothing_is_printed_without_callback(capsys) -> None:
    injmesh.generate(DISC, 0.25)
    out = capsys.readouterr()
    assert out.out == "" and out.err == ""


# --- the Mesh value ---------------------------------------------------------------------------


def test_mesh_is_immutable(disc_mesh: Mesh) -> None:
    with pytest.raises(ValueError, match="read-only"):
        disc_mesh.points[0, 0] = 5.0
    with pytest.raises(ValueError):
        disc_mesh.triangles[0, 0] = 0
    with pytest.raises(ValueError):
        disc_mesh.boundary_edges[0, 0] = 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        disc_mesh.points = np.zeros((3, 2))  # type: ignore[misc]


def test_mesh_copies_its_inputs() -> None:
    p = np.array([[0, 0], [1, 0], [0, 1]], dtype=float)
    t = np.array([[0, 1, 2]])
    mesh = Mesh(points=p, triangles=t, boundary_edges=np.array([[0, 1], [1, 2], [2, 0]]),
                boundary_tags=np.zeros(3, dtype=int))
    p[0, 0] = 9.0
    assert mesh.points[0, 0] == 0.0


def test_mesh_repr_summarises(disc_mesh: Mesh) -> None:
    r = repr(disc_mesh)
    assert "points" in r and "triangles" in r
    assert str(disc_mesh.n_points) in r
    assert len(r) < 100


def test_mesh_properties(disc_mesh: Mesh) -> None:
    m = disc_mesh
    assert m.n_points == len(m.points) and m.n_triangles == len(m.triangles)
    assert np.array_equal(m.boundary_nodes, np.unique(m.boundary_edges))
    assert m.quality().shape == (m.n_triangles,)
    assert m.angles().shape == (m.n_triangles, 3)
    assert np.allclose(m.angles().sum(axis=1), 180.0)
    assert m.areas().sum() == pytest.approx(math.pi, rel=0.02)
    # Euler: V - E + F = 1 for a disc.
    assert m.n_points - len(m.edges) + m.n_triangles == 1
    s = m.summary()
    assert s["N"] == m.n_points and s["converged"] is True
    assert 0 < s["q_min"] <= s["q_mean"] <= 1
    assert s["Er_rel"] == pytest.approx(m.size_report().relative)


def test_size_report_against_another_h(disc_mesh: Mesh) -> None:
    assert disc_mesh.size_report(0.2).relative == pytest.approx(disc_mesh.size_report().relative)
    assert disc_mesh.size_report(0.4).ratio_mean == pytest.approx(0.5 * disc_mesh.size_report().ratio_mean)


def test_mesh_without_size_refuses_size_report() -> None:
    mesh = Mesh(points=np.array([[0, 0], [1, 0], [0, 1]], dtype=float), triangles=np.array([[0, 1, 2]]),
                boundary_edges=np.array([[0, 1], [1, 2], [2, 0]]), boundary_tags=np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="size"):
        mesh.size_report()


# --- quality metrics ----------------------------------------------------------------------------


def test_quality_of_equilateral_is_one() -> None:
    p = np.array([[0, 0], [1, 0], [0.5, math.sqrt(3) / 2]])
    assert triangle_quality(p, np.array([[0, 1, 2]]))[0] == pytest.approx(1.0, abs=1e-12)
    # Invariant under scaling, rotation and vertex order.
    rot = np.array([[math.cos(1), -math.sin(1)], [math.sin(1), math.cos(1)]])
    q = triangle_quality(1e3 * p @ rot.T, np.array([[2, 0, 1], [0, 2, 1]]))
    assert np.allclose(q, 1.0)


def test_quality_of_degenerate_is_zero() -> None:
    p = np.array([[0, 0], [1, 0], [2, 0], [0, 0]], dtype=float)
    q = triangle_quality(p, np.array([[0, 1, 2], [0, 1, 3]]))
    assert np.array_equal(q, [0.0, 0.0])


def test_quality_of_right_isoceles() -> None:
    p = np.array([[0, 0], [1, 0], [0, 1]], dtype=float)
    assert triangle_quality(p, np.array([[0, 1, 2]]))[0] == pytest.approx(2 * (math.sqrt(2) - 1))


def test_unique_edges_sorted_i_lt_j() -> None:
    t = np.array([[0, 1, 2], [2, 1, 3], [3, 1, 4]])
    e = unique_edges(t)
    assert np.all(e[:, 0] < e[:, 1])
    assert len(e) == len({tuple(x) for x in e.tolist()}) == 7
    assert np.array_equal(e, e[np.lexsort((e[:, 1], e[:, 0]))])


def test_rectangle_mesh_area_is_exact() -> None:
    rect = Rectangle((0, 0), (2, 1))
    mesh = injmesh.generate(rect, 0.15)
    assert_valid_mesh(mesh, rect)
    assert mesh.areas().sum() == pytest.approx(2.0, rel=1e-12)


# --- robustness: features at or below the element size ----------------------------------------


def test_hole_smaller_than_h_is_left_out_with_a_warning() -> None:
    plate = Rectangle((0, 0), (1, 1)) - Circle((0.5, 0.5), 0.01)
    with pytest.warns(UserWarning, match="smaller than the elements"):
        mesh = injmesh.generate(plate, 0.2)
    assert_valid_mesh(mesh, Rectangle((0, 0), (1, 1)))
    assert np.array_equal(np.unique(mesh.boundary_tags), [0])


def test_coarse_hole_leaves_no_gap_in_the_mesh() -> None:
    """A hole carrying five nodes: triangles next to its chords have centroids beyond the true
    circle, yet they are inside the meshed pentagon and must be kept (no gap, no tag -1)."""
    plate = Rectangle((-1, -1), (1, 1)) - Circle((0, 0), 0.16)
    mesh = injmesh.generate(plate, lambda p: 0.1 + 0.3 * np.hypot(p[:, 0], p[:, 1]))
    assert np.all(mesh.boundary_tags >= 0)
    hole = mesh.boundary_edges[mesh.boundary_tags == 1]
    polygon = mesh.points[hole]
    hole_area = -0.5 * np.sum(polygon[:, 0, 0] * polygon[:, 1, 1] - polygon[:, 1, 0] * polygon[:, 0, 1])
    assert mesh.areas().sum() == pytest.approx(4.0 - hole_area, rel=1e-9)


def test_small_hole_under_strong_grading_keeps_distinct_nodes() -> None:
    """Regression: Eq. 3.3 applied in the plane drifted the few nodes of a small, strongly
    graded hole onto one point; balancing on arc length keeps them apart."""
    plate = Rectangle((-1, -1), (1, 1)) - Circle((0, 0), 0.09)
    mesh = injmesh.generate(plate, lambda p: 0.044 + 0.18 * np.hypot(p[:, 0] + 0.3, p[:, 1] - 0.4))
    assert_valid_mesh(mesh, plate)
    e = mesh.boundary_edges[mesh.boundary_tags == 1]
    lengths = np.hypot(*(mesh.points[e[:, 0]] - mesh.points[e[:, 1]]).T)
    assert len(e) >= 3 and lengths.min() > 0.5 * lengths.max()
    assert mesh.quality().min() > 0.5


def test_spike_narrower_than_h_conforms() -> None:
    """A 10-degree spike: its boundary segments are split where they are encroached, so the
    mesh keeps every boundary segment; boundary nodes do not crowd into the tip, so smoothing
    converges."""
    spike = Polygon([(0, 0), (1, 0), (1, 0.5), (-1.5, 0.55), (0, 0.4)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", injmesh.ConvergenceWarning)
        mesh = injmesh.generate(spike, 0.1)
    assert mesh.converged
    assert_valid_mesh(mesh, spike)
    assert mesh.areas().sum() == pytest.approx(spike.area, rel=1e-9)


def test_fixed_points_are_exact_nodes_of_the_injection_mesh() -> None:
    """User points inside (and on) the domain are mesh nodes, untouched by smoothing, repair
    and the quality pass."""
    fixed = np.array([[0.3, 0.2], [-0.4, 0.1], [0.0, -0.5], [1.0, 0.0]])
    mesh = injmesh.generate(DISC, 0.1, fixed_points=fixed)
    assert_valid_mesh(mesh, DISC)
    for f in fixed:
        assert np.hypot(*(mesh.points - f).T).min() == 0.0
    assert mesh.quality().min() > 0.6


def test_a_plain_function_is_not_cleaned_so_needs_no_h_min(monkeypatch) -> None:
    """Domain.cleaned changes nothing for a plain signed distance: the cleaning's h_min
    estimate (a quadrature of h) is skipped, and the mesh is the same."""
    import injmesh.pipeline as pipeline

    case = CASES["l_shape"]
    before = injmesh.generate(case.sdf, case.size, bbox=case.bbox, fixed_points=case.fixed_points)

    def no_estimate(*args, **kwargs):
        raise AssertionError("h_min was estimated for the cleaning")

    monkeypatch.setattr(pipeline, "estimate_nodes", no_estimate)
    after = injmesh.generate(case.sdf, case.size, bbox=case.bbox, fixed_points=case.fixed_points)
    assert np.array_equal(before.points, after.points) and np.array_equal(before.triangles, after.triangles)
    assert after.stats.cleaning == {}


@pytest.mark.parametrize("name", ["unit_disc", "circle_with_hole", "two_circles_and_square"])
@pytest.mark.parametrize("region", [False, True])
def test_the_node_estimate_is_made_once_for_a_domain_cleaning_keeps(monkeypatch, name, region) -> None:
    """A circle is its own cleaned domain, and a difference of circles (and rectangles) is
    cleaned to the exact boundary it computes its distance with: the cleaning's node estimate
    is the one the regions (and Step 1, where h needs no correction) would make, so it is not
    made again; the mesh is the same as with every estimate made afresh."""
    import injmesh.boundary as boundary
    import injmesh.pipeline as pipeline
    from test_regions import PAPER_INCLUSIONS

    case = CASES[name]
    centre, radius = PAPER_INCLUSIONS[name]
    regions = {"inclusion": Circle(centre, radius)} if region else None
    calls = []
    real = boundary.estimate_nodes

    def counted(*args, **kwargs):
        calls.append(args)
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "estimate_nodes", counted)
    monkeypatch.setattr(boundary, "estimate_nodes", counted)
    once = injmesh.generate(case.geometry, case.size, regions=regions)
    made = len(calls)
    monkeypatch.setattr(pipeline._Estimate, "of", lambda self, domain, size: None)
    calls.clear()
    again = injmesh.generate(case.geometry, case.size, regions=regions)
    assert len(calls) == (3 if region else 2)
    assert made < len(calls)
    if name == "unit_disc":
        assert made == 1
    assert np.array_equal(once.points, again.points) and np.array_equal(once.triangles, again.triangles)


@pytest.mark.parametrize("seed", range(6))
def test_a_kept_node_estimate_is_the_one_of_the_size_followed(seed) -> None:
    """On random circles (their own cleaned domains), rings (which are not) and sizes, an
    estimate that :class:`pipeline._Estimate` hands to Step 1 equals ``estimate_nodes`` of what
    Step 1 follows, bit for bit; and it is handed over where it applies."""
    from injmesh.boundary import corner_size, estimate_nodes
    from injmesh.pipeline import _capped, _clean, _Estimate, _target_size
    from injmesh.sizing import as_size_function

    rng = np.random.default_rng(seed)
    c, r = rng.uniform(-2, 2, 2), rng.uniform(0.3, 3.0)
    apex, base, slope = rng.uniform(-2, 2, 2), rng.uniform(0.05, 0.2) * r, rng.uniform(0.02, 0.15)
    sizes = [lambda p: base + slope * np.hypot(*(p - apex).T), lambda p: np.full(len(p), 0.3 * r), 0.1 * r]
    kept_any = False
    for domain in (Circle(c, r), Circle(c, r) - Circle(c + 0.3 * r * rng.uniform(-1, 1, 2), 0.2 * r)):
        for size in sizes:
            h = as_size_function(size)
            dom, _, known, _ = _clean(domain, h)
            assert isinstance(known, _Estimate)
            cornered = corner_size(dom, h, 0.2)
            target, follow = _target_size(dom, cornered, 2.0, 0.2)
            kept = known.followed(dom, cornered, target)
            if kept is not None:
                kept_any = True
                assert kept == estimate_nodes(dom, _capped(follow, dom.diameter))
    assert kept_any


@pytest.mark.parametrize("seed", range(8))
def test_a_combination_answers_the_node_estimate_as_its_exact_boundary(seed) -> None:
    """Where ``pipeline._answers_as`` says a CSG domain computes the node estimate as its
    cleaned exact boundary does, the two estimates are equal bit for bit (random unions,
    differences and intersections of circles and rectangles, random graded sizes)."""
    from injmesh.boundary import estimate_nodes
    from injmesh.pipeline import _answers_as
    from injmesh.sizing import as_size_function

    rng = np.random.default_rng(100 + seed)
    c, r = rng.uniform(-1, 1, 2), rng.uniform(0.5, 2.0)
    disc = Circle(c, r)
    box = Rectangle(c - rng.uniform(0.2, 0.9, 2) * r, c + rng.uniform(0.2, 0.9, 2) * r)
    small = Circle(c + rng.uniform(-0.3, 0.3, 2) * r, rng.uniform(0.05, 0.2) * r)
    domain = [disc - small, disc | (box - small), (disc & box) - small, (box | disc) - small][seed % 4]
    apex, base, slope = rng.uniform(-2, 2, 2), rng.uniform(0.02, 0.1) * r, rng.uniform(0.1, 0.5)
    h = as_size_function(lambda p: base + slope * np.hypot(*(p - apex).T))
    exact = domain.exact_brep()
    # An intersection's box is its operands' overlap, often larger than its exact boundary's
    # (then it is not reused); a difference's and a union's are the boundary's own.
    assert _answers_as(domain, exact) or seed % 4 == 2
    if _answers_as(domain, exact):
        assert estimate_nodes(domain, h.restricted(domain)) == estimate_nodes(exact, h.restricted(exact))


def _pfix_polygon() -> tuple[np.ndarray, np.ndarray]:
    """A polygon as GIS data gives it, and its vertices as a DistMesh ``pfix``: a vertex
    repeated 2e-7 away, and vertices on straight sides (which the outline does not make
    corners of)."""
    ring = np.array([(0.0, 0.0), (0.5, 0.0), (1.0, 0.0), (1.0, 0.6), (1.0000002, 0.6000001),
                     (0.7, 1.0), (0.35, 1.0), (0.0, 1.0), (0.0, 0.5)])
    return ring, ring.copy()


@pytest.mark.parametrize("form", ["geometry", "plain"])
def test_a_pfix_of_the_polygons_vertices_meshes(form: str) -> None:
    """Every vertex of the outline given as a fixed point, near-duplicates included, as
    DistMesh users write it: one node per distinct vertex, none twice (the repeated vertex
    made a zero-area triangle, a vertex on a straight side two nodes at one place), and the
    merge counted in ``stats.cleaning``."""
    ring, pfix = _pfix_polygon()
    poly = Polygon(ring)
    if form == "geometry":
        mesh = injmesh.generate(poly, 0.1, fixed_points=pfix)
    else:
        mesh = injmesh.generate(poly.sdf, 0.1, bbox=(-0.1, -0.1, 1.1, 1.1), fixed_points=pfix)
    assert_valid_mesh(mesh, poly)
    distinct = np.delete(pfix, 4, axis=0)
    for v in distinct:
        assert np.hypot(*(mesh.points - v).T).min() <= 3e-7
    # No two nodes closer than the checks' "same point".
    from scipy.spatial import cKDTree

    assert not cKDTree(mesh.points).query_pairs(1e-6 * poly.diameter)
    if form == "geometry":
        assert mesh.stats.cleaning.get("merged_fixed_points", 0) >= 1


def test_a_fixed_point_a_hair_inside_the_boundary_is_one_boundary_node() -> None:
    """A point 1e-9 inside a side is on the boundary as far as the checks go: one boundary
    node, not a boundary node and an interior node at the same place."""
    square = Rectangle((0, 0), (1, 1))
    mesh = injmesh.generate(square, 0.2, fixed_points=[(0.5, 1e-9)])
    assert_valid_mesh(mesh, square)
    assert np.count_nonzero(np.hypot(mesh.points[:, 0] - 0.5, mesh.points[:, 1]) < 1e-6) == 1
