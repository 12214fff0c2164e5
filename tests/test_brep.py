"""The flat boundary representation: exact distance, sign, projection and corners against brute
force; polygons with holes; far offsets and tiny scales; the simplicity sweep at every size."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from injmesh import GeometryError, Polygon

SETTINGS = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)


def _star(rng: np.random.Generator, n: int, r0: float = 0.3, r1: float = 1.0) -> np.ndarray:
    gaps = rng.uniform(1.0, 3.0, n)
    ang = 2 * np.pi * np.cumsum(gaps) / gaps.sum()
    r = rng.uniform(r0, r1, n)
    return np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1)


def _brute(rings: list[np.ndarray], q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distance, nearest point (every edge tried) and even-odd inside flag, in plain NumPy."""
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    ab = b - a
    t = np.clip(np.einsum("nmk,mk->nm", q[:, None, :] - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    foot = a + t[..., None] * ab
    d2 = np.sum((q[:, None, :] - foot) ** 2, axis=2)
    k = np.argmin(d2, axis=1)
    rows = np.arange(len(q))
    y = q[:, None, 1]
    crosses = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xint = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    inside = np.count_nonzero(crosses & (q[:, None, 0] < xint), axis=1) % 2 == 1
    return np.sqrt(d2[rows, k]), foot[rows, k], inside


def _check_against_brute(poly: Polygon, rings: list[np.ndarray], q: np.ndarray, scale: float) -> None:
    dist, _, inside = _brute(rings, q)
    d = poly.sdf(q)
    assert np.all(np.abs(np.abs(d) - dist) <= 1e-12 * scale + 1e-12 * dist)
    clear = dist > 1e-9 * scale  # on the boundary either sign is right
    assert np.array_equal(d[clear] < 0, inside[clear])
    foot = poly.project(q)
    # The foot is a boundary point at the nearest distance.
    assert np.all(np.abs(np.hypot(*(foot - q).T) - dist) <= 1e-12 * scale + 1e-12 * dist)
    assert _brute(rings, foot)[0].max() <= 1e-12 * scale


@pytest.mark.parametrize("n", [3, 4, 7, 100, 1000])
def test_distance_sign_and_foot_match_brute_force(n: int) -> None:
    rng = np.random.default_rng(n)
    v = _star(rng, n)
    poly = Polygon(v)
    mid = 0.5 * (v + np.roll(v, -1, axis=0))
    q = np.concatenate([rng.uniform(-1.3, 1.3, (2000, 2)), v, mid, 1.5 * v, 0.999 * v, 1.001 * mid])
    _check_against_brute(poly, [v], q, 1.0)


@SETTINGS
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(3, 40),
    scale=st.sampled_from([1e-8, 1e-3, 1.0, 1e3, 1e6]),
    offset=st.sampled_from([0.0, 5e5, -3.3e6, 1e9]),
)
def test_random_polygons_at_any_scale_and_offset(seed: int, n: int, scale: float, offset: float) -> None:
    """sdf sign against an even-odd reference, |sdf| against brute-force distance, feet on the
    boundary, and invariance: d(offset + s p) = s d(p) to rounding of the coordinates."""
    assume(offset == 0.0 or scale >= 1e-6 * abs(offset))  # representable: 1e-10 relative at least
    rng = np.random.default_rng(seed)
    v = _star(rng, n)
    base = Polygon(v)
    q = np.concatenate([rng.uniform(-1.3, 1.3, (300, 2)), v * rng.uniform(0.9, 1.1, (n, 1))])
    shift = np.array([offset, -0.5 * offset])
    moved = Polygon(shift + scale * v)
    assert len(moved.vertices) == n
    assert moved.area == pytest.approx(scale * scale * base.area, rel=1e-6 if offset else 1e-12)
    # Coordinates far from the origin carry an absolute rounding of eps * |offset|.
    slack = 4e-16 * (abs(offset) + scale)
    d_moved = moved.sdf(shift + scale * q)
    d_base = base.sdf(q)
    assert np.all(np.abs(d_moved - scale * d_base) <= 4 * slack)
    if offset == 0.0:
        _check_against_brute(moved, [scale * v], scale * q, scale)


def test_polygon_with_holes_matches_brute_force() -> None:
    shell = np.array([(0, 0), (4, 0), (4, 3), (0, 3)], float)
    h1 = np.array([(1, 1), (1.5, 1), (1.5, 2), (1, 2)], float)
    h2 = np.array([(2.5, 0.5), (3.5, 0.5), (3, 2.5)], float)
    poly = Polygon(shell, holes=[h1, h2])
    assert poly.area == pytest.approx(12 - 0.5 - 1.0)
    rings = poly.boundary_loops(0.1)
    assert len(rings) == 3
    areas = [0.5 * float(np.dot(r[:, 0], np.roll(r[:, 1], -1)) - np.dot(r[:, 1], np.roll(r[:, 0], -1)))
             for r in rings]
    assert areas[0] > 0 and areas[1] < 0 and areas[2] < 0  # domain on the left
    rng = np.random.default_rng(5)
    q = rng.uniform(-0.5, 4.5, (3000, 2))
    _check_against_brute(poly, [shell, h1, h2], q, 5.0)
    assert len(poly.corners()) == 11


def test_from_rings_nests_islands_in_lakes() -> None:
    outer = np.array([(0, 0), (10, 0), (10, 10), (0, 10)], float)
    lake = np.array([(2, 2), (8, 2), (8, 8), (2, 8)], float)[::-1]
    island = np.array([(4, 4), (6, 4), (6, 6), (4, 6)], float)
    other = np.array([(12, 0), (14, 0), (13, 2)], float)
    multi = Polygon.from_rings([lake, island, outer, other])  # any order, any orientation
    assert multi.area == pytest.approx(100 - 36 + 4 + 2)
    d = multi.sdf(np.array([[1, 5], [3, 5], [5, 5], [13, 1], [11, 5]], float))
    assert list(d < 0) == [True, False, True, True, False]


@pytest.mark.parametrize(
    ("shell", "holes", "match"),
    [
        ([(0, 0), (2, 2), (2, 0), (0, 1)], None, r"edge 0 of the shell \(0, 0\) to \(2, 2\) meets edge 2"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(3, 1), (5, 1), (5, 2), (3, 2)]], "meets .* of the hole 0"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (2, 1), (2, 2), (1, 2)], [(1.5, 1.5), (3, 1.5), (3, 3)]],
         "hole 0 .* meets .* hole 1"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(5, 1), (6, 1), (6, 2)]], "hole 0 lies outside the shell"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (3, 1), (3, 3), (1, 3)], [(1.5, 1.5), (2, 1.5), (2, 2)]],
         "hole 1 lies inside hole 0"),
        ([(0, 0), (4, 0), (4, 4), (0, 4)], [[(0, 0), (1, 1), (1, 2)]], "not simple"),  # touches the shell
        ([(0, 0), (2, 0), (1, 0), (1, 1)], None, "not simple"),  # edges fold back onto each other
    ],
)
def test_rings_that_meet_are_refused(shell, holes, match: str) -> None:
    with pytest.raises(GeometryError, match=match):
        Polygon(shell, holes=holes)


@pytest.mark.parametrize("n", [10, 5000, 20000])
def test_self_intersection_found_at_every_size(n: int) -> None:
    """A star outline whose two vertices are swapped crosses itself: found at any size, and the
    error names both edges with their coordinates."""
    rng = np.random.default_rng(n)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    v = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.9, 1.0, (n, 1))
    Polygon(v)  # simple
    k = n // 3
    bad = v.copy()
    bad[[k, k + 2]] = bad[[k + 2, k]]
    pattern = r"not simple: edge \d+ of the shell \(.*\) to \(.*\) meets edge \d+"
    with pytest.raises(GeometryError, match=pattern):
        Polygon(bad)


def test_touching_vertex_is_refused() -> None:
    # A vertex of the ring lies on a non-adjacent edge.
    with pytest.raises(GeometryError, match="not simple"):
        Polygon([(0, 0), (4, 0), (4, 2), (2, 0), (0, 2)])


def test_closing_vertex_kept_in_utm_coordinates() -> None:
    """A last vertex 30 m from the first at x ~ 5e5 is a vertex, not a repeated closing one."""
    ring = np.array([(500000.0, 4000000.0), (500100.0, 4000000.0), (500100.0, 4000100.0),
                     (500000.0, 4000030.0)])
    assert len(Polygon(ring).vertices) == 4
    closed = np.concatenate([ring, ring[:1]])
    assert len(Polygon(closed).vertices) == 4


def test_tiny_square_keeps_its_four_vertices() -> None:
    sq = 1e-8 * np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)
    poly = Polygon(sq)
    assert len(poly.vertices) == 4
    assert poly.area == pytest.approx(1e-16)
    assert len(poly.corners()) == 4
    assert poly.sdf(np.array([[0.5e-8, 0.5e-8]]))[0] == pytest.approx(-0.5e-8)


def test_far_offset_polygon_is_accepted_and_exact() -> None:
    sq = 1e9 + np.array([(0, 0), (1, 0), (1, 1), (0, 1)], float)
    poly = Polygon(sq)
    assert poly.area == pytest.approx(1.0)
    d = poly.sdf(np.array([[1e9 + 0.5, 1e9 + 0.25], [1e9 + 2, 1e9 + 0.5]]))
    assert d == pytest.approx([-0.25, 1.0])


def test_corners_at_any_angle() -> None:
    """Every vertex turning by more than CORNER_ANGLE is a corner, and only those."""
    tips = [(0, 0), (1, 0), (1, 1), (0.5, 1.02), (0, 1)]  # (0.5, 1.02) turns ~4.6 degrees
    c = Polygon(tips).corners()
    assert len(c) == 4
    assert not np.any(np.all(np.isclose(c, [0.5, 1.02]), axis=1))
    needle = [(0, 0), (1, 0.02), (0, 0.04)]  # a 2.3-degree tip
    assert len(Polygon(needle).corners()) == 3


def test_gradient_is_unit_and_points_away_from_the_foot() -> None:
    poly = Polygon(_star(np.random.default_rng(9), 12))
    q = np.random.default_rng(10).uniform(-1.2, 1.2, (500, 2))
    g = poly.gradient(q)
    assert np.allclose(np.hypot(*g.T), 1.0)
    d = poly.sdf(q)
    step = q + 1e-6 * g
    assert np.all(poly.sdf(step) - d > 0.5e-6)


def test_queries_are_deterministic() -> None:
    poly = Polygon(_star(np.random.default_rng(11), 300))
    q = np.random.default_rng(12).uniform(-1.2, 1.2, (4000, 2))
    a, b = poly.project(q), poly.project(q[::-1])[::-1]
    assert np.array_equal(poly.sdf(q), poly.sdf(q.copy()))
    assert np.array_equal(np.hypot(*(a - q).T), np.hypot(*(b - q).T))


def test_polygon_math_circle_area() -> None:
    n = 4096
    ang = np.linspace(0, 2 * math.pi, n, endpoint=False)
    poly = Polygon(np.stack([np.cos(ang), np.sin(ang)], axis=1))
    assert poly.area == pytest.approx(0.5 * n * math.sin(2 * math.pi / n))


def _brute_simple(rings: list[np.ndarray]) -> bool:
    """O(n^2) reference: no two edges meet except consecutive ones at their shared vertex
    (without folding back), with exact rational arithmetic on small integer coordinates."""
    from fractions import Fraction

    edges = []
    for r, ring in enumerate(rings):
        n = len(ring)
        for k in range(n):
            edges.append((r, k, n, tuple(map(Fraction, ring[k])), tuple(map(Fraction, ring[(k + 1) % n]))))

    def orient(a, b, c) -> int:
        d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        return (d > 0) - (d < 0)

    def on(a, b, p) -> bool:
        return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])

    def meet(e, f) -> bool:
        a, b, c, d = e[3], e[4], f[3], f[4]
        o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
        if o1 * o2 < 0 and o3 * o4 < 0:
            return True
        return ((o1 == 0 and on(a, b, c)) or (o2 == 0 and on(a, b, d)) or (o3 == 0 and on(c, d, a))
                or (o4 == 0 and on(c, d, b)))

    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            e, f = edges[i], edges[j]
            if e[0] == f[0] and ((e[1] + 1) % e[2] == f[1] or (f[1] + 1) % f[2] == e[1]):
                if e[2] == 2:
                    return False
                first, second = (e, f) if (e[1] + 1) % e[2] == f[1] else (f, e)
                p, v, q = first[3], first[4], second[4]
                if orient(p, v, q) == 0 and (p[0] - v[0]) * (q[0] - v[0]) + (p[1] - v[1]) * (q[1] - v[1]) > 0:
                    return False
                continue
            if meet(e, f):
                return False
    return True


@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    rings=st.lists(
        st.lists(st.tuples(st.integers(0, 5), st.integers(0, 5)), min_size=3, max_size=9),
        min_size=1,
        max_size=3,
    )
)
def test_simplicity_sweep_matches_brute_force_on_a_grid(rings) -> None:
    """Rings on a 6x6 integer grid: collinear edges, vertical edges, shared vertices, touching
    and overlapping edges everywhere.  The sweep flags exactly the rings brute force flags."""
    from injmesh.geometry.primitives import _check_rings

    arrays = []
    for ring in rings:
        v = np.array(ring, dtype=float)
        keep = np.any(v != np.roll(v, -1, axis=0), axis=1)
        v = v[keep]
        assume(len(v) >= 3)
        arrays.append(v)
    expected = _brute_simple(arrays)
    try:
        _check_rings(arrays, [f"ring {k}" for k in range(len(arrays))], np.zeros(2))
        found = True
    except GeometryError:
        found = False
    assert found == expected


def test_compiled_callers_query_through_kernel_data() -> None:
    """Kernels of other stages can query the boundary per point from inside their own loops."""
    import numba

    from injmesh.kernels import brep as kb

    @numba.njit
    def signed_distances(q, g):  # type: ignore[no-untyped-def]
        stack = np.empty(2 * kb._STACK)
        tie_j = np.empty(kb._TIES, dtype=np.int64)
        tie_w = np.empty(kb._TIES, dtype=np.int64)
        out = np.empty(len(q))
        hint = -1
        for i in range(len(q)):
            d, _, _, _, hint = kb.nearest_point(q[i, 0], q[i, 1], hint, g, stack, tie_j, tie_w)
            out[i] = d
        return out

    dom = Polygon(_star(np.random.default_rng(13), 50), holes=[0.1 * _star(np.random.default_rng(14), 5)])
    q = np.random.default_rng(15).uniform(-1.2, 1.2, (1000, 2))
    origin, g = dom.kernel_data()
    assert np.array_equal(signed_distances(q - origin, g), dom.sdf(q))
