"""Properties over random inputs (Hypothesis): random star-shaped polygons and uniform sizes."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import injmesh
from conftest import assert_valid_mesh
from injmesh import Polygon, Rectangle

SETTINGS = settings(
    max_examples=15,
    deadline=None,
    derandomize=True,  # the same examples on every run: a red test is reproducible
    suppress_health_check=[HealthCheck.too_slow],
)


@st.composite
def star_polygons(draw) -> np.ndarray:
    """Vertices at sorted angles around the origin with radii in [0.5, 1].

    Angular gaps are drawn in [1, 3] and normalised, so every gap is below pi: the polygon is
    star-shaped about the origin, hence simple.
    """
    n = draw(st.integers(min_value=5, max_value=10))
    gaps = np.array(draw(st.lists(st.floats(1.0, 3.0), min_size=n, max_size=n)))
    start = draw(st.floats(0.0, 2 * math.pi))
    angles = start + 2 * math.pi * np.cumsum(gaps) / gaps.sum()
    radii = np.array(draw(st.lists(st.floats(0.5, 1.0), min_size=n, max_size=n)))
    return np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)


def _polygon_area(v: np.ndarray) -> float:
    x, y = v[:, 0], v[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


@SETTINGS
@given(vertices=star_polygons(), h=st.floats(0.08, 0.3))
def test_random_star_polygon_meshes_validly(vertices: np.ndarray, h: float) -> None:
    poly = Polygon(vertices)
    mesh = injmesh.generate(poly, h)
    # Centroids inside, boundary nodes on the polygon (|d| < 1e-6 diam), CCW, conforming.
    assert_valid_mesh(mesh, poly)
    assert abs(mesh.areas().sum() - _polygon_area(vertices)) <= 0.01 * _polygon_area(vertices)
    # Every polygon vertex is a mesh node (the corners stay fixed).
    corners = poly.corners()
    for c in corners:
        assert np.hypot(*(mesh.points - c).T).min() < 1e-9


@SETTINGS
@given(
    w=st.floats(0.3, 3.0),
    aspect=st.floats(0.2, 1.0),
    h=st.floats(0.08, 0.3),
)
def test_random_rectangle_is_covered_exactly(w: float, aspect: float, h: float) -> None:
    rect = Rectangle((0, 0), (w, w * aspect))
    mesh = injmesh.generate(rect, h)
    assert_valid_mesh(mesh, rect)
    assert math.isclose(mesh.areas().sum(), w * w * aspect, rel_tol=1e-9)


@SETTINGS
@given(
    vertices=star_polygons(),
    centre=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)),
    base=st.floats(0.04, 0.1),
    slope=st.floats(0.0, 0.3),
)
def test_random_star_polygon_with_graded_size(
    vertices: np.ndarray, centre: tuple[float, float], base: float, slope: float
) -> None:
    """Graded h: the mesh is valid and conforms to its boundary (checked exactly by
    assert_valid_mesh), covers the polygon to 1 % (a vertex turning by less than CORNER_ANGLE
    is not a corner: the boundary treats it as a smooth curve sampled at h) and follows h."""
    poly = Polygon(vertices)
    cx, cy = centre

    def h(p: np.ndarray) -> np.ndarray:
        return base + slope * np.hypot(p[:, 0] - cx, p[:, 1] - cy)

    mesh = injmesh.generate(poly, h)
    assert_valid_mesh(mesh, poly)
    assert math.isclose(mesh.areas().sum(), _polygon_area(vertices), rel_tol=1e-2)
    assert mesh.size_report().relative < 0.2


def _cone(cx: float, cy: float, base: float, slope: float):
    return lambda p: base + slope * np.hypot(p[:, 0] - cx, p[:, 1] - cy)


def _random_graded_cases(count: int, seed: int):
    """Random star polygons (angles free: corners down to a few degrees), a third of them with
    a small hole, and steep graded sizes (slope up to 0.4): the regime where features approach
    the element size."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < count:
        n = int(rng.integers(3, 14))
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
        if np.max(np.diff(np.r_[ang, ang[0] + 2 * np.pi])) > 0.9 * np.pi:
            continue
        r = rng.uniform(0.4, 1.0, n)
        poly = Polygon(np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1))
        domain = poly - injmesh.Circle((0, 0), rng.uniform(0.05, 0.2)) if len(out) % 3 == 0 else poly
        cx, cy = rng.uniform(-0.5, 0.5, 2)
        base, slope = rng.uniform(0.02, 0.08), rng.uniform(0, 0.4)
        out.append((domain, _cone(cx, cy, base, slope)))
    return out


def test_random_graded_domains_never_fail_silently() -> None:
    """Every mesh is valid and conforming; anything short of that is reported as a warning
    (a feature left out, non-convergence, a lost segment), never returned silently."""
    import warnings

    from injmesh.quality import signed_areas

    silent = 0
    for domain, h in _random_graded_cases(30, seed=7):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            mesh = injmesh.generate(domain, h)
        assert np.all(signed_areas(mesh.points, mesh.triangles) > 0)
        conforming = bool(np.all(mesh.boundary_tags >= 0))
        if not caught:
            silent += not conforming
            # Conforming: the mesh covers exactly the region its boundary edges enclose.
            e = mesh.boundary_edges
            a, b = mesh.points[e[:, 0]], mesh.points[e[:, 1]]
            enclosed = 0.5 * np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])
            assert math.isclose(mesh.areas().sum(), enclosed, rel_tol=1e-9)
    assert silent == 0
