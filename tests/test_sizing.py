"""The size function h: validation at the edge, with messages that name the bad value."""

from __future__ import annotations

import numpy as np
import pytest

import injmesh
from injmesh import Circle, SizeError
from injmesh.sizing import SizeFunction, as_size_function

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
