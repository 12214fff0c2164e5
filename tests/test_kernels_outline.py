"""Compiled loops over outlines (kernels.outline) against the NumPy/Python code they replaced."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage
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


def _cones_reference(p, hp, corners, spacing, rate, k):
    """The k-d tree query ``corner_size``'s cap made before the kernel."""
    reach = (hp.max() - spacing.min()) / rate
    dist, near = cKDTree(corners).query(p, k=k, distance_upper_bound=reach)
    dist, near = dist.reshape(len(p), k), near.reshape(len(p), k)
    seen = near < len(corners)
    s = spacing[np.minimum(near, len(corners) - 1)]
    return np.minimum(hp, np.where(seen, s + rate * dist, np.inf).min(axis=1))


@pytest.mark.parametrize("layout", ["random", "outline", "line", "one"])
def test_corner_cones_match_the_k_nearest_query(layout: str) -> None:
    from injmesh.kernels.outline import cell_grid, corner_cones

    rng = np.random.default_rng(5)
    if layout == "random":
        corners = rng.random((500, 2))
    elif layout == "outline":
        corners = shapes.large(1, n_vertices=800).rings[0]
    elif layout == "line":  # no extent across: a one-row grid
        corners = np.stack([rng.random(300), np.full(300, 0.5)], axis=1)
    else:
        corners = np.array([[0.3, 0.4]])
    corners = np.ascontiguousarray(corners, dtype=float)
    spacing = 0.001 + 0.02 * rng.random(len(corners))
    lo, hi = corners.min(axis=0) - 0.3, corners.max(axis=0) + 0.3
    p = np.concatenate([rng.uniform(lo, hi, (4000, 2)), corners, [[50.0, -40.0]]])
    for hp in (0.01 + 0.05 * rng.random(len(p)), np.full(len(p), 3.0)):
        for cell in (0.003, 0.02, 0.2):
            grid = cell_grid(corners, cell)
            nx, ny, first = grid[2], grid[3], grid[5]
            empty = (np.diff(first) == 0).reshape(ny, nx)
            rings = ndimage.distance_transform_cdt(empty, metric="chessboard").ravel().astype(np.int64)
            for k in {1, min(6, len(corners))}:
                for rate in (0.1, 0.5):
                    got = corner_cones(p, hp, corners, spacing, rate, k, spacing.min(), grid, cell, rings)
                    assert np.array_equal(got, _cones_reference(p, hp, corners, spacing, rate, k))
                    assert np.all(got <= hp)


def test_corner_size_on_a_small_cluster_of_corners_is_fast_far_away() -> None:
    # Two corners close together in a big domain with a large h: every point's search stops
    # at the ring farther than its k-th corner (this once scanned 4,000 rows per point).
    from injmesh.boundary import _CornerCap
    from injmesh.sizing import as_size_function

    cap = _CornerCap(as_size_function(lambda p: 0.2 + np.hypot(*p.T)), np.array([[1.0, 0.0], [1.0, 0.08]]),
                     np.array([0.08, 0.08]), 0.2)
    p = np.random.default_rng(0).uniform(-2, 2, (20000, 2))
    out = cap(p)
    ref = _cones_reference(p, 0.2 + np.hypot(*p.T), cap.corners, cap.spacing, 0.2, 2)
    assert np.array_equal(out, ref)
