"""Compiled loops over outlines (kernels.outline) against the NumPy/Python code they replaced."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from injmesh import Circle, Polygon, Rectangle, shapes
from injmesh.geometry.primitives import _clean_ring
from injmesh.kernels.outline import facing_walls, merge_close
from injmesh.sizing.features import thick_everywhere


def _merge_reference(v: np.ndarray, tolerance: float) -> list[int]:
    """The Python walk ``Polygon.cleaned`` used before the kernel."""
    keep = [0]
    for i in range(1, len(v)):
        if np.hypot(*(v[i] - v[keep[-1]])) >= tolerance:
            keep.append(i)
    while len(keep) > 1 and np.hypot(*(v[keep[-1]] - v[keep[0]])) < tolerance:
        keep.pop()
    return keep


def _rings(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(40):
        n = int(rng.integers(1, 40))
        v = rng.random((n, 2))
        # Runs of near-duplicates, and the ring's end close to its start.
        v = np.repeat(v, rng.integers(1, 4, n), axis=0)
        v = v + 1e-3 * rng.standard_normal(v.shape)
        out.append(np.ascontiguousarray(v))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_merge_close_matches_the_python_walk(seed: int) -> None:
    for v in _rings(seed):
        for tolerance in (0.0, 1e-4, 2e-3, 0.05, 0.5, 10.0):
            got = merge_close(v, tolerance)
            assert got.tolist() == _merge_reference(v, tolerance)
            # Invariants: increasing, starts at 0, consecutive kept vertices at least tolerance
            # apart, and so are the last and the first.
            assert got[0] == 0 and np.all(np.diff(got) > 0)
            if len(got) > 1:
                kept = v[got]
                assert np.all(np.hypot(*np.diff(kept, axis=0).T) >= tolerance)
                assert np.hypot(*(kept[-1] - kept[0])) >= tolerance


def test_clean_ring_counts_on_a_detailed_outline() -> None:
    ring = shapes.large(0, n_vertices=2000).rings[0]
    out, merged, spikes = _clean_ring(ring, 1e-3)
    assert merged + spikes == len(ring) - len(out) > 0
    keep = merge_close(np.ascontiguousarray(out), 1e-3)
    assert len(keep) == len(out)  # nothing left to merge


def _thick_reference(v, prv, seg, seg_len, v_n, seg_n, radius, width, back_to_back, cos):
    """The NumPy body ``thick_everywhere`` had before the kernel: every pair within radius."""
    pairs = cKDTree(v).query_pairs(radius, output_type="ndarray")
    if not len(pairs):
        return False, set()
    a = np.concatenate([pairs[:, 0], pairs[:, 1]])
    b = np.concatenate([pairs[:, 1], pairs[:, 0]])
    a = np.concatenate([a, a])
    s = np.concatenate([b, prv[b]])
    own = (s == a) | (s == prv[a])
    a, s = a[~own], s[~own]
    ab = seg[s]
    t = np.clip(np.einsum("kj,kj->k", v[a] - v[s], ab) / np.maximum(seg_len[s] ** 2, np.finfo(float).tiny),
                0.0, 1.0)
    foot = v[s] + t[:, None] * ab
    gap = foot - v[a]
    dist = np.hypot(*gap.T)
    if back_to_back > 0:
        near = (dist > 0) & (dist < back_to_back)
        e = gap[near] / dist[near][:, None]
        behind = ((np.einsum("kj,kj->k", e, v_n[a[near]]) < -cos)
                  & (np.einsum("kj,kj->k", e, seg_n[s[near]]) > cos))
        if behind.any():
            return True, set()
    close = (dist > 0) & (dist < width)
    e = gap[close] / dist[close][:, None]
    facing = ((np.einsum("kj,kj->k", e, v_n[a[close]]) > cos)
              & (-np.einsum("kj,kj->k", e, seg_n[s[close]]) > cos))
    found = {(int(i), float(x), float(y), float(d)) for i, (x, y), d in
             zip(a[close][facing], foot[close][facing], dist[close][facing], strict=True)}
    return False, found


def _walls(v: np.ndarray):
    from injmesh.sizing.features import wall_frames

    n = len(v)
    idx = np.arange(n)
    nxt, prv = (idx + 1) % n, (idx - 1) % n
    seg, seg_len, v_n, seg_n = wall_frames(v, nxt, prv)
    return v, prv, seg, seg_len, v_n, seg_n


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_facing_walls_matches_the_numpy_pairs(seed: int) -> None:
    ring = shapes.coastline(seed, n_vertices=300, n_islands=0, strait=0.05).rings[0]
    args = _walls(np.ascontiguousarray(ring, dtype=float))
    cos = math.cos(math.radians(40.0))
    for width in (0.01, 0.05, 0.2):
        for back in (0.0, 0.02):
            radius = max(width, back) * 1.25
            behind, a, foot, dist = facing_walls(*args, radius, width, back, cos, False)
            ref_behind, ref = _thick_reference(*args, radius, width, back, cos)
            assert behind == ref_behind
            got = {(int(i), float(x), float(y), float(d)) for i, (x, y), d in zip(a, foot, dist, strict=True)}
            assert got == ref
            # Stopping at the first facing pair finds one exactly when there are any.
            first = facing_walls(*args, radius, width, back, cos, True)
            assert first[0] == behind or len(first[1]) == 1
            if not behind:
                assert (len(first[1]) > 0) == (len(ref) > 0)
            # Invariants: feet closer than the width, on the other side of the vertex's normal.
            assert np.all((dist > 0) & (dist < width))


def test_thick_everywhere_on_simple_domains() -> None:
    channel = Rectangle((0, 0), (4, 0.2))
    assert not thick_everywhere(channel, 0.3, 30.0)
    assert thick_everywhere(channel, 0.15, 30.0)
    disc = Circle((0, 0), 1.0)
    assert thick_everywhere(disc, 1.5, 30.0)
    # A slit hole close to the rim: back to back within 0.05.
    slit = Rectangle((0, 0), (2, 1)) - Polygon([(0.5, 0.96), (1.5, 0.96), (1.5, 0.97), (0.5, 0.97)])
    assert thick_everywhere(slit, 0.01, 30.0)
    assert not thick_everywhere(slit, 0.01, 30.0, back_to_back=0.05)
    # ``needed`` below the gap everywhere: thick.
    assert thick_everywhere(channel, 0.3, 30.0, needed=lambda p: np.full(len(p), 0.1))
    assert not thick_everywhere(channel, 0.3, 30.0, needed=lambda p: np.full(len(p), 0.25))


def test_unrestricted_size_equals_the_restricted_one_inside() -> None:
    from injmesh.boundary import corner_size
    from injmesh.sizing import as_size_function, effective_size
    from injmesh.sizing.features import unrestricted

    domain = shapes.large(0, n_vertices=600).domain()
    rng = np.random.default_rng(2)
    x0, y0, x1, y1 = domain.bbox
    p = rng.uniform((x0, y0), (x1, y1), (5000, 2))
    inside = domain.sdf(p) <= 0
    for size in (0.05, lambda q: 0.04 + 0.02 * np.abs(q[:, 0])):
        h = corner_size(domain, as_size_function(size))
        # A small max_cells: the grid is too coarse for h, min(grid, h restricted) is returned.
        target = effective_size(h, domain, max_cells=20_000)
        fast = unrestricted(target, h)
        if callable(size):  # a user function may not be asked outside: kept restricted
            assert fast is target
        else:
            assert fast is not target
        assert np.array_equal(fast(p[inside]), target(p[inside]))


def _cones_reference(p, hp, corners, spacing, rate):
    """``min(hp, min_c (s_c + rate sqrt(dx dx + dy dy)))`` over every corner, by brute force;
    hp at points with a non-finite coordinate."""
    out = np.array(hp, dtype=float)
    finite = np.isfinite(p).all(axis=1)
    p = np.where(finite[:, None], p, 0.0)
    for k in range(0, len(corners), 500):
        dx = p[:, 0, None] - corners[None, k:k + 500, 0]
        dy = p[:, 1, None] - corners[None, k:k + 500, 1]
        cone = spacing[None, k:k + 500] + rate * np.sqrt(dx * dx + dy * dy)
        out = np.minimum(out, cone.min(axis=1))
    out[~finite] = np.asarray(hp, dtype=float)[~finite]
    return out


def _layout(name: str, rng: np.random.Generator) -> np.ndarray:
    if name == "random":
        return rng.random((500, 2))
    if name == "clustered":  # dense clumps far apart: cells and tree boxes of very unequal fill
        centres = rng.random((5, 2)) * 10.0
        return np.concatenate([c + 1e-3 * rng.standard_normal((120, 2)) for c in centres])
    if name == "outline":
        return shapes.large(1, n_vertices=800).rings[0]
    if name == "line":  # no extent across: one row of cells, flat boxes
        return np.stack([rng.random(300), np.full(300, 0.5)], axis=1)
    if name == "lattice":  # many corners exactly equally far from many points
        g = np.arange(12) * 0.125 + 3.0
        return np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    return np.array([[0.3, 0.4]])


@pytest.mark.parametrize("layout", ["random", "clustered", "outline", "line", "lattice", "one"])
def test_corner_cones_are_the_minimum_over_every_corner(layout: str) -> None:
    from injmesh.kernels.outline import cone_index, corner_cones

    rng = np.random.default_rng(5)
    corners = np.ascontiguousarray(_layout(layout, rng), dtype=float)
    if layout == "lattice":  # equal spacings too: ties everywhere
        spacing = np.full(len(corners), 0.01)
    else:
        spacing = 0.001 + 0.02 * rng.random(len(corners))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    span = float(np.max(hi - lo)) + 0.1
    p = np.concatenate([
        rng.uniform(lo - 0.3 * span, hi + 0.3 * span, (3000, 2)),  # in, around and off the grid
        rng.uniform(lo, hi, (1000, 2)),
        corners, corners + 1e-9,  # on the corners (cone = spacing) and just beside them
        [[50.0, -40.0], [1e6, 1e6], [np.nan, 0.5], [0.5, np.inf], [-np.inf, np.nan]],
    ])
    if layout == "lattice":  # cell corners and midpoints between lattice points
        p = np.concatenate([p, corners + 0.0625, corners[:, ::-1] + [0.0, 0.0625]])
    for hp in (0.01 + 0.05 * rng.random(len(p)), np.full(len(p), 3.0), np.full(len(p), np.inf)):
        hp = hp.copy()
        hp[::97] = np.nan  # NaN h stays NaN
        hp[1::89] = 0.0005  # h below every spacing: kept
        for rate in (0.1, 0.5):
            ref = _cones_reference(p, hp, corners, spacing, rate)
            # Cells with leaf lists (h_max above their bound), without (0), lists cut short.
            for leaf, margin, cells, h_max in ((8, 0.05, len(corners), np.inf), (1, 0.0, 1.0, 0.05),
                                               (3, 2.0, 7.0 * len(corners), 0.0), (2, 0.3, 30.0, 10.0)):
                index = cone_index(corners, spacing, rate, leaf, margin, cells, h_max)
                got = corner_cones(p, hp, index)
                assert np.array_equal(got, ref, equal_nan=True), (leaf, margin, cells, h_max)
                assert np.array_equal(corner_cones(p, hp, index), got, equal_nan=True)
            # Points with a non-finite coordinate, or h at or below every spacing, keep h.
            kept = ~np.isfinite(p).all(axis=1) | ~(hp > spacing.min())
            assert np.array_equal(got[kept], hp[kept], equal_nan=True)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(1e-4, 0.5)), min_size=1, max_size=40),
    st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(1e-4, 2.0)), min_size=1, max_size=30),
    st.floats(0.05, 1.0),
    st.integers(1, 6),
    st.floats(0.0, 3.0),
)
def test_corner_cones_match_brute_force_on_any_corners(corners, points, rate, leaf, h_max) -> None:
    from injmesh.kernels.outline import cone_index, corner_cones

    c = np.ascontiguousarray(np.array(corners)[:, :2])
    s = np.ascontiguousarray(np.array(corners)[:, 2])
    p = np.ascontiguousarray(np.array(points)[:, :2])
    hp = np.array(points)[:, 2]
    index = cone_index(c, s, rate, leaf, 0.5, 2.0 * len(c), h_max)
    assert np.array_equal(corner_cones(p, hp, index), _cones_reference(p, hp, c, s, rate))


def test_cone_grid_bounds_hold_and_far_points_keep_h() -> None:
    # The grid's per-cell lower bound is below every cone over its cell (the early out is
    # exact), and tight: a point far from the corners is dismissed by it, not by a search.
    from injmesh.kernels.outline import cone_index, corner_cones

    rng = np.random.default_rng(3)
    corners = np.ascontiguousarray(shapes.large(2, n_vertices=600).rings[0], dtype=float)
    spacing = 0.002 + 0.01 * rng.random(len(corners))
    index = cone_index(corners, spacing, 0.2, 8, 0.2, float(len(corners)), np.inf)
    x0, y0, size, nx, ny, cell_rows = index[1][:6]
    lower = cell_rows[:, 0]
    p = rng.uniform((x0, y0), (x0 + nx * size, y0 + ny * size), (20000, 2))
    cell = (np.floor((p[:, 1] - y0) / size) * nx + np.floor((p[:, 0] - x0) / size)).astype(int)
    exact = _cones_reference(p, np.full(len(p), np.inf), corners, spacing, 0.2)
    assert np.all(lower[cell] <= exact)
    # Lower bounds within a cell's diagonal of the cones (the grid is worth its cells).
    assert np.all(exact - lower[cell] <= 0.2 * math.sqrt(2.0) * size * (1 + 1e-9) + 1e-12)
    hp = np.minimum(exact, lower[cell]) + 0.0  # h at the bound: every point kept, unchanged
    assert np.array_equal(corner_cones(p, hp, index), hp)


def test_corner_cap_is_rate_lipschitz() -> None:
    # The minimum over every corner moves at most rate |dp| along a path: no jump where the
    # set of nearest corners changes (what a k-nearest truncation did).
    from injmesh.boundary import _CornerCap
    from injmesh.sizing import as_size_function

    rng = np.random.default_rng(4)
    corners = rng.random((400, 2))
    spacing = 0.001 + 0.05 * rng.random(400)
    cap = _CornerCap(as_size_function(1.0), corners, spacing, 0.2)
    t = np.linspace(0.0, 1.0, 20001)
    path = np.stack([t, 0.5 + 0.4 * np.sin(7.0 * t)], axis=1)
    out = cap(path)
    step = np.hypot(*np.diff(path, axis=0).T)
    assert np.all(np.abs(np.diff(out)) <= 0.2 * step * (1 + 1e-9) + 1e-15)
    assert np.array_equal(out, _cones_reference(path, np.ones(len(path)), corners, spacing, 0.2))


def test_corner_size_on_a_small_cluster_of_corners_is_fast_far_away() -> None:
    # Two corners close together in a big domain with a large h: the grid of lower bounds
    # covers only the cluster, so almost every point is dismissed by the tree's root bound
    # (this once scanned 4,000 rows of cells per point).
    from injmesh.boundary import _CornerCap
    from injmesh.sizing import as_size_function

    cap = _CornerCap(as_size_function(lambda p: 0.2 + np.hypot(*p.T)), np.array([[1.0, 0.0], [1.0, 0.08]]),
                     np.array([0.08, 0.08]), 0.2)
    x0, y0, size, nx, ny = cap.index[1][:5]
    assert nx * ny <= 8 and nx * size < 1.0 and ny * size < 1.0
    p = np.random.default_rng(0).uniform(-2, 2, (20000, 2))
    out = cap(p)
    assert np.array_equal(out, _cones_reference(p, 0.2 + np.hypot(*p.T), cap.corners, cap.spacing, 0.2))


def test_corner_cones_do_not_depend_on_the_order_of_the_points() -> None:
    # A point starts from the leaf of its predecessor's minimum: the order of a batch may change
    # the work, never a value.  Mesh-like order (sorted along the outline), shuffled, reversed.
    from injmesh.kernels.outline import cone_index, corner_cones

    rng = np.random.default_rng(6)
    ring = np.ascontiguousarray(shapes.large(3, n_vertices=1500).rings[0], dtype=float)
    spacing = np.hypot(*(np.roll(ring, -1, axis=0) - ring).T)
    index = cone_index(ring, spacing, 0.2, 8, 0.1, 2.0 * len(ring), 0.05)
    # Points near the outline in its order (each a little off a vertex), then uniform ones.
    near = np.repeat(ring, 4, axis=0) + 0.01 * rng.standard_normal((4 * len(ring), 2))
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    p = np.concatenate([near, rng.uniform(lo - 0.1, hi + 0.1, (3000, 2))])
    hp = np.full(len(p), 0.05)
    ref = _cones_reference(p, hp, ring, spacing, 0.2)
    assert np.array_equal(corner_cones(p, hp, index), ref)
    for order in (rng.permutation(len(p)), np.arange(len(p))[::-1]):
        q = np.ascontiguousarray(p[order])
        assert np.array_equal(corner_cones(q, hp[order], index), ref[order])


def test_cone_index_leaf_rows_hold_every_corner_once() -> None:
    # The padded leaf rows are a copy of the tree's corners: each corner in its leaf's row,
    # every padding lane an infinite cone.
    from injmesh.kernels.outline import cone_index

    rng = np.random.default_rng(7)
    for n, leaf in ((1, 8), (5, 1), (37, 3), (1000, 8)):
        corners = rng.random((n, 2))
        spacing = 0.001 + 0.01 * rng.random(n)
        (_, _, first_leaf, node, pts), grid = cone_index(corners, spacing, 0.2, leaf, 0.1, 2.0 * n, 1.0)
        lv = grid[-1]
        assert lv.shape[2] % 4 == 0 and len(lv) == len(node) - first_leaf
        for j in range(len(lv)):
            lo, hi = int(node[first_leaf + j, 5]), int(node[first_leaf + j, 6])
            assert np.array_equal(lv[j, :, : hi - lo], pts[lo:hi].T)
            assert np.all(np.isinf(lv[j, 2, hi - lo:]))
        assert sorted(map(tuple, pts[:, :2])) == sorted(map(tuple, corners))


@pytest.mark.parametrize("seed", range(4))
def test_points_in_balls_are_the_pairs_within_each_radius(seed: int) -> None:
    from injmesh.kernels.outline import points_in_balls

    rng = np.random.default_rng(seed)
    v = rng.random((400, 2)) * [3.0, 1.0]
    q = np.concatenate([rng.uniform(-0.5, 3.5, (150, 2)), v[:20]])
    radius = 0.3 * rng.random(len(q))
    radius[::17] = 0.0  # a point of v at the centre is still in the ball
    radius[5] = np.inf
    radius[7] = np.nan  # finds nothing
    for size in (0.05, 0.2, 10.0):
        rows, cols = points_in_balls(q, radius, v, size)
        got = set(zip(rows.tolist(), cols.tolist(), strict=True))
        d2 = ((q[:, None, :] - v[None, :, :]) ** 2).sum(axis=2)
        want = set(zip(*np.nonzero(d2 <= radius[:, None] ** 2), strict=True))
        assert got == {(int(i), int(j)) for i, j in want}
        assert len(got) == len(rows)  # no pair twice
