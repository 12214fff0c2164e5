"""Random shape families: simple, deterministic, holes inside, requested properties hold.

Simplicity is checked here by an independent brute-force test over all pairs of edges with an
exact orientation predicate (a float filter with a rational fallback), not by the generator's
own sweep.
"""

from __future__ import annotations

import json
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh import shapes
from injmesh.inputs import read_geojson, read_wkt

SMALL = {
    "star": {"n_holes": 2},
    "walk": {"n_holes": 1},
    "holes": {},
    "sharp": {},
    "neck": {"n_holes": 1},
    "duplicates": {},
    "coastline": {"n_vertices": 300, "island_vertices": 40, "n_islands": 2},
    "large": {"n_vertices": 600},
    "plates": {},
    "airfoil": {"n_points": 40},
}


def exact_orient(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Sign of the orientation of (a, b, c), exact: float with an error bound, else Fractions."""
    left = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
    right = (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    det = left - right
    sign = np.sign(det)
    # Shewchuk's static bound for orient2d (coordinate differences are exact only with care,
    # so the bound is taken generously).
    unsure = np.abs(det) <= 1e-14 * (np.abs(left) + np.abs(right))
    for k in np.flatnonzero(unsure):
        ax, ay, bx, by, cx, cy = (Fraction(float(v)) for v in (*a[k], *b[k], *c[k]))
        d = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        sign[k] = (d > 0) - (d < 0)
    return sign


def meets(p1, p2, q1, q2) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Whether closed segments p1 p2 and q1 q2 share at least one point (exact)."""
    o1, o2 = exact_orient(p1, p2, q1), exact_orient(p1, p2, q2)
    o3, o4 = exact_orient(q1, q2, p1), exact_orient(q1, q2, p2)

    def within(a, b, c):  # type: ignore[no-untyped-def]
        return np.all((np.minimum(a, b) <= c) & (c <= np.maximum(a, b)), axis=1)

    proper = (o1 * o2 < 0) & (o3 * o4 < 0)
    touch = ((o1 == 0) & within(p1, p2, q1)) | ((o2 == 0) & within(p1, p2, q2))
    touch |= ((o3 == 0) & within(q1, q2, p1)) | ((o4 == 0) & within(q1, q2, p2))
    return proper | touch


def crossing_pairs(rings: list[np.ndarray]) -> int:
    """Number of pairs of non-adjacent edges (over all rings) that meet: brute force."""
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    rid = np.concatenate([np.full(len(r), k) for k, r in enumerate(rings)])
    loc = np.concatenate([np.arange(len(r)) for r in rings])
    size = np.concatenate([np.full(len(r), len(r)) for r in rings])
    i, j = np.triu_indices(len(a), k=1)
    adjacent = (rid[i] == rid[j]) & (((loc[j] - loc[i]) % size[i] == 1) | ((loc[i] - loc[j]) % size[i] == 1))
    i, j = i[~adjacent], j[~adjacent]
    total = 0
    for s in range(0, len(i), 500_000):
        ii, jj = i[s : s + 500_000], j[s : s + 500_000]
        total += int(meets(a[ii], b[ii], a[jj], b[jj]).sum())
    # Adjacent edges may only share their common vertex: no fold back (collinear overlap).
    for r in rings:
        u, v, w = np.roll(r, 1, axis=0), r, np.roll(r, -1, axis=0)
        back = (exact_orient(u, v, w) == 0) & (np.einsum("ij,ij->i", u - v, w - v) > 0)
        total += int(back.sum())
    return total


def inside(points: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """Even-odd test of many points against one ring."""
    a, b = ring[None], np.roll(ring, -1, axis=0)[None]
    x, y = points[:, None, 0], points[:, None, 1]
    straddle = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    return np.count_nonzero(straddle & (xc > x), axis=1) % 2 == 1


def area(r: np.ndarray) -> float:
    x, y = r[:, 0], r[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def assert_valid(s: shapes.Shape) -> None:
    for r in s.rings:
        assert r.dtype == np.float64 and r.ndim == 2 and r.shape[1] == 2 and len(r) >= 3
        assert np.all(np.isfinite(r))
        assert not np.array_equal(r[0], r[-1]), "rings are not closed by a repeated vertex"
    assert area(s.shell) > 0
    assert all(area(h) < 0 for h in s.holes)
    assert all(area(i) > 0 for i in s.islands)
    assert crossing_pairs(s.rings) == 0
    for k, h in enumerate(s.holes):
        assert inside(h, s.shell).all()
        for m, g in enumerate(s.holes):
            if m != k:
                assert not inside(h, g).any()
    for k, isl in enumerate(s.islands):
        assert not inside(isl, s.shell).any() and not inside(s.shell, isl).any()
        for m, g in enumerate(s.islands):
            if m != k:
                assert not inside(isl, g).any()
    assert shapes.shape_problems(s.shell, s.holes, s.islands) == []


@pytest.mark.parametrize("name", sorted(SMALL))
def test_every_family_is_simple_and_deterministic(name: str) -> None:
    make = shapes.FAMILIES[name]
    for seed in (0, 1, 7):
        s = make(seed, **SMALL[name])
        assert_valid(s)
        assert s.family == name and s.seed == seed and s.size > 0
        again = make(seed, **SMALL[name])
        for r1, r2 in zip(s.rings, again.rings, strict=True):
            assert r1.tobytes() == r2.tobytes()
    def blob(x: shapes.Shape) -> bytes:
        return b"".join(r.tobytes() for r in x.rings)

    assert blob(make(0, **SMALL[name])) != blob(make(1, **SMALL[name]))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n_holes=st.integers(0, 3), kind=st.sampled_from(["star", "walk"]))
def test_random_seeds_give_valid_shapes_with_the_holes_asked(seed: int, n_holes: int, kind: str) -> None:
    s = shapes.FAMILIES[kind](seed, n_holes=n_holes)
    assert len(s.holes) == n_holes
    assert_valid(s)


def test_walk_outlines_are_not_all_star_shaped() -> None:
    # A ring is star-shaped about its centroid only if every edge is seen counter-clockwise.
    def star_about_centroid(r: np.ndarray) -> bool:
        c = r.mean(axis=0)
        a, b = r - c, np.roll(r, -1, axis=0) - c
        return bool(np.all(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0] > 0))

    rings = [s.shell for s in shapes.family("walk", 10, seed=0)]
    assert sum(not star_about_centroid(r) for r in rings) >= 8


@pytest.mark.parametrize("min_angle", [5.0, 12.0, 29.0])
def test_sharp_vertices_reach_the_requested_angle(min_angle: float) -> None:
    for s in shapes.family("sharp", 5, seed=3, min_angle=min_angle):
        angles = shapes.interior_angles(s.shell)
        assert angles.min() == pytest.approx(min_angle, abs=1e-6)
        assert s.min_angle == pytest.approx(min_angle, abs=1e-6)
        assert np.count_nonzero(angles < 30.0 + 1e-9) >= 1
        assert_valid(s)


def test_interior_angles_of_a_notched_square() -> None:
    ring = np.array([(0, 0), (2, 0), (2, 2), (1, 2), (1, 1), (0, 1)], dtype=float)
    assert shapes.interior_angles(ring).tolist() == [90.0, 90.0, 90.0, 90.0, 270.0, 90.0]
    # Seen from the domain around a clockwise hole, a convex hole corner is reflex.
    assert shapes.interior_angles(ring[::-1]).tolist() == [270.0, 90.0, 270.0, 270.0, 270.0, 270.0]


@pytest.mark.parametrize("width", [0.02, 0.08])
def test_necks_are_narrower_than_the_width_asked(width: float) -> None:
    for s in shapes.family("neck", 5, seed=11, width=width):
        # The channel crosses x = 0: exactly two boundary crossings, closer than width.
        a, b = s.shell, np.roll(s.shell, -1, axis=0)
        cross = (a[:, 0] < 0) != (b[:, 0] < 0)
        t = -a[cross, 0] / (b[cross, 0] - a[cross, 0])
        ys = a[cross, 1] + t * (b[cross, 1] - a[cross, 1])
        assert len(ys) == 2
        assert 0 < abs(ys[0] - ys[1]) < width
        assert 0.3 * 0.9 * width < s.params["neck_width"] < width
        assert s.size == width
        assert_valid(s)


def test_near_duplicate_vertices_are_gap_apart() -> None:
    for s in shapes.family("duplicates", 6, seed=5, gap=1e-7):
        v = s.shell
        step = np.hypot(*(np.roll(v, -1, axis=0) - v).T)
        diag = np.hypot(*np.ptp(v, axis=0))
        close = step < 1e-5 * diag
        assert 1 <= close.sum() <= 3 and close.sum() == s.params["count"]
        assert np.allclose(step[close] / diag, 1e-7, rtol=1e-3)
        assert_valid(s)


def test_coastline_straits_are_narrower_than_h() -> None:
    h = 0.04
    s = shapes.coastline(2, n_vertices=400, island_vertices=40, n_islands=3, strait=h)
    assert len(s.shell) == 400 and len(s.islands) == 3 and not s.holes
    assert_valid(s)
    for isl in s.islands:
        gap = min(
            float(np.min(shapes.segment_distances(
                np.repeat(isl, len(s.shell), axis=0), np.repeat(isl, len(s.shell), axis=0),
                np.tile(s.shell, (len(isl), 1)), np.tile(np.roll(s.shell, -1, axis=0), (len(isl), 1)),
            ))),
            1.0,
        )
        assert 0 < gap < h
    sea = shapes.coastline(2, n_vertices=400, island_vertices=40, n_islands=3, strait=h, water=True)
    assert len(sea.holes) == 4 and not sea.islands
    assert sea.holes[0].tobytes() == s.shell[::-1].tobytes()
    assert_valid(sea)


def test_large_outline_has_exactly_the_vertices_asked() -> None:
    s = shapes.large(0)
    assert len(s.shell) == 20_000 and not s.holes
    assert shapes.shape_problems(s.shell) == []
    small = shapes.large(0, n_vertices=1500)
    assert len(small.shell) == 1500
    assert_valid(small)


def test_plate_holes_keep_their_clearance() -> None:
    for s in shapes.family("plates", 4, seed=0, clearance=0.05):
        assert s.shell.tolist() == [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]]
        assert 2 <= len(s.holes) <= 8
        for k, h in enumerate(s.holes):
            assert h[:, 0].min() >= 0.05 - 1e-12 and h[:, 0].max() <= 1.95 + 1e-12
            assert h[:, 1].min() >= 0.05 - 1e-12 and h[:, 1].max() <= 0.95 + 1e-12
            for g in s.holes[k + 1 :]:
                d = np.hypot(*(h[:, None, :] - g[None, :, :]).transpose(2, 0, 1)).min()
                assert d >= 0.05 - 1e-12


def test_naca_profiles() -> None:
    p = shapes.naca4("0012", 200)
    assert p[:, 0].min() == pytest.approx(0.0, abs=1e-12) and p[:, 0].max() == pytest.approx(1.0)
    assert np.ptp(p[:, 1]) == pytest.approx(0.12, rel=0.01)
    assert area(p) > 0
    blunt = shapes.naca4("2412", 60, closed=False)
    thickness = np.hypot(*(blunt[0] - blunt[-1]))  # the edge closing the ring
    assert 0.001 < thickness < 0.005  # a thin blunt trailing edge
    s = shapes.airfoil(4, code="4415", closed=True, angle=10.0)
    assert s.params == {"code": "4415", "closed": True, "angle": 10.0, "attempts": 1}
    # The sharp trailing edge: the domain's angle there is reflex and close to 360 degrees.
    assert shapes.interior_angles(s.holes[0]).max() > 330
    with pytest.raises(shapes.ShapeError, match="four digits"):
        shapes.naca4("24120")


def test_geojson_and_wkt_are_plain_closed_and_read_back() -> None:
    s = shapes.star(1, n_holes=2)
    g = s.to_geojson()
    assert g["type"] == "Polygon" and len(g["coordinates"]) == 3
    assert json.loads(json.dumps(g)) == g  # lists and floats only
    for ring, arr in zip(g["coordinates"], s.rings, strict=True):
        assert isinstance(ring, list) and isinstance(ring[0], list)
        assert ring[0] == ring[-1] and np.array_equal(np.array(ring[:-1]), arr)
    w = s.to_wkt()
    nums = np.array([float(x) for x in re.findall(r"-?[\d.]+(?:e-?\d+)?", w)])
    assert np.array_equal(nums[: 2 * len(s.shell)].reshape(-1, 2), s.shell)  # round-trip exact
    assert shapes.to_geojson(s.shell, s.holes) == g and shapes.to_wkt(s.shell, s.holes) == w
    centre = s.holes[0].mean(axis=0, keepdims=True)
    for dom in (read_geojson(g), read_wkt(w), s.domain()):
        assert dom.sdf(centre)[0] > 0  # inside a hole: outside the domain
        assert np.abs(dom.sdf(s.shell)).max() < 1e-9
    coast = shapes.coastline(0, n_vertices=200, island_vertices=30, n_islands=2)
    assert coast.to_geojson()["type"] == "MultiPolygon" and len(coast.to_geojson()["coordinates"]) == 3
    assert coast.to_wkt().startswith("MULTIPOLYGON ((")
    assert np.abs(read_wkt(coast.to_wkt()).sdf(coast.islands[1]) ).max() < 1e-9


def test_shape_problems_names_each_defect() -> None:
    square = [(0, 0), (1, 0), (1, 1), (0, 1)]
    assert shapes.shape_problems(square) == []
    # The tests' own brute-force checker sees the same defects.
    sq = np.array(square, dtype=float)
    assert crossing_pairs([sq]) == 0 and crossing_pairs([sq[[0, 2, 1, 3]]]) == 1
    assert crossing_pairs([sq, np.array([(1.0, 0.5), (1.5, 0.2), (1.5, 0.8)])]) == 2
    assert "not counter-clockwise" in shapes.shape_problems(square[::-1])[0]
    bowtie = shapes.shape_problems([(0, 0), (1, 1), (1, 0), (0, 1)])
    assert any("cross or touch" in p for p in bowtie)
    touching = shapes.shape_problems([(0, 0), (2, 0), (2, 2), (1, 0), (0, 2)])
    assert any("cross or touch" in p for p in touching)
    hole = [(0.2, 0.2), (0.2, 0.4), (0.4, 0.2)]
    assert shapes.shape_problems(square, [hole]) == []
    assert "not clockwise" in shapes.shape_problems(square, [hole[::-1]])[0]
    outside = [(2.2, 0.2), (2.2, 0.4), (2.4, 0.2)]
    assert shapes.shape_problems(square, [outside]) == ["hole 0: not inside the shell"]
    nested = [(0.1, 0.1), (0.1, 0.8), (0.8, 0.1)]
    assert "hole 1: inside hole 0" in shapes.shape_problems(square, [nested, hole])
    assert shapes.shape_problems(square, islands=[[(0.2, 0.2), (0.4, 0.2), (0.2, 0.4)]]) == [
        "island 0: overlaps the shell"
    ]
    spike = shapes.shape_problems([(0, 0), (1, 0), (2, 0), (1, 0.0), (1, 1)])
    assert spike  # an edge folding back onto its neighbour
    assert "needs shape" in shapes.shape_problems([(0, 0), (1, 0)])[0]


def test_family_iterates_over_consecutive_seeds_and_rejects_bad_arguments(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    got = list(shapes.family("star", 3, seed=5, n_holes=1))
    assert [s.seed for s in got] == [5, 6, 7]
    assert got[1].shell.tobytes() == shapes.star(6, n_holes=1).shell.tobytes()
    with pytest.raises(shapes.ShapeError, match="unknown shape family"):
        next(shapes.family("blob", 1))
    with pytest.raises(shapes.ShapeError, match="seed"):
        shapes.star(-1)
    with pytest.raises(shapes.ShapeError, match="min_angle"):
        shapes.sharp(0, min_angle=0.0)
    monkeypatch.setattr(shapes, "MAX_ATTEMPTS", 5)
    with pytest.raises(shapes.ShapeError, match="no valid shape in 5 attempts"):
        shapes.star(0, n_holes=3, hole_radius=(0.9, 1.0))
    assert issubclass(shapes.ShapeError, ValueError)
