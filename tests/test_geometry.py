"""Contract tests: every geometry class through the same checks, then class-specific facts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from injmesh import (
    Circle,
    Difference,
    Domain,
    GeometryError,
    Implicit,
    Intersection,
    Polygon,
    Rectangle,
    Union,
)
from injmesh.cases import CASES

CONVEX = [(0, 0), (2, 0), (2.5, 1), (1, 2), (-0.5, 1)]
ARROW = [(0, 0), (2, 1), (0, 2), (0.7, 1)]  # non-convex: reflex vertex at (0.7, 1)
LENS = 2 * math.acos(0.75) - 0.75 * math.sqrt(1.75)  # overlap of two unit discs 1.5 apart


def _shoelace(v) -> float:
    v = np.asarray(v, dtype=float)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _annulus(p):
    r = np.hypot(p[:, 0], p[:, 1])
    return np.maximum(r - 1.0, 0.3 - r)


# name: (domain, inside point, outside point, number of boundary loops, area)
DOMAINS = {
    "circle": (Circle((0.3, -0.2), 0.7), (0.3, -0.2), (1.2, 0.6), 1, math.pi * 0.49),
    "rectangle": (Rectangle((2, 1), (0, 0)), (1.0, 0.5), (3.0, 0.5), 1, 2.0),
    "polygon-convex-ccw": (Polygon(CONVEX), (1.0, 1.0), (3.0, 3.0), 1, abs(_shoelace(CONVEX))),
    "polygon-convex-cw": (Polygon(CONVEX[::-1]), (1.0, 1.0), (3.0, 3.0), 1, abs(_shoelace(CONVEX))),
    "polygon-nonconvex-ccw": (Polygon(ARROW), (1.0, 1.0), (0.3, 1.0), 1, abs(_shoelace(ARROW))),
    "polygon-nonconvex-cw": (Polygon(ARROW[::-1]), (1.0, 1.0), (0.3, 1.0), 1, abs(_shoelace(ARROW))),
    "union": (Circle((0, 0), 1) | Circle((1.5, 0), 1), (0.75, 0.0), (0.75, 0.9), 1, 2 * math.pi - LENS),
    "intersection": (Rectangle((-1, -1), (1, 1)) & Circle((1, 1), 1), (0.5, 0.5), (-0.5, -0.5), 1,
                     math.pi / 4),
    "difference": (Rectangle((0, 0), (2, 2)) - Circle((1, 1), 0.5), (0.2, 0.2), (1.0, 1.0), 2,
                   4 - math.pi / 4),
    "nested-csg": ((Rectangle((0, 0), (2, 1)) | Circle((2, 0.5), 0.5)) - Rectangle((0.5, 0.25), (1, 0.75)),
                   (0.25, 0.5), (0.75, 0.5), 2, 2 + math.pi / 8 - 0.25),
    "implicit": (Implicit(_annulus, bbox=(-1, -1, 1, 1)), (0.6, 0.0), (0.0, 0.0), 2, math.pi * 0.91),
    "implicit-l-shape": (Implicit(CASES["l_shape"].sdf, bbox=(0, 0, 1, 1)), (0.8, 0.8), (0.3, 0.8), 1,
                         0.64),
}

pytestmark = pytest.mark.filterwarnings("error")


@pytest.fixture(params=sorted(DOMAINS))
def example(request: pytest.FixtureRequest):
    return DOMAINS[request.param]


def _near_boundary(domain: Domain, rng: np.random.Generator, n: int = 200) -> np.ndarray:
    """Points within 3 % of the diameter of the boundary, on both sides."""
    loops = np.concatenate(domain.boundary_loops(domain.diameter / 200))
    base = loops[rng.integers(len(loops), size=n)]
    return base + rng.uniform(-0.03, 0.03, size=(n, 2)) * domain.diameter


# --- the contract --------------------------------------------------------------------------


def test_is_a_domain(example) -> None:
    domain = example[0]
    assert isinstance(domain, Domain)
    assert domain.diameter > 0
    assert "object at 0x" not in repr(domain)


def test_sdf_sign_and_shape(example) -> None:
    domain, inside, outside = example[:3]
    d = domain.sdf(np.array([inside, outside, inside], dtype=float))
    assert d.shape == (3,)
    assert d.dtype == np.float64
    assert d[0] < 0 < d[1]
    assert d[0] == d[2]
    # A Domain is also its own sdf, and accepts a single point.
    assert np.array_equal(domain(np.array([inside])), d[:1])
    assert domain.sdf(inside).shape == (1,)
    assert domain.sdf(np.empty((0, 2))).shape == (0,)


def test_sdf_rejects_bad_shapes(example) -> None:
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        example[0].sdf(np.zeros((4, 3)))


def test_project_lands_on_boundary(example) -> None:
    domain = example[0]
    p = _near_boundary(domain, np.random.default_rng(1))
    q = domain.project(p)
    assert q.shape == p.shape
    assert np.abs(domain.sdf(q)).max() < 1e-8 * domain.diameter
    # Projection moves a point no further than it was from the boundary (plus slack for the
    # min/max distance bound of combinations, which underestimates).
    assert np.all(np.hypot(*(q - p).T) <= 1.5 * np.abs(domain.sdf(p)) + 1e-9 * domain.diameter)


def test_project_does_not_modify_input(example) -> None:
    domain = example[0]
    p = _near_boundary(domain, np.random.default_rng(2), n=20)
    before = p.copy()
    domain.project(p)
    assert np.array_equal(p, before)


def test_bbox_contains_boundary(example) -> None:
    domain = example[0]
    x0, y0, x1, y1 = domain.bbox
    assert x1 > x0 and y1 > y0
    loops = np.concatenate(domain.boundary_loops(domain.diameter / 100))
    slack = 1e-9 * domain.diameter
    assert loops[:, 0].min() >= x0 - slack and loops[:, 0].max() <= x1 + slack
    assert loops[:, 1].min() >= y0 - slack and loops[:, 1].max() <= y1 + slack


def test_boundary_loops_oriented_and_closed_up(example) -> None:
    domain, _, _, n_loops, area = example
    loops = domain.boundary_loops(domain.diameter / 200)
    assert len(loops) == n_loops
    signed = [_shoelace(loop) for loop in loops]
    # Outer boundary counter-clockwise (positive), holes clockwise: together the area.
    assert max(signed, key=abs) > 0
    assert sum(signed) == pytest.approx(area, rel=1e-2)
    for loop in loops:
        assert loop.ndim == 2 and loop.shape[1] == 2 and len(loop) >= 3
        assert np.abs(domain.sdf(loop)).max() < 1e-6 * domain.diameter


def test_corners_lie_on_boundary(example) -> None:
    domain = example[0]
    c = domain.corners()
    assert c.ndim == 2 and c.shape[1] == 2
    if len(c):
        assert np.abs(domain.sdf(c)).max() < 1e-6 * domain.diameter
        assert domain.on_boundary(c).all()


def test_set_operators_return_domains(example) -> None:
    domain = example[0]
    other = Circle((0, 0), 0.1)
    assert isinstance(domain | other, Union)
    assert isinstance(domain & other, Intersection)
    assert isinstance(domain - other, Difference)
    for combo in (domain | other, domain & other, domain - other):
        assert isinstance(combo, Domain)
    with pytest.raises(TypeError, match="cannot combine"):
        domain | 3  # noqa: B018


def test_set_operators_agree_with_point_membership(example) -> None:
    domain = example[0]
    other = Circle(domain.bbox[:2], 0.5 * domain.diameter)
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = domain.bbox
    p = rng.uniform([x0, y0], [x1, y1], size=(500, 2))
    a, b = domain.sdf(p) < 0, other.sdf(p) < 0
    assert np.array_equal((domain | other).sdf(p) < 0, a | b)
    assert np.array_equal((domain & other).sdf(p) < 0, a & b)
    assert np.array_equal((domain - other).sdf(p) < 0, a & ~(other.sdf(p) <= 0))


# --- primitives: exact figures -------------------------------------------------------------


def test_circle_is_exact() -> None:
    c = Circle((1, 2), 0.5)
    assert c.sdf(np.array([[1, 2], [2, 2]])) == pytest.approx([-0.5, 0.5])
    assert c.bbox == (0.5, 1.5, 1.5, 2.5)
    assert len(c.corners()) == 0
    # The centre projects somewhere on the circle, not to NaN.
    assert np.hypot(*(c.project(np.array([[1.0, 2.0]])) - [1, 2]).T) == pytest.approx(0.5)


def test_rectangle_corners_are_its_vertices() -> None:
    r = Rectangle((0, 0), (2, 1))
    expected = {(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (0.0, 1.0)}
    assert {tuple(c) for c in r.corners().tolist()} == expected
    assert r.sdf(np.array([[1, 0.5], [3, 2]])) == pytest.approx([-0.5, math.sqrt(2)])


def test_polygon_orientation_is_normalised() -> None:
    a, b = Polygon(ARROW), Polygon(ARROW[::-1])
    assert a.area == pytest.approx(b.area) and a.area > 0
    p = np.random.default_rng(4).uniform(-0.5, 2.5, size=(300, 2))
    assert np.allclose(a.sdf(p), b.sdf(p))


def test_polygon_reflex_vertex_is_a_corner() -> None:
    corners = {tuple(np.round(c, 12)) for c in Polygon(ARROW).corners().tolist()}
    assert (0.7, 1.0) in corners
    assert len(corners) == 4


def test_polygon_rejects_bow_tie() -> None:
    with pytest.raises(GeometryError, match="not simple"):
        Polygon([(0, 0), (2, 2), (2, 0), (0, 1)])
    # The symmetric bow-tie has zero signed area, and is refused too.
    with pytest.raises(GeometryError):
        Polygon([(0, 0), (1, 1), (1, 0), (0, 1)])


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Polygon([(0, 0), (1, 0)]), "at least 3"),
        (lambda: Polygon([(0, 0), (1, 0), (2, 0)]), "zero area"),
        (lambda: Polygon([(0, 0), (1, np.nan), (0, 1)]), "finite"),
        (lambda: Circle((0, 0), 0), "radius"),
        (lambda: Circle((0, 0), -1), "radius"),
        (lambda: Rectangle((0, 0), (0, 1)), "x0 < x1"),
        (lambda: Implicit(lambda p: p[:, 0], bbox=(0, 0, 0, 1)), "xmin < xmax"),
        (lambda: Implicit(lambda p: p[:, 0], bbox=(0, 1)), "four finite numbers"),
    ],
)
def test_invalid_geometry_is_refused(make, match: str) -> None:
    with pytest.raises(GeometryError, match=match):
        make()


def test_polygon_closing_vertex_is_dropped() -> None:
    p = Polygon([(0, 0), (1, 0), (0, 1), (0, 0)])
    assert len(p.vertices) == 3


# --- combinations ---------------------------------------------------------------------------


def _has_point(points: np.ndarray, target, tol: float = 1e-6) -> bool:
    return bool(np.hypot(*(np.asarray(points) - np.asarray(target, dtype=float)).T).min() < tol)


def test_l_shape_geometry_has_reentrant_corner() -> None:
    corners = CASES["l_shape"].geometry.corners()
    assert _has_point(corners, (0.6, 0.4))
    for c in [(0, 0), (1, 0), (1, 1), (0.6, 1), (0, 0.4)]:
        assert _has_point(corners, c)


def test_two_circles_and_square_has_crossing_points() -> None:
    corners = CASES["two_circles_and_square"].geometry.corners()
    assert _has_point(corners, (-0.3, 1.0))
    assert _has_point(corners, (1.0, 1.0 - math.sqrt(0.35)))
    for c in [(-1, -1), (1, -1), (-1, 1)]:
        assert _has_point(corners, c)


def test_csg_corners_include_crossings_of_two_discs() -> None:
    # Unit discs 1.5 apart cross at (0.75, +-sqrt(1 - 0.75^2)).
    corners = (Circle((0, 0), 1) | Circle((1.5, 0), 1)).corners()
    y = math.sqrt(1 - 0.75**2)
    assert len(corners) == 2
    assert _has_point(corners, (0.75, y), 1e-9) and _has_point(corners, (0.75, -y), 1e-9)


def test_csg_drops_corners_off_the_boundary() -> None:
    # The small square's corners are all inside the big one: the union has only 4 corners.
    u = Rectangle((0, 0), (2, 2)) | Rectangle((0.5, 0.5), (1, 1))
    assert len(u.corners()) == 4


def test_square_with_hole_corners() -> None:
    assert len(CASES["square_with_hole"].geometry.corners()) == 8


# --- implicit domains -----------------------------------------------------------------------


def test_implicit_finds_l_shape_corners_without_fixed_points() -> None:
    corners = Implicit(CASES["l_shape"].sdf, bbox=(0, 0, 1, 1)).corners()
    expected = CASES["l_shape"].fixed_points
    assert len(corners) == len(expected) == 6
    for c in expected:
        assert _has_point(corners, c, 1e-6), f"corner {tuple(c)} not found"


def test_implicit_square_corners() -> None:
    sq = Implicit(lambda p: np.max(np.abs(p), axis=1) - 1, bbox=(-1, -1, 1, 1))
    corners = sq.corners()
    assert len(corners) == 4
    for c in [(-1, -1), (1, -1), (1, 1), (-1, 1)]:
        assert _has_point(corners, c, 1e-6)


def test_implicit_smooth_boundary_has_no_corners() -> None:
    assert len(Implicit(_annulus, bbox=(-1, -1, 1, 1)).corners()) == 0


def test_implicit_uses_fixed_points_as_corners() -> None:
    case = CASES["square_with_hole"]
    corners = Implicit(case.sdf, bbox=case.bbox, fixed_points=case.fixed_points).corners()
    assert len(corners) == 8
    for c in case.fixed_points:
        assert _has_point(corners, c, 1e-12)


def test_l_shape_plain_sdf_has_one_loop() -> None:
    """The printed L-shape sdf is 0 along y = 0.4, 0.6 < x < 1, inside the domain: no boundary."""
    dom = Implicit(CASES["l_shape"].sdf, bbox=(0, 0, 1, 1))
    loops = dom.boundary_loops(0.01)
    assert len(loops) == 1
    assert _shoelace(loops[0]) == pytest.approx(0.64, rel=1e-3)
    # Points on the interior zero line are not on the boundary.
    line = np.array([[0.7, 0.4], [0.8, 0.4], [0.9, 0.4]])
    assert np.all(dom.sdf(line) == 0)
    assert not dom.on_boundary(line).any()


def test_implicit_wraps_bad_callables() -> None:
    with pytest.raises(GeometryError, match="shape"):
        Implicit(lambda p: np.zeros((len(p), 2)), bbox=(0, 0, 1, 1))
    with pytest.raises(GeometryError, match="not finite"):
        Implicit(lambda p: np.full(len(p), np.nan), bbox=(0, 0, 1, 1))
    with pytest.raises(TypeError, match="callable"):
        Implicit(3, bbox=(0, 0, 1, 1))


def test_empty_domain_in_box() -> None:
    dom = Implicit(lambda p: np.ones(len(p)), bbox=(-1, -1, 1, 1))
    with pytest.raises(GeometryError, match="empty"):
        dom.boundary_loops(0.05)


def test_bbox_missing_part_of_domain() -> None:
    dom = Implicit(lambda p: np.hypot(p[:, 0], p[:, 1]) - 1, bbox=(-0.5, -0.5, 0.5, 0.5))
    with pytest.raises(GeometryError, match="does not contain"):
        dom.boundary_loops(0.05)


@pytest.mark.parametrize("name", sorted(CASES))
def test_csg_projection_lands_on_the_boundary_near_corners(name: str) -> None:
    """Random points, and points scattered around every corner (inside and out), project onto
    the boundary: beyond a convex corner the foot is the corner itself."""
    g = CASES[name].geometry
    rng = np.random.default_rng(1)
    x0, y0, x1, y1 = g.bbox
    p = rng.uniform([x0 - 0.1, y0 - 0.1], [x1 + 0.1, y1 + 0.1], (4000, 2))
    c = g.corners()
    if len(c):
        p = np.concatenate([p, c[rng.integers(0, len(c), 2000)] + rng.normal(scale=0.01, size=(2000, 2))])
    foot = g.project(p)
    assert np.abs(g.sdf(foot)).max() < 2e-6 * g.diameter


def test_plain_projection_stacks_its_calls_to_d() -> None:
    """A plain d is asked once for the points and both gradient offsets, then once per
    Newton step (plus once for a stale gradient): its call, not its points, is the cost of a
    Python d on the few hundred nodes that slide at each smoothing step."""
    calls = []

    def ellipse(p: np.ndarray) -> np.ndarray:  # not a distance: Newton steps, not one
        calls.append(len(p))
        return np.hypot(p[:, 0] / 2.0, p[:, 1]) - 1.0

    domain = Implicit(ellipse, (-3, -2, 3, 2))
    calls.clear()
    rng = np.random.default_rng(5)
    ang = rng.uniform(0, 2 * np.pi, 200)
    p = np.stack([2.0 * np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.8, 1.2, (200, 1))
    q = domain.project(p)
    assert np.abs(ellipse(q)).max() < 1e-9
    assert calls[0] == 3 * len(p)  # d and both offsets at once
    # After that, per Newton step one call for d and at most one (stacked) for a gradient.
    assert len(calls) <= 1 + 2 * 8


# --- plain callables' corners ----------------------------------------------------------------


def test_plain_corners_near_fixed_points_are_the_fixed_points() -> None:
    """A fixed point at a corner replaces it (no refined copy beside it); corners without a
    fixed point are found and refined, on every loop."""
    from injmesh.geometry import as_domain

    case = CASES["square_with_hole"]
    given = as_domain(case.sdf, bbox=case.bbox, fixed_points=case.fixed_points).corners()
    assert len(given) == 8 and np.array_equal(given, case.fixed_points)
    found = as_domain(case.sdf, bbox=case.bbox).corners()
    assert len(found) == 8
    for c in case.fixed_points:
        assert _has_point(found, c, 1e-6)
    half = as_domain(case.sdf, bbox=case.bbox, fixed_points=case.fixed_points[::2]).corners()
    assert len(half) == 8
    for c in case.fixed_points:
        assert _has_point(half, c, 1e-6)


def test_corners_of_all_loops_refined_together_as_one_by_one() -> None:
    """One bisection over the corners of every loop gives each loop's own result, bit for bit."""
    from injmesh.geometry import as_domain
    from injmesh.geometry.tracing import corner_brackets, grid_spacing, refine_corners

    case = CASES["square_with_four_holes"]
    dom = as_domain(case.sdf, bbox=case.bbox)
    spacing = grid_spacing(dom.bbox, np.inf)
    loops = dom.boundary_loops(spacing)
    brackets = [corner_brackets(loop, spacing) for loop in loops]
    one_by_one = np.concatenate([refine_corners(dom, b[1], b[2]) for b in brackets])
    together = refine_corners(dom, np.concatenate([b[1] for b in brackets]),
                              np.concatenate([b[2] for b in brackets]))
    assert len(together) == 4 and np.array_equal(one_by_one, together)


def test_implicit_tracing_is_kept_per_spacing_and_handed_out_as_copies(monkeypatch) -> None:
    """``Implicit.boundary_loops`` keeps its last tracing (corners and Step 1 ask the same
    spacing): asked again it gives the same loops, which a caller may change freely."""
    from injmesh.geometry.tracing import trace_loops

    def ring(p):
        r = np.hypot(p[:, 0], p[:, 1])
        return np.maximum(r - 1.0, 0.4 - r)

    dom = Implicit(ring, bbox=(-1, -1, 1, 1))
    first = dom.boundary_loops(0.05)
    fresh = [dom.project(loop) for loop in trace_loops(dom.sdf, dom.bbox, 0.05)]
    assert len(first) == len(fresh) == 2
    assert all(np.array_equal(a, b) for a, b in zip(first, fresh, strict=True))
    first[0][:] = 0.0
    again = dom.boundary_loops(0.05)
    assert all(np.array_equal(a, b) for a, b in zip(again, fresh, strict=True))
    other = dom.boundary_loops(0.1)
    assert len(other[0]) < len(fresh[0])
    # Both tracings are kept: asked again, neither is traced anew.
    import injmesh.geometry.implicit as implicit

    monkeypatch.setattr(implicit, "trace_loops", None)
    assert all(np.array_equal(a, b) for a, b in zip(dom.boundary_loops(0.05), fresh, strict=True))
    assert all(np.array_equal(a, b) for a, b in zip(dom.boundary_loops(0.1), other, strict=True))
