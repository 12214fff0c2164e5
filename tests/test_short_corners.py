"""Sharp corners shorter than h, and the mouths of spikes and inlets (issue 8's coastlines).

A coastline's spikes and inlets are a fraction of h long: the walls of a sharp corner end at
polygon vertices before the tip's grading does, and the mouth where they end is narrower than
the boundary around it.  The tip triangle should still be the best the angle allows (an
isosceles triangle) and nothing around the mouth worse than that.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import injmesh
from conftest import assert_valid_mesh
from injmesh import Polygon
from injmesh.boundary import corner_spacing, mesh_boundary
from injmesh.sizing import as_size_function


def _bound(degrees: float) -> float:
    """The best q of the triangles in a corner of this angle: a fan of k equal wedges."""
    best = 0.0
    for k in range(1, 8):
        a = math.radians(degrees / k)
        best = max(best, 8 * math.sin(a / 2) * math.sin((math.pi - a) / 4) ** 2)
    return best


def _spike(degrees: float, short: float, long: float) -> Polygon:
    """The unit square with a spike of the given angle on its top edge: the left wall (of
    length ``short``) ends on the edge, the right one (``long``) goes on into the square."""
    a = math.radians(degrees)
    tip = np.array([0.5, 1.0 + short * math.cos(a / 2)])
    left = tip + short * np.array([-math.sin(a / 2), -math.cos(a / 2)])
    right = tip + long * np.array([math.sin(a / 2), -math.cos(a / 2)])
    return Polygon([(0, 0), (1, 0), (1, 1), tuple(right), tuple(tip), tuple(left), (0, 1)])


def _inlet(degrees: float, depth: float) -> Polygon:
    """The unit square with a narrow wedge of domain going up from its top edge (the sea's
    inlet into land): the wedge's mouth is its width at the edge."""
    w = depth * math.tan(math.radians(degrees) / 2)
    return Polygon([(0, 0), (1, 0), (1, 1), (0.5 + w, 1), (0.5, 1 + depth), (0.5 - w, 1), (0, 1)])


def _mesh(domain: object, h: float) -> injmesh.Mesh:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return injmesh.generate(domain, h)


@pytest.mark.parametrize(("degrees", "short", "long"), [(12.0, 0.03, 0.045), (12.0, 0.02, 0.08),
                                                        (9.0, 0.05, 0.07)])
def test_a_spike_shorter_than_h_gets_an_isosceles_tip(degrees: float, short: float, long: float) -> None:
    """Walls of 0.2-0.7 h, one longer than the other: before, each wall was halved by the
    encroachment splits by its own length, and the tip triangle was 0.15 where 0.37 is
    possible (12 degrees, walls 0.3 and 0.45 h)."""
    spike = _spike(degrees, short, long)
    mesh = _mesh(spike, 0.1)
    assert_valid_mesh(mesh, spike)
    assert mesh.quality().min() >= 0.98 * _bound(degrees)
    # Step 1 puts the nodes of both walls at the same distances from the tip.
    tip = np.asarray(spike.rings[0])[4]
    bnd = mesh_boundary(spike, as_size_function(0.1), np.zeros((0, 2)), max_nodes=10**6)
    r = np.hypot(*(bnd.points - tip).T)
    side = np.sign(bnd.points[:, 0] - tip[0])
    left = np.sort(r[(side < 0) & (r <= short * (1 + 1e-9)) & (r > 0)])
    right = np.sort(r[(side > 0) & (r <= short * (1 + 1e-9))])
    assert len(left) >= 1 and np.allclose(left, right, rtol=1e-9)


@pytest.mark.parametrize(("degrees", "depth"), [(7.5, 0.025), (10.0, 0.06)])
def test_a_narrow_inlet_is_as_good_as_its_tip_allows(degrees: float, depth: float) -> None:
    """An inlet of domain 0.03-0.1 h wide at its mouth: the boundary around the mouth, laid at
    h, made slivers with the mouth's edge (q 0.16 on the coastline's 7.5-degree inlet; here
    0.19 and 0.25).  The mouth's two corners face each other across it, so its width is their
    spacing, and the size grows from it."""
    inlet = _inlet(degrees, depth)
    mesh = _mesh(inlet, 0.1)
    assert_valid_mesh(mesh, inlet)
    assert mesh.quality().min() >= 0.98 * _bound(degrees)


def test_corners_facing_each_other_across_the_domain_are_spaced_by_that_gap() -> None:
    inlet = _inlet(7.5, 0.025)  # mouth 0.0033 wide, walls 0.025 long
    width = 2 * 0.025 * math.tan(math.radians(7.5) / 2)
    corners = np.asarray(inlet.rings[0])[[3, 5]]
    pts, spacing = corner_spacing(inlet, as_size_function(0.1))
    mouth = np.any(np.all(pts[:, None, :] == corners[None], axis=2), axis=1)
    assert mouth.sum() >= 2 and np.allclose(spacing[mouth], width)  # (a corner may be listed twice)
    # A notch of the outside as narrow: corners close across the outside keep their spacing
    # along the boundary (the notch's wall).
    notch = Polygon([(0, 0), (1, 0), (1, 1), (0.5 + width / 2, 1), (0.5, 0.975), (0.5 - width / 2, 1),
                     (0, 1)])
    corners = np.asarray(notch.rings[0])[[3, 5]]
    pts, spacing = corner_spacing(notch, as_size_function(0.1))
    mouth = np.any(np.all(pts[:, None, :] == corners[None], axis=2), axis=1)
    assert mouth.sum() == 2 and np.all(spacing[mouth] > 0.02)


def test_a_small_coastline_meshes_to_its_sharpest_corners_bound() -> None:
    """A 300-vertex coastline with an island, straits narrower than h: its 21-degree spike
    (walls 0.63 and 0.69 h) gave q 0.18 where 0.60 is possible; deterministic."""
    from injmesh import shapes
    from injmesh.inputs import read_geojson
    from injmesh.shapes import interior_angles

    h = 0.06
    shape = shapes.coastline(5, n_vertices=300, n_islands=1, island_vertices=40, strait=h)
    domain = read_geojson(shapes.to_geojson(shape))
    mesh = _mesh(domain, h)
    assert mesh.stats.valid and not mesh.stats.cleaning
    sharpest = min(float(interior_angles(np.asarray(r)).min()) for r in shape.rings)
    assert mesh.quality().min() >= 0.98 * _bound(sharpest)
    again = _mesh(domain, h)
    assert np.array_equal(mesh.points, again.points) and np.array_equal(mesh.triangles, again.triangles)
