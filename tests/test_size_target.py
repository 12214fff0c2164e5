"""generate(..., target_nodes=N): h scaled to meet a node count."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import injmesh
from conftest import assert_valid_mesh
from injmesh import Circle, Rectangle
from injmesh.cases import CASES
from injmesh.errors import ConvergenceWarning, NodeBudgetError


@pytest.mark.parametrize("name", ["unit_disc", "square_with_four_holes", "l_shape"])
def test_paper_cases_meet_the_count_within_3_percent(name: str) -> None:
    case = CASES[name]
    mesh = injmesh.generate(case.geometry, case.size, target_nodes=400)
    assert abs(mesh.n_points / 400 - 1) <= 0.03
    assert_valid_mesh(mesh, case.geometry)
    assert mesh.quality().min() > 0.7
    # The shape of h is kept: the mesh still follows the scaled size.
    assert mesh.size_report().relative < 0.15


def test_graded_size_meets_the_count_and_keeps_its_grading() -> None:
    square = Rectangle((0, 0), (1, 1))

    def h(p: np.ndarray) -> np.ndarray:
        return 0.01 + 0.3 * np.hypot(p[:, 0] - 0.3, p[:, 1] - 0.3)

    mesh = injmesh.generate(square, h, target_nodes=600)
    assert abs(mesh.n_points / 600 - 1) <= 0.03
    # Finer near (0.3, 0.3) than far from it, by about the ratio h prescribes.
    near = np.hypot(*(mesh.points - [0.3, 0.3]).T) < 0.1
    far = np.hypot(*(mesh.points - [0.3, 0.3]).T) > 0.6
    assert near.sum() / max(far.sum(), 1) > 1.5


def test_a_uniform_size_is_any_constant() -> None:
    """Bit for bit for constants a power of two apart; for 1e-3 the search's scales round
    differently and the count is a step function of the scale, so the figures agree."""
    disc = Circle((0, 0), 1)
    a = injmesh.generate(disc, 1.0, target_nodes=200)
    b = injmesh.generate(disc, 2.0**-10, target_nodes=200)
    assert abs(a.n_points / 200 - 1) <= 0.03
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
    c = injmesh.generate(disc, 1e-3, target_nodes=200)
    assert abs(c.n_points / 200 - 1) <= 0.03
    assert c.quality().mean() == pytest.approx(a.quality().mean(), abs=0.005)


def test_deterministic() -> None:
    case = CASES["circle_with_hole"]
    a = injmesh.generate(case.geometry, case.size, target_nodes=250)
    b = injmesh.generate(case.geometry, case.size, target_nodes=250)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)


def test_feature_size_sets_a_floor_and_warns() -> None:
    channel = Rectangle((0, 0), (3, 0.05))
    with pytest.warns(ConvergenceWarning, match="target_nodes=20: the mesh has"):
        mesh = injmesh.generate(channel, 1.0, target_nodes=20)
    # Two elements across the 0.05 channel, whatever was asked.
    assert mesh.quality().min() > 0.6 and mesh.n_points > 100
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        coarse = injmesh.generate(channel, 1.0, target_nodes=400)
    assert abs(coarse.n_points / 400 - 1) <= 0.03


def test_time_spent_searching_is_reported() -> None:
    mesh = injmesh.generate(Circle((0, 0), 1), 1.0, target_nodes=80)
    assert mesh.stats.seconds["target_nodes"] >= 0


@pytest.mark.parametrize("bad", [True, 2, 10.5, "100", -5])
def test_bad_target_nodes(bad: object) -> None:
    with pytest.raises(ValueError, match="target_nodes"):
        injmesh.generate(Circle((0, 0), 1), 1.0, target_nodes=bad)  # type: ignore[arg-type]


def test_target_nodes_above_the_budget_is_refused_before_any_work() -> None:
    with pytest.raises(NodeBudgetError, match="target_nodes=5000 is above max_nodes=1000"):
        injmesh.generate(Circle((0, 0), 1), 1.0, target_nodes=5000, max_nodes=1000)


def test_target_nodes_is_for_injection_only() -> None:
    with pytest.raises(ValueError, match="method='injection' only"):
        injmesh.generate(Circle((0, 0), 1), 1.0, target_nodes=100, method="distmesh")


def test_a_count_just_under_the_budget_is_met() -> None:
    # The stages' budget checks are estimates (this h "implies" about 554 nodes at the final
    # scale); target_nodes itself is what is checked against max_nodes.
    square = Rectangle((0, 0), (1, 1))
    mesh = injmesh.generate(square, "0.01 + 0.1*x", target_nodes=500, max_nodes=520)
    assert abs(mesh.n_points / 500 - 1) <= 0.03


def test_fixed_points_and_a_plain_sdf() -> None:
    def disc(p: np.ndarray) -> np.ndarray:
        return np.hypot(p[:, 0], p[:, 1]) - 1

    mesh = injmesh.generate(disc, 1.0, bbox=(-1, -1, 1, 1), fixed_points=[(0.3, 0.2)],
                            target_nodes=300)
    assert abs(mesh.n_points / 300 - 1) <= 0.03
    assert np.any(np.all(mesh.points == [0.3, 0.2], axis=1))
