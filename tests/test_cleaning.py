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
    # A union leaving a near-duplicate vertex: merged (by the set operation's snapping here),
    # no edge shorter than the tolerance is left.
    u = Rectangle((0, 0), (1, 1)) | Polygon([(1, 0), (2, 0), (2, 1), (1.0000001, 1), (1, 1)])
    cleaned, report = u.cleaned(1e-5)
    assert cleaned.area == pytest.approx(2.0)
    for loop in cleaned.boundary_loops(10.0):
        assert np.hypot(*(np.roll(loop, -1, axis=0) - loop).T).min() >= 1e-5
    # Segments only, nothing to clean: the set operation's own exact boundary comes back (the
    # stages then reuse what they computed on it); something to clean: a cleaned polygon.
    ell = Rectangle((0, 0), (2, 1)) | Rectangle((0, 0), (1, 2))
    cleaned, report = ell.cleaned(1e-3)
    assert cleaned is ell.exact_brep() and not any(report.values())
    notch = Rectangle((0, 0), (2, 1)) - Polygon([(0.5, 1), (0.5 + 1e-4, 0.5), (0.5 + 2e-4, 1)])
    cleaned, report = notch.cleaned(1e-3)
    assert isinstance(cleaned, Polygon) and any(report.values())
    # Arcs: a piece shorter than the tolerance is removed and its neighbours meet.
    sliver = Circle((0, 0), 1) - Rectangle((0.999999, -1), (2, 1))
    dom, report = sliver.cleaned(1e-2)
    assert report["short_pieces"] == 1
    assert dom.area == pytest.approx(np.pi, rel=1e-4)


# --- pinches: the outline coming back within min_feature of itself ---------------------------

def _with_lobe(side: float, neck: float) -> list[tuple[float, float]]:
    """The unit square with a square lobe of ``side`` on its right, joined by a neck ``neck``
    wide (parallel edges at y = 0.5 and 0.5 + neck)."""
    return [(0, 0), (1, 0), (1, 0.5), (1.1, 0.5), (1.1, 0.5 - side / 2), (1.1 + side, 0.5 - side / 2),
            (1.1 + side, 0.5 + side / 2), (1.1, 0.5 + side / 2), (1.1, 0.5 + neck), (1, 0.5 + neck), (1, 1),
            (0, 1)]


def test_near_self_touch_meshes_validly_and_the_warning_names_the_spot() -> None:
    import injmesh

    h = 0.1
    poly = Polygon(_with_lobe(0.05, h / 1000))  # a neck of h/1000, a lobe smaller than h^2
    with pytest.warns(UserWarning, match=r"1 part\(s\) of the outline .* at \(1, 0\.50005\)"):
        mesh = injmesh.generate(poly, h)
    assert mesh.stats.valid and mesh.stats.cleaning["pinched_parts"] == 1
    assert mesh.points[:, 0].max() <= 1.0 + 1e-9  # the lobe and the neck are gone
    assert mesh.quality().min() > 0.5
    assert float(np.sum(mesh.areas())) == pytest.approx(1.0, rel=1e-6)


def test_pocket_behind_a_narrow_mouth_is_filled() -> None:
    # A square pocket of the outside entered from the right by a slit 1e-5 wide.
    ring = [(0, 0), (1, 0), (1, 0.5), (0.6, 0.5), (0.6, 0.45), (0.5, 0.45), (0.5, 0.55), (0.6, 0.55),
            (0.6, 0.50001), (1, 0.50001), (1, 1), (0, 1)]
    q, report = Polygon(ring).cleaned(1e-6, min_feature=1e-4)
    assert report["pinched_parts"] == 1
    assert q.area == pytest.approx(1.0, abs=1e-5)
    assert q.sdf(np.array([[0.55, 0.5]]))[0] < 0  # the pocket is inside now


def test_hole_almost_touching_the_shell_is_filled() -> None:
    hole = [(0.2, 0.2), (0.5, 0.2), (0.5, 1 - 5e-5), (0.2, 0.5)]
    q, report = Polygon([(0, 0), (1, 0), (1, 1), (0, 1)], holes=[hole]).cleaned(1e-6, min_feature=1e-3)
    assert report["pinched_parts"] == 1 and len(q.rings) == 1
    assert q.dropped_parts[0][:2] == pytest.approx((0.5, 1 - 2.5e-5))


def test_a_part_larger_than_max_area_is_an_error_naming_the_place() -> None:
    import injmesh
    from injmesh import GeometryError as Err

    poly = Polygon(_with_lobe(0.2, 1e-4))  # lobe area 0.04 > h^2 = 0.01
    with pytest.raises(Err, match=r"within 0\.0001 of itself at \(1, 0\.50005\).*min_feature"):
        poly.cleaned(1e-6, min_feature=1e-3, max_area=0.01)
    with pytest.raises(Err, match=r"at \(1, 0\.50005\)"):
        injmesh.generate(poly, 0.1)  # by default: 1 % of h and parts up to h^2
    # Given explicitly, min_feature drops the part whatever its size.
    q, report = poly.cleaned(1e-6, min_feature=1e-3)
    assert report["pinched_parts"] == 1 and q.area == pytest.approx(1.0)


def test_min_feature_zero_and_below_the_gap_keep_the_outline() -> None:
    poly = Polygon(_with_lobe(0.05, 1e-3))
    for width in (0.0, 5e-4):
        q, report = poly.cleaned(1e-6, min_feature=width)
        assert report["pinched_parts"] == 0 and q is poly
    assert poly.cleaned(1e-6, min_feature=2e-3)[1]["pinched_parts"] == 1
    with pytest.raises(ValueError, match="min_feature"):
        poly.cleaned(1e-6, min_feature=-1.0)


def test_sharp_wedges_are_not_pinches() -> None:
    # A 3-degree spike sampled along both walls: its walls are closer than min_feature near the
    # tip, but it narrows steadily to the tip (a wedge, not a neck).
    t = np.linspace(0.0, 1.0, 40)[:-1, None]
    tip = np.array([2.9, 0.5])
    lower = (1 - t) * np.array([1.0, 0.45]) + t * tip
    upper = (1 - t) * np.array([1.0, 0.55]) + t * tip
    ring = np.concatenate([[(0, 0), (1, 0)], lower, [tip], upper[::-1], [(1, 1), (0, 1)]])
    poly = Polygon(ring)
    q, report = poly.cleaned(1e-7, min_feature=0.02)
    assert report["pinched_parts"] == 0 and q is poly


def test_pinched_meshes_are_deterministic() -> None:
    import warnings

    import injmesh

    poly = Polygon(_with_lobe(0.05, 1e-4))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = injmesh.generate(poly, 0.1)
        b = injmesh.generate(Polygon(_with_lobe(0.05, 1e-4)), 0.1)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
