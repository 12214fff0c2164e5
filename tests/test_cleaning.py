"""Cleaning at a tolerance: near-duplicate vertices, spikes, orientation, reported counts, and
never a silent change of topology."""

from __future__ import annotations

import numpy as np
import pytest

from injmesh import Circle, GeometryError, Implicit, Polygon, Rectangle


def test_near_duplicate_vertices_are_merged_and_reported() -> None:
    # The polygon: two vertices 8e-7 apart (as in GIS data).
    p = Polygon([(0, 0), (1, 0), (1.0000005, 0.0000006), (0.6, 1), (0, 1), (0, 0)])
    q, report = p.cleaned(1e-3 * 0.1)
    assert len(q.vertices) == 4
    assert report["merged_vertices"] == 1
    assert report["zero_length_edges"] == 0  # the closing vertex is notation, not a defect
    assert q.area == pytest.approx(p.area, abs=1e-6)
    # Nothing to do: the same object and zero counts.
    same, again = q.cleaned(1e-4)
    assert same is q and again["merged_vertices"] == again["spikes"] == 0


def test_exact_repeats_and_orientation_are_reported() -> None:
    p = Polygon([(0, 0), (0, 1), (0, 1), (1, 1), (1, 0)])  # clockwise, one repeated vertex
    _, report = p.cleaned(1e-9)
    assert report["zero_length_edges"] == 1
    assert report["reoriented_rings"] == 1


def test_spike_is_removed() -> None:
    ring = [(0, 0), (1, 0), (1, 0.5), (2, 0.5 + 1e-9), (1, 0.5 + 2e-9), (1, 1), (0, 1)]
    q, report = Polygon(ring).cleaned(1e-6)
    assert report["spikes"] == 1
    assert len(q.vertices) == 5
    assert q.area == pytest.approx(1.0)
    assert q.sdf(np.array([[1.5, 0.5]]))[0] > 0.4  # the spike is gone


def test_collapsed_hole_is_dropped_and_counted() -> None:
    shell = [(0, 0), (4, 0), (4, 4), (0, 4)]
    tiny = [(1, 1), (1 + 1e-8, 1), (1, 1 + 1e-8)]
    q, report = Polygon(shell, holes=[tiny, [(2, 2), (3, 2), (3, 3)]]).cleaned(1e-6)
    assert report["dropped_rings"] == 1
    assert len(q.boundary_loops(0.1)) == 2


def test_cleaning_that_would_break_the_polygon_raises() -> None:
    # A notch reaching down to 1.5e-6 above a bump of the bottom edge: merging the bump's two
    # vertices (2.6e-6 apart) lifts the bottom edge through the notch's tip.
    ring = [(0, 0), (1.9999, 0), (2.0, 3e-6), (2.000001, 0), (4, 0), (4, 4), (2.1, 4), (2.0000008, 1.5e-6),
            (1.9, 4), (0, 4)]
    poly = Polygon(ring)
    with pytest.raises(GeometryError, match="would make it invalid: Polygon is not simple"):
        poly.cleaned(1e-5)


def test_shell_collapsing_raises() -> None:
    with pytest.raises(GeometryError, match="collapses"):
        Polygon([(0, 0), (1e-7, 0), (0, 1e-7)]).cleaned(1e-3)


def test_bad_tolerance() -> None:
    with pytest.raises(ValueError, match="tolerance"):
        Polygon([(0, 0), (1, 0), (0, 1)]).cleaned(float("nan"))


def test_other_domains_clean() -> None:
    imp = Implicit(lambda p: np.hypot(p[:, 0], p[:, 1]) - 1, bbox=(-1, -1, 1, 1))
    assert imp.cleaned(1e-3) == (imp, {})
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
    dom, report = ring.cleaned(1e-6)
    assert report == {"short_pieces": 0, "dropped_loops": 0}
    assert dom.sdf(np.array([[0.75, 0.0]]))[0] == pytest.approx(-0.25)
    # A union leaving a near-duplicate vertex: cleaned as a polygon.
    u = Rectangle((0, 0), (1, 1)) | Polygon([(1, 0), (2, 0), (2, 1), (1.0000001, 1), (1, 1)])
    cleaned, report = u.cleaned(1e-5)
    assert isinstance(cleaned, Polygon)
    assert cleaned.area == pytest.approx(2.0)
    # Arcs: a piece shorter than the tolerance is removed and its neighbours meet.
    sliver = Circle((0, 0), 1) - Rectangle((0.999999, -1), (2, 1))
    dom, report = sliver.cleaned(1e-2)
    assert report["short_pieces"] == 1
    assert dom.area == pytest.approx(np.pi, rel=1e-4)
