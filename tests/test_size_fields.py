"""Size fields from data: GriddedSize (a raster, bilinear) and ScatteredSize (samples, linear).

Invariants: the data are reproduced exactly at the nodes/samples, a smooth h to 2 % between them,
values stay within the data's range, outside the data the nearest value holds, bad data are
refused with a message that names the problem and where it is.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import injmesh
from injmesh import Rectangle, SizeError
from injmesh.sizing import GriddedSize, ScatteredSize, as_size_function


def smooth_h(p: np.ndarray) -> np.ndarray:
    """A smooth size varying by a factor of about 4 over the unit square."""
    x, y = p[:, 0], p[:, 1]
    return 0.02 + 0.05 * (x**2 + y) + 0.01 * np.sin(3 * x) * np.cos(2 * y)


def grid_of(h, x: np.ndarray, y: np.ndarray) -> GriddedSize:
    X, Y = np.meshgrid(x, y)
    return GriddedSize(x, y, h(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(len(y), len(x)))


RNG = np.random.default_rng(7)
INSIDE = RNG.uniform(0, 1, size=(5000, 2))


@pytest.mark.parametrize("uniform", [True, False])
def test_gridded_is_exact_at_nodes_and_close_between(uniform: bool) -> None:
    if uniform:
        x, y = np.linspace(0, 1, 41), np.linspace(0, 1, 31)
    else:
        x = np.sort(np.concatenate([[0, 1], RNG.uniform(0, 1, 39)]))
        y = np.sort(np.concatenate([[0, 1], RNG.uniform(0, 1, 29)]))
    g = grid_of(smooth_h, x, y)
    X, Y = np.meshgrid(x, y)
    nodes = np.stack([X.ravel(), Y.ravel()], axis=1)
    assert np.array_equal(g(nodes), smooth_h(nodes))
    rel = np.abs(g(INSIDE) / smooth_h(INSIDE) - 1)
    assert rel.max() < 0.02


def test_gridded_outside_takes_the_nearest_grid_value() -> None:
    g = grid_of(smooth_h, np.linspace(0, 1, 11), np.linspace(0, 1, 11))
    far = np.array([[-5.0, -5.0], [7.0, 0.5], [0.3, 9.0], [2.0, 2.0]])
    clamped = np.clip(far, 0, 1)
    assert np.array_equal(g(far), g(clamped))
    assert g(far)[0] == g.values[0, 0] and g(far)[3] == g.values[-1, -1]


def test_gridded_accepts_a_decreasing_axis_like_a_raster() -> None:
    x, y = np.linspace(0, 1, 11), np.linspace(0, 1, 9)
    g = grid_of(smooth_h, x, y)
    flipped = GriddedSize(x, y[::-1], g.values[::-1])
    assert np.array_equal(flipped(INSIDE), g(INSIDE))


def test_gridded_values_are_copied_and_read_only() -> None:
    x = y = np.linspace(0, 1, 5)
    v = np.full((5, 5), 0.1)
    g = GriddedSize(x, y, v)
    v[:] = -1.0
    assert np.all(g(INSIDE[:10]) == 0.1)
    with pytest.raises(ValueError):
        g.values[0, 0] = 1.0


def test_gridded_is_deterministic_and_handles_nan_points() -> None:
    g = grid_of(smooth_h, np.linspace(0, 1, 17), np.linspace(0, 1, 13))
    assert np.array_equal(g(INSIDE), g(INSIDE.copy()))
    out = g(np.array([[np.nan, 0.5], [0.5, 0.5]]))
    assert np.isnan(out[0]) and np.isfinite(out[1])
    with pytest.raises(SizeError, match="positive and finite"):
        as_size_function(g)(np.array([[np.nan, 0.5]]))


@settings(max_examples=40, deadline=None)
@given(
    nx=st.integers(2, 12),
    ny=st.integers(2, 12),
    seed=st.integers(0, 2**32 - 1),
)
def test_gridded_stays_within_the_data_range(nx: int, ny: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.uniform(0.01, 1, nx))
    y = np.cumsum(rng.uniform(0.01, 1, ny))
    v = rng.uniform(0.1, 10, (ny, nx))
    g = GriddedSize(x, y, v)
    p = rng.uniform(-1, max(x[-1], y[-1]) + 1, (200, 2))
    out = g(p)
    assert np.all(out >= v.min() * (1 - 1e-12)) and np.all(out <= v.max() * (1 + 1e-12))


@pytest.mark.parametrize(
    ("x", "y", "values", "match"),
    [
        ([0, 1, 1, 2], [0, 1], np.ones((2, 4)), r"monotone.*x\[1\] = 1.0 and x\[2\] = 1.0"),
        ([0, 2, 1], [0, 1], np.ones((2, 3)), r"x must be strictly monotone"),
        ([0, 1], [0, 1, 0.5], np.ones((3, 2)), r"y must be strictly monotone"),
        ([0, 1, 2], [0, 1], np.ones((3, 2)), r"shape \(len\(y\), len\(x\)\) = \(2, 3\).*transposed"),
        ([0, 1, 2], [0, 1], np.ones(6), r"shape \(len\(y\), len\(x\)\)"),
        ([0], [0, 1], np.ones((2, 1)), "at least two"),
        ([[0, 1]], [0, 1], np.ones((2, 2)), "1-D"),
        ([0, np.nan], [0, 1], np.ones((2, 2)), r"x\[1\] = nan is not finite"),
        ([0, 1, 2], [0, 1], [[1, 1, 1], [1, np.nan, 1]], r"values\[1, 1\] = nan at \(1.0, 1.0\)"),
        ([0, 1, 2], [0, 1], [[1, 1, 1], [1, 1, -2]], r"values\[1, 2\] = -2.0 at \(2.0, 1.0\)"),
        ([0, 1, 2], [0, 1], [[1, 1, 1], [1, 1, 0]], r"values\[1, 2\] = 0.0"),
        ([0, 1, 2], [0, 1], [[1, 1, 1], [1, np.inf, 1]], r"= inf"),
        ([0, 1], [0, 1], np.ones((2, 2), dtype=complex), "complex"),
        ([0, 1], [0, 1], np.ones((2, 2), dtype=bool), "booleans"),
        ([0, 1], [0, 1], [["a", "b"], ["c", "d"]], "strings"),
        (["0", "1"], [0, 1], np.ones((2, 2)), "x must hold real numbers, got strings"),
        ([0, 1], [0, 1], np.array([[0.1, None], [0.1, 0.1]], dtype=object), "objects"),
    ],
)
def test_gridded_bad_input(x, y, values, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        GriddedSize(x, y, values)


def test_gridded_nan_message_counts_bad_values() -> None:
    v = np.ones((3, 3))
    v[1, 1] = v[2, 0] = np.nan
    with pytest.raises(SizeError, match=r"2 bad values"):
        GriddedSize([0, 1, 2], [0, 1, 2], v)


def test_scattered_is_exact_at_samples_and_close_between() -> None:
    # Jittered stations (as measurements usually are), the unit square's outline included.
    rng = np.random.default_rng(3)
    t = np.linspace(0, 1, 41)
    X, Y = np.meshgrid(t, t)
    pts = np.stack([X.ravel(), Y.ravel()], axis=1)
    interior = (pts > 0).all(axis=1) & (pts < 1).all(axis=1)
    pts[interior] += rng.uniform(-0.01, 0.01, (int(interior.sum()), 2))
    s = ScatteredSize(pts, smooth_h(pts))
    assert np.allclose(s(pts), smooth_h(pts), rtol=1e-12, atol=0)
    rel = np.abs(s(INSIDE) / smooth_h(INSIDE) - 1)
    assert rel.max() < 0.02


def test_scattered_reproduces_a_linear_size_inside_the_hull() -> None:
    pts = np.random.default_rng(4).uniform(-1, 1, (200, 2))
    lin = lambda p: 0.5 + 0.1 * p[:, 0] - 0.2 * p[:, 1]  # noqa: E731
    s = ScatteredSize(pts, lin(pts))
    q = np.random.default_rng(5).uniform(-0.5, 0.5, (500, 2))
    assert np.allclose(s(q), lin(q), rtol=1e-12)


def test_scattered_outside_the_hull_takes_the_nearest_sample() -> None:
    s = ScatteredSize([(0, 0), (1, 0), (0, 1)], [0.1, 0.2, 0.3])
    assert np.array_equal(s(np.array([[5.0, -1.0], [-3.0, 4.0], [-2.0, -2.0]])), [0.2, 0.3, 0.1])


def test_scattered_far_from_the_origin() -> None:
    offset = np.array([1e9, -3e8])
    pts = np.random.default_rng(6).uniform(0, 1, (300, 2))
    lin = lambda p: 0.5 + 0.1 * p[:, 0]  # noqa: E731
    near = ScatteredSize(pts, lin(pts))
    far = ScatteredSize(pts + offset, lin(pts))
    q = np.random.default_rng(8).uniform(0.2, 0.8, (100, 2))
    assert np.allclose(far(q + offset), near(q), rtol=1e-6)


def test_scattered_degenerate_samples_use_the_nearest() -> None:
    one = ScatteredSize([(0.5, 0.5)], [0.2])
    assert np.all(one(INSIDE[:20]) == 0.2)
    line = ScatteredSize([(0, 0), (1, 1), (2, 2)], [0.1, 0.2, 0.3])
    assert np.array_equal(line(np.array([[0.1, 0.0], [2.5, 2.0]])), [0.1, 0.3])


def test_scattered_merges_duplicates_by_their_mean() -> None:
    s = ScatteredSize([(0, 0), (1, 0), (0, 1), (0, 0)], [0.1, 0.2, 0.3, 0.3])
    assert len(s.points) == 3
    assert s(np.array([[0.0, 0.0]]))[0] == pytest.approx(0.2)


@pytest.mark.parametrize(
    ("points", "values", "match"),
    [
        (np.zeros((0, 2)), np.zeros(0), "at least one sample"),
        (np.zeros((3, 3)), np.ones(3), r"shape \(n, 2\)"),
        ([(0, 0), (1, 0)], [0.1], r"shape \(2,\)"),
        ([(0, 0), (np.nan, 0)], [0.1, 0.1], r"points\[1\] = \(nan, 0.0\) is not finite"),
        ([(0, 0), (1, 0), (0, 1)], [0.1, np.nan, 0.1], r"values\[1\] = nan at \(1.0, 0.0\)"),
        ([(0, 0), (1, 0), (0, 1)], [0.1, 0.1, -1], r"values\[2\] = -1.0 at \(0.0, 1.0\)"),
        ([(0, 0), (1, 0), (0, 1)], [0.1, 0.1, 1j], "complex"),
        ([(0, 0), (1, 0), (0, 1)], [True, True, True], "booleans"),
        ([(0, 0), (1, 0), (0, 1)], ["0.1", "0.1", "0.1"], "strings"),
    ],
)
def test_scattered_bad_input(points, values, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        ScatteredSize(points, values)


def test_fields_mesh_like_the_analytic_size() -> None:
    """A mesh from either field follows the analytic h as well as a mesh from h itself."""
    domain = Rectangle((0, 0), (1, 1))
    h = lambda p: 0.06 + 0.1 * p[:, 0]  # noqa: E731
    x = np.linspace(-0.1, 1.1, 25)
    pts = np.random.default_rng(9).uniform(-0.1, 1.1, (400, 2))
    errors = []
    for size in (h, grid_of(h, x, x), ScatteredSize(pts, h(pts))):
        mesh = injmesh.generate(domain, size)
        errors.append(mesh.size_report(h).relative)
        assert mesh.quality().min() > 0.7
    assert abs(errors[1] - errors[0]) < 0.02 and abs(errors[2] - errors[0]) < 0.02
