"""Our .msh files feed a finite element code: scikit-fem solves Poisson's equation on them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from injmesh.cli import main

skfem = pytest.importorskip("skfem")
from skfem import Basis, BilinearForm, ElementTriP1, LinearForm, MeshTri, condense, solve  # noqa: E402
from skfem.helpers import dot, grad  # noqa: E402


@BilinearForm
def laplace(u, v, w):
    return dot(grad(u), grad(v))


@LinearForm
def unit_load(v, w):
    return v


def solve_poisson(mesh: MeshTri) -> np.ndarray:
    """P1 solution of -Laplace(u) = 1 with u = 0 on the whole boundary."""
    basis = Basis(mesh, ElementTriP1())
    A, b = laplace.assemble(basis), unit_load.assemble(basis)
    return solve(*condense(A, b, D=basis.get_dofs()))


def test_poisson_on_the_unit_disc(tmp_path):
    """u = (1 - r^2)/4 exactly; P1 on our h = 0.05 mesh is within 1e-3 at every node.

    (Measured: about 1.2e-4, from the P1 discretisation and the polygonal boundary, both O(h^2).)
    """
    path = tmp_path / "disc.msh"
    assert main(["generate", "unit_disc", "--size", "0.05", "-o", str(path), "-q"]) == 0
    mesh = MeshTri.load(str(path))
    assert mesh.nelements > 2000
    assert set(mesh.boundaries) == {"outer boundary"}
    assert set(mesh.subdomains) == {"domain"}
    # The tagged boundary is the whole boundary.
    assert np.array_equal(np.sort(mesh.boundaries["outer boundary"]), np.sort(mesh.boundary_facets()))

    u = solve_poisson(mesh)
    x, y = mesh.p
    exact = (1 - x**2 - y**2) / 4
    assert np.abs(u - exact).max() < 1e-3


def test_holes_become_named_boundaries(tmp_path):
    """A GeoJSON square with two holes: scikit-fem sees each hole as its own named boundary."""
    shell = [[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]
    hole_a = [[1, 1], [1, 2], [2, 2], [2, 1], [1, 1]]
    hole_b = [[2.5, 0.5], [3.5, 0.5], [3, 1.5], [2.5, 0.5]]
    src = tmp_path / "plate.geojson"
    src.write_text(json.dumps({"type": "Polygon", "coordinates": [shell, hole_a, hole_b]}))
    path = tmp_path / "plate.msh"
    assert main(["generate", str(src), "--size", "0.3", "-o", str(path), "-q"]) == 0
    mesh = MeshTri.load(str(path))
    assert set(mesh.boundaries) == {"outer boundary", "hole 1", "hole 2"}
    facets = np.concatenate([mesh.boundaries[k] for k in mesh.boundaries])
    assert np.array_equal(np.sort(facets), np.sort(mesh.boundary_facets()))
    # Each hole's facets are exactly the facets on one of the two hole rings.
    midpoints = mesh.p[:, mesh.facets].mean(axis=1).T
    in_a = np.all((midpoints > 1 - 1e-9) & (midpoints < 2 + 1e-9), axis=1)
    sizes = sorted(int(in_a[mesh.boundaries[k]].sum()) for k in ("hole 1", "hole 2"))
    assert sizes[0] == 0 and sizes[1] > 0
