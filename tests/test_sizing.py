"""The size function h: validation at the edge, with messages that name the bad value."""

from __future__ import annotations

import numpy as np
import pytest

import injmesh
from injmesh import Circle, SizeError
from injmesh.sizing import SizeFunction, as_size_function, inside_only

DISC = Circle((0, 0), 1)
POINTS = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))


def test_size_error_is_a_value_error() -> None:
    assert issubclass(SizeError, ValueError)


@pytest.mark.parametrize("value", [0.1, 1, np.float32(0.25), np.int64(2)])
def test_number_is_a_constant(value) -> None:
    h = as_size_function(value)
    out = h(POINTS)
    assert out.shape == (len(POINTS),)
    assert out.dtype == np.float64
    assert np.all(out == float(value))


def test_callable_is_evaluated_and_checked() -> None:
    h = as_size_function(lambda p: 0.1 + p[:, 0] ** 2)
    assert np.allclose(h(POINTS), 0.1 + POINTS[:, 0] ** 2)


def test_scalar_result_is_broadcast() -> None:
    h = as_size_function(lambda p: 0.2)
    assert np.all(h(POINTS) == 0.2)


def test_validated_function_passes_through() -> None:
    h = as_size_function(0.3)
    assert as_size_function(h) is h
    assert isinstance(h, SizeFunction)


def test_single_point_is_accepted() -> None:
    assert as_size_function(lambda p: p[:, 0] + 2)(np.array([1.0, 0.0])).shape == (1,)


@pytest.mark.parametrize(
    ("size", "match"),
    [
        (0, "positive"),
        (-0.1, "positive"),
        (float("nan"), "nan"),
        (float("inf"), "inf"),
    ],
)
def test_bad_numbers(size, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        as_size_function(size)
    with pytest.raises(SizeError, match=match):
        injmesh.generate(DISC, size)


@pytest.mark.parametrize(
    ("size", "match"),
    [
        (lambda p: np.full((len(p), 2), 0.1), r"must return shape \(\d+,\) .* got shape \(\d+, 2\)"),
        (lambda p: np.full(len(p) + 1, 0.1), r"must return shape"),
        (lambda p: np.full(len(p), -0.1), "positive and finite"),
        (lambda p: np.zeros(len(p)), "positive and finite"),
        (lambda p: np.where(p[:, 0] > 0.5, np.nan, 0.1), "positive and finite"),
        (lambda p: float(p), "failed on an \\(n, 2\\) array"),
    ],
)
def test_bad_callables(size, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        as_size_function(size)(POINTS)
    with pytest.raises(SizeError, match=match):
        injmesh.generate(DISC, size)


@pytest.mark.parametrize("size", [b"0.1", None, [0.1], True])  # a str is an expression
def test_bad_types(size) -> None:
    with pytest.raises(TypeError, match="size must be"):
        as_size_function(size)
    with pytest.raises(TypeError, match="size must be"):
        injmesh.generate(DISC, size)


def test_negative_value_message_names_the_point() -> None:
    h = as_size_function(lambda p: np.where(p[:, 0] > 0, -1.0, 0.1))
    with pytest.raises(SizeError, match=r"= -1\.0"):
        h(np.array([[-1.0, 0.0], [2.0, 3.0]]))


def test_negative_value_message_is_readable() -> None:
    """Under NumPy 2 a tuple of array items would print as ``(np.float64(2.0), ...)``."""
    h = as_size_function(lambda p: np.where(p[:, 0] > 0, -1.0, 0.1))
    with pytest.raises(SizeError) as info:
        h(np.array([[-1.0, 0.0], [2.0, 3.0]]))
    assert "np.float64" not in str(info.value)
    assert "(2.0, 3.0)" in str(info.value)


@pytest.mark.parametrize(
    ("size", "what"),
    [
        (lambda p: np.full(len(p), "0.1"), "strings"),
        (lambda p: np.full(len(p), 0.1 + 0j), "complex numbers"),
        (lambda p: np.full(len(p), 0.1, dtype=object), "Python objects"),
        (lambda p: np.ones(len(p), dtype=bool), "booleans"),
        (lambda p: True, "booleans"),
        (lambda p: [0.1] * (len(p) - 1) + ["x"], "strings"),
    ],
)
def test_results_that_are_not_real_numbers_are_refused(size, what: str) -> None:
    with pytest.raises(SizeError, match=f"must return real numbers, got {what}"):
        as_size_function(size)(POINTS)
    with pytest.raises(SizeError, match="real numbers"):
        injmesh.generate(DISC, size)


def test_integer_results_are_lengths() -> None:
    h = as_size_function(lambda p: np.ones(len(p), dtype=int))
    assert np.array_equal(h(POINTS), np.ones(len(POINTS)))


def test_bad_value_message_counts_the_other_points() -> None:
    h = as_size_function(lambda p: np.where(p[:, 0] > 0, np.inf, 0.1))
    with pytest.raises(SizeError, match=r"= inf \(and \d+ other of the 50 points\)"):
        h(POINTS)


def test_restricted_size_is_only_evaluated_inside() -> None:
    """DistMesh's own example: h is negative inside the hole of the ring."""
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
    seen: list[np.ndarray] = []

    def h(p: np.ndarray) -> np.ndarray:
        seen.append(p.copy())
        return 0.05 + 0.3 * (np.hypot(p[:, 0], p[:, 1]) - 0.5)

    with pytest.raises(SizeError, match="positive and finite"):
        as_size_function(h)(np.array([[0.0, 0.0]]))
    inside = as_size_function(h).restricted(ring)
    p = np.random.default_rng(1).uniform(-2, 2, (400, 2))
    out = inside(p)
    assert np.all(out >= 0.05 - 1e-9)
    assert ring.sdf(seen[-1]).max() <= 1e-6 * ring.diameter
    # Points inside are evaluated where they are.
    keep = ring.sdf(p) <= 0
    assert np.array_equal(out[keep], 0.05 + 0.3 * (np.hypot(p[keep, 0], p[keep, 1]) - 0.5))


def test_inside_only_lets_distmesh_style_sizes_mesh() -> None:
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
    h = lambda p: 0.05 + 0.3 * (np.hypot(p[:, 0], p[:, 1]) - 0.5)  # noqa: E731
    mesh = injmesh.generate(ring, inside_only(h, ring), fixed_points=np.array([[1.0, 0.0]]))
    assert mesh.quality().min() > 0.6


def test_huge_sizes_are_clamped_to_the_diameter_when_restricted() -> None:
    square = injmesh.Rectangle((0, 0), (1, 1))
    assert as_size_function(1e300).restricted(square)(POINTS).max() == square.diameter
    h = as_size_function(lambda p: np.full(len(p), 1e300)).restricted(square)
    assert h(POINTS).max() == square.diameter
    mesh = injmesh.generate(square, inside_only(1e300, square))
    assert mesh.n_points >= 4


def test_restricted_keeps_a_constant_constant() -> None:
    h = as_size_function(0.1).restricted(DISC)
    assert h.constant == 0.1 and np.all(h(POINTS) == 0.1)
