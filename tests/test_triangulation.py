"""Delaunay, removal of outside triangles, boundary edges, and Lawson flips."""

from __future__ import annotations

import numpy as np
import pytest

from injmesh.quality import signed_areas, unique_edges
from injmesh.triangulation import TriangulationError, boundary_edges, delaunay, flip_to_delaunay


def _canonical(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t)
    r = np.argmin(t, axis=1)
    rolled = np.stack([t[np.arange(len(t)), (r + k) % 3] for k in range(3)], axis=1)
    return rolled[np.lexsort(rolled.T[::-1])]


def test_flips_after_small_moves_give_the_delaunay_triangulation() -> None:
    rng = np.random.default_rng(0)
    xs, ys = np.meshgrid(np.arange(20.0), np.arange(20.0))
    p = np.stack([xs.ravel(), ys.ravel()], axis=1) + 0.2 * rng.standard_normal((400, 2))
    tri = delaunay(p)
    # Interior nodes move by about 5 % of the spacing, as between two triangulations of the
    # smoothing: the old connectivity is no longer Delaunay, and flips must reach exactly what
    # Qhull computes from scratch.
    # Qhull's convex hull has slivers (not found in a domain mesh): leave their nodes still.
    hull = np.unique(boundary_edges(tri))
    near_hull = np.unique(tri[np.isin(tri, hull).any(axis=1)])
    moved = p.copy()
    inner = np.setdiff1d(np.arange(len(p)), near_hull)
    moved[inner] += 0.05 * rng.standard_normal((len(inner), 2))
    assert not np.array_equal(_canonical(tri), _canonical(delaunay(moved)))
    flipped = flip_to_delaunay(moved, tri)
    assert flipped is not None
    assert np.all(signed_areas(moved, flipped) > 0)
    assert np.array_equal(_canonical(flipped), _canonical(delaunay(moved)))


def test_flips_keep_the_boundary() -> None:
    """Edges with one triangle are never flipped: a non-convex mesh keeps its outline."""
    # An L made of two squares' worth of grid, with a poor diagonal choice everywhere.
    xs, ys = np.meshgrid(np.arange(5.0), np.arange(5.0))
    p = np.stack([xs.ravel(), ys.ravel()], axis=1)
    p += 0.01 * np.random.default_rng(1).standard_normal(p.shape)
    tri = delaunay(p)
    keep = ~np.all((p[tri][:, :, 0] >= 2) & (p[tri][:, :, 1] >= 2), axis=1)
    tri = tri[keep]
    before = {tuple(sorted(e)) for e in boundary_edges(tri)}
    flipped = flip_to_delaunay(p, tri)
    assert flipped is not None
    assert {tuple(sorted(e)) for e in boundary_edges(flipped)} == before
    assert len(unique_edges(flipped)) == len(unique_edges(tri))


def test_flips_decline_an_inverted_triangle() -> None:
    p = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=float)
    tri = delaunay(p)
    p[3] = [-1.0, -1.0]  # folds a triangle over
    assert flip_to_delaunay(p, tri) is None


def test_delaunay_rejects_too_few_points() -> None:
    with pytest.raises(TriangulationError, match="at least 3"):
        delaunay(np.zeros((2, 2)))
