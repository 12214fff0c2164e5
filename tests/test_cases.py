"""The paper's six cases, meshed both as composed geometry and as Table 10's plain sdf.

Figures asserted: validity, q_mean >= 0.95, relative size error <= 0.12, q_min at least the
paper's own figure for its algorithm, node count within 0.8-1.25 of what h implies, and the two
forms of each case agreeing on the node count to 5 % and on q_min to 0.02.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import CASE_NAMES, FORMS, assert_valid_mesh, paper_mesh
from injmesh.boundary import estimate_nodes
from injmesh.cases import CASES
from injmesh.geometry import as_domain
from injmesh.sizing import as_size_function

ALL = [(name, form) for name in CASE_NAMES for form in FORMS]


def _domain(name: str, form: str):
    case = CASES[name]
    if form == "geometry":
        return case.geometry
    return as_domain(case.sdf, bbox=case.bbox, fixed_points=case.fixed_points)


@pytest.mark.parametrize(("name", "form"), ALL)
def test_case_mesh_is_valid(name: str, form: str) -> None:
    mesh = paper_mesh(name, form)
    # The plain sdf is checked against itself: its zero set is the boundary, its sign the inside.
    assert_valid_mesh(mesh, _domain(name, form))
    assert mesh.converged


@pytest.mark.parametrize(("name", "form"), ALL)
def test_case_mean_quality(name: str, form: str) -> None:
    assert paper_mesh(name, form).quality().mean() >= 0.95


@pytest.mark.parametrize(("name", "form"), ALL)
def test_case_size_error(name: str, form: str) -> None:
    report = paper_mesh(name, form).size_report()
    assert report.relative <= 0.12
    assert 0.9 <= report.ratio_mean <= 1.1


@pytest.mark.parametrize(("name", "form"), ALL)
def test_case_min_quality_reaches_paper(name: str, form: str) -> None:
    q_min = paper_mesh(name, form).quality().min()
    assert q_min >= CASES[name].paper_ours.q_min


@pytest.mark.parametrize(("name", "form"), ALL)
def test_case_node_count_follows_h(name: str, form: str) -> None:
    h = as_size_function(CASES[name].size)
    _, interior = estimate_nodes(_domain(name, form), h)
    mesh = paper_mesh(name, form)
    # A boundary node carries half the area of an interior one: N ~ area term + half of them.
    expected = interior + 0.5 * mesh.stats.boundary_nodes
    assert 0.85 * expected <= mesh.n_points <= 1.15 * expected


@pytest.mark.parametrize("name", CASE_NAMES)
def test_geometry_and_sdf_agree(name: str) -> None:
    a, b = paper_mesh(name, "geometry"), paper_mesh(name, "sdf")
    assert b.n_points == pytest.approx(a.n_points, rel=0.05)
    # Same region: the meshes cover the same area.
    assert b.areas().sum() == pytest.approx(a.areas().sum(), rel=1e-3)
    # One mechanism, two paths (issue 8): the same quality within 0.02.
    assert abs(b.quality().min() - a.quality().min()) <= 0.02


@pytest.mark.parametrize("name", CASE_NAMES)
def test_case_boundary_tags_count_loops(name: str) -> None:
    """One tag per boundary loop: 1 for simply connected cases, 1 + holes otherwise."""
    loops = {"square_with_hole": 2, "circle_with_hole": 2, "square_with_four_holes": 5}.get(name, 1)
    mesh = paper_mesh(name, "geometry")
    assert np.array_equal(np.unique(mesh.boundary_tags), np.arange(loops))
