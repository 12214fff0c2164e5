"""Local feature size and the effective size the pipeline follows.

Invariants: a channel of width w has feature size ~w across its whole width, whatever its
orientation; a thick region's convex corners do not make it thin; spikes and necks do; the floor
holds; ``effective_size`` is h itself where nothing needs correcting, and at most
feature_size / layers and gradation-limited where something does.
"""

from __future__ import annotations

from itertools import product

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import injmesh
from injmesh import Circle, Polygon, Rectangle, SizeError
from injmesh.sizing import GriddedSize, effective_size, feature_size


def rotate(points, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.asarray(points, dtype=float) @ np.array([[c, s], [-s, c]])


def inside_nodes(g: GriddedSize, domain) -> tuple[np.ndarray, np.ndarray]:
    X, Y = np.meshgrid(g.x, g.y)
    p = np.stack([X.ravel(), Y.ravel()], axis=1)
    keep = domain.sdf(p) <= 0
    return p[keep], g.values.ravel()[keep]


@pytest.mark.parametrize("angle", [0.0, 0.5, np.pi / 4])
def test_channel_width_across_the_whole_width(angle: float) -> None:
    w = 0.2
    channel = Polygon(rotate([(0, 0), (4, 0), (4, w), (0, w)], angle))
    fs = feature_size(channel)
    across = np.linspace(0, w, 21)
    for along in (0.5, 2.0, 3.5):
        q = rotate(np.stack([np.full_like(across, along), across], axis=1), angle)
        assert np.all(np.abs(fs(q) / w - 1) < 0.08), fs(q)


def test_square_corners_do_not_make_it_thin() -> None:
    square = Rectangle((0, 0), (1, 1))
    fs = feature_size(square)
    _, values = inside_nodes(fs, square)
    assert values.min() > 0.95  # about the side everywhere, corners included
    assert fs(np.array([[0.0, 0.0], [1.0, 1.0], [0.01, 0.99]])).min() > 0.95


@pytest.mark.parametrize(
    ("domain", "thickness"),
    [
        (Polygon([(0, 0), (1, 0), (0.5, np.sqrt(3) / 2)]), 0.8),  # 60-degree corners
        (Rectangle((0, 0), (2, 1)), 1.0),
        (Polygon([(0, 0), (2, 0), (2, 2), (1, 2), (1, 1), (0, 1)]), 1.0),  # L-shape, arms 1 wide
    ],
)
def test_thick_regions_are_not_thin_anywhere(domain, thickness: float) -> None:
    fs = feature_size(domain)
    _, values = inside_nodes(fs, domain)
    assert values.min() > 0.95 * thickness


def test_disc_and_annulus() -> None:
    disc = Circle((0, 0), 1)
    _, values = inside_nodes(feature_size(disc), disc)
    assert np.all(np.abs(values / 2 - 1) < 0.05)
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.6)
    _, values = inside_nodes(feature_size(ring), ring)
    assert np.all(np.abs(values / 0.4 - 1) < 0.08)


def test_spike_and_neck_count() -> None:
    spike = Polygon([(0, 0), (1, 0), (1, 0.475), (2, 0.49), (2, 0.51), (1, 0.525), (1, 1), (0, 1)])
    fs = feature_size(spike)
    width = lambda x: 0.05 - 0.03 * (x - 1)  # noqa: E731
    xs = np.array([1.2, 1.5, 1.8])
    assert np.all(np.abs(fs(np.stack([xs, np.full(3, 0.5)], axis=1)) - width(xs)) < 0.01)
    assert fs(np.array([[0.5, 0.5]]))[0] > 0.9
    neck = Rectangle((0, 0), (1, 1)) | Rectangle((1, 0.47), (1.5, 0.53)) | Rectangle((1.5, 0), (2.5, 1))
    fs = feature_size(neck)
    assert np.all(np.abs(fs(np.array([[1.25, 0.5], [1.25, 0.475], [1.1, 0.52]])) - 0.06) < 0.01)
    assert fs(np.array([[0.3, 0.5]]))[0] > 0.9


def test_sharp_wedge_counts_and_floor_holds() -> None:
    wedge = Polygon([(0, 0), (1, -0.09), (1, 0.09)])  # about 10 degrees
    fs = feature_size(wedge, min_size=0.01)
    x = np.array([0.3, 0.6, 0.9])
    assert np.all(np.abs(fs(np.stack([x, 0 * x], axis=1)) - 0.18 * x) < 0.01)
    assert fs.values.min() >= 0.01


def test_plain_callable_matches_the_primitive() -> None:
    d = lambda p: np.maximum(np.abs(p[:, 0] - 1) - 1, np.abs(p[:, 1] - 0.1) - 0.1)  # noqa: E731
    fs = feature_size(d, bbox=(0, 0, 2, 0.2))
    q = np.array([[1.0, 0.1], [1.0, 0.0], [1.0, 0.2], [0.5, 0.05]])
    assert np.all(np.abs(fs(q) - 0.2) < 0.01)


def test_feature_size_is_deterministic() -> None:
    dom = Circle((0, 0), 1) - Circle((0.3, 0), 0.5)
    assert np.array_equal(feature_size(dom).values, feature_size(dom).values)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"min_size": 0}, "min_size must be positive"),
        ({"min_size": "1"}, "min_size must be a positive number"),
        ({"corner_angle": 200}, "below 180"),
        ({"spacing": -1}, "spacing must be a positive"),
    ],
)
def test_feature_size_bad_options(kwargs: dict, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        feature_size(Rectangle((0, 0), (1, 1)), **kwargs)


def test_effective_size_is_h_itself_when_nothing_needs_correcting() -> None:
    case = injmesh.cases.CASES["circle_with_hole"]
    h = effective_size(case.size, case.geometry)
    p = np.random.default_rng(0).uniform(-1, 1, (500, 2))
    p = p[case.geometry.sdf(p) <= 0]
    assert np.array_equal(h(p), case.size(p))


def test_effective_size_in_a_channel() -> None:
    w = 0.1
    channel = Rectangle((0, 0), (2, w))
    h = effective_size(0.2, channel, layers=2)
    q = np.stack([np.linspace(0.2, 1.8, 50), np.linspace(0, w, 50)], axis=1)
    assert np.all(h(q) <= w / 2 * 1.08)
    h3 = effective_size(0.2, channel, layers=3)
    assert np.all(h3(q) <= w / 3 * 1.08)


def test_effective_size_limits_gradation_from_a_neck() -> None:
    neck = Rectangle((0, 0), (1, 1)) | Rectangle((1, 0.47), (1.5, 0.53)) | Rectangle((1.5, 0), (2.5, 1))
    h = effective_size(0.2, neck, rate=0.2)
    field = h.function
    assert isinstance(field, GriddedSize)
    p, values = inside_nodes(field, neck)
    assert values.max() == pytest.approx(0.2)
    assert values.min() <= 0.031
    # Moving away from the neck the size grows at most at the rate.
    a, b = np.array([[1.25, 0.5]]), np.array([[0.6, 0.5]])
    assert h(b)[0] - h(a)[0] <= 0.2 * 0.65 * 1.05


def test_effective_size_only_asks_h_inside() -> None:
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
    seen: list[np.ndarray] = []

    def h(p: np.ndarray) -> np.ndarray:
        seen.append(p.copy())
        return 0.05 + 0.3 * (np.hypot(p[:, 0], p[:, 1]) - 0.5)

    size = effective_size(h, ring)
    size(np.array([[0.0, 0.0], [3.0, 3.0], [0.75, 0.0]]))
    assert ring.sdf(np.concatenate(seen)).max() <= 1e-6 * ring.diameter


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"layers": 0}, "layers must be positive"), ({"rate": -1}, "rate must be positive")],
)
def test_effective_size_bad_options(kwargs: dict, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        effective_size(0.1, Rectangle((0, 0), (1, 1)), **kwargs)


def test_thin_channel_meshes_with_layers_across() -> None:
    """h = 0.25 in a 0.08-wide channel: slivers without the feature size, sound elements with it."""
    channel = Rectangle((0, 0), (1.5, 0.08))
    mesh = injmesh.generate(channel, effective_size(0.25, channel))
    assert mesh.quality().min() > 0.6
    # At least two elements across: some interior node off the walls.
    y = mesh.points[:, 1]
    assert np.any((y > 0.01) & (y < 0.07))


def test_feature_size_is_scale_and_translation_invariant() -> None:
    pts = [(0, 0), (1, 0), (1, 0.475), (2, 0.49), (2, 0.51), (1, 0.525), (1, 1), (0, 1)]
    base = feature_size(Polygon(pts))
    q = np.array([[1.2, 0.5], [1.5, 0.5], [0.5, 0.5], [0.02, 0.02]])
    scaled = feature_size(Polygon(np.asarray(pts) * 1024.0))
    assert np.allclose(scaled(q * 1024.0), 1024.0 * base(q), rtol=1e-9)
    # Far from the origin: the thin part is measured the same; in the thick part the medial
    # axis of the square is one point, seen or not depending on rounding, and the feature size
    # is only known to be thick (missing a medial-axis node can only raise it).
    offset = np.array([1e6, -3e5])
    moved = feature_size(Polygon(np.asarray(pts) + offset))
    assert np.allclose(moved(q[:2] + offset), base(q[:2]), rtol=1e-4)
    assert np.all(moved(q[2:] + offset) > 0.95)


def test_a_strait_thinner_than_the_grid_refines_it() -> None:
    """A 0.015-wide strait between two lobes holds no node of the default grid (spacing ~0.02):
    the facing walls are found on the boundary and the grid is refined to resolve it."""
    strait = Polygon([(0, 0), (2, 0), (2, 0.9925), (2.3, 0.9925), (2.3, 0), (4.3, 0), (4.3, 2), (2.3, 2),
                      (2.3, 1.0075), (2, 1.0075), (2, 2), (0, 2)])
    fs = feature_size(strait)
    assert fs.spacing[0] <= 0.015 / 2
    assert fs(np.array([[2.15, 1.0]]))[0] == pytest.approx(0.015, rel=0.1)
    assert fs(np.array([[1.0, 1.0]]))[0] > 1.9


# --- the boundary test that lets effective_size skip the grid -------------------------------


def _feature_term_changes_nothing(domain, size, layers: float = 2.0, angle: float = 30.0) -> bool:
    """The grid computation effective_size skips: is feature_size / layers >= h at every node?"""
    from injmesh.sizing.background import sample_size, sampled_grid
    from injmesh.sizing.features import FEATURE_CELLS, feature_grid, refine_for_gaps

    h = injmesh.sizing.as_size_function(size)
    grid, h0 = sampled_grid(h, domain, None, 10**6, 0.2, domain.diameter / FEATURE_CELLS)
    finer = refine_for_gaps(domain, grid, angle, 10**6)
    if finer is not grid:
        grid, h0 = finer, sample_size(h, domain, finer, 0.2)
    fs = feature_grid(domain, grid, 2.0 * grid.spacing, angle)
    inside = grid.inside
    return bool(np.all(fs[inside] / layers >= h0[inside] * (1 - 1e-12)))


def _claims_thick(domain, size) -> bool:
    from injmesh.sizing.background import sampled_grid
    from injmesh.sizing.features import FEATURE_CELLS, _thick, _thick_uniform

    h = injmesh.sizing.as_size_function(size)
    if h.constant is not None:
        return _thick_uniform(domain, h.constant, 2.0, 30.0)
    grid, h0 = sampled_grid(h, domain, None, 10**6, 0.2, domain.diameter / FEATURE_CELLS)
    return _thick(domain, float(h0[grid.inside].max()), 2.0, 30.0, grid.spacing, h.restricted(domain))


def _thick_cases():
    from injmesh import shapes
    from injmesh.cases import CASES

    out = [pytest.param(c.geometry, c.size, id=name) for name, c in CASES.items()]
    for fam, seed, factor in [("star", 0, 0.25), ("star", 1, 0.5), ("holes", 2, 0.25), ("walk", 3, 0.25),
                              ("plates", 0, 1.0), ("airfoil", 3, 0.25), ("neck", 1, 0.25)]:
        shape = shapes.FAMILIES[fam](seed)
        out.append(pytest.param(shape.domain(), factor * shape.size, id=f"{fam}{seed}x{factor}"))
    out.append(pytest.param(Rectangle((0, 0), (1, 1)), 0.3, id="square-coarse"))
    out.append(pytest.param(Circle((0, 0), 1) - Circle((0.55, 0), 0.3), 0.05, id="eccentric-hole"))
    # Exactly two elements across: the feature size equals 2 h there, a tie that counts as thick.
    out.append(pytest.param(Rectangle((0, 0), (2, 0.1)), 0.05, id="channel-tie"))
    out.append(pytest.param(Rectangle((0, 0), (2, 0.1)), lambda p: 0.03 + 0.02 * p[:, 1] / 0.1,
                            id="channel-tie-graded"))
    return out


@pytest.mark.parametrize("domain, size", _thick_cases())
def test_thick_claim_implies_the_feature_size_changes_nothing(domain, size) -> None:
    """Where the boundary test lets effective_size skip the feature-size grid, the grid would
    not have lowered h anywhere (the claim may be False where the grid finds nothing: slower,
    never wrong)."""
    if _claims_thick(domain, size):
        assert _feature_term_changes_nothing(domain, size)


@pytest.mark.parametrize(
    "domain, size",
    [
        (Rectangle((0, 0), (2, 0.1)), 0.06),  # a channel under two elements wide
        (Polygon([(0, 0), (1, 0), (1, 0.45), (0.55, 0.5), (1, 0.55), (1, 1), (0, 1)]), 0.05),  # a notch
        (Polygon([(0, 0), (1, 0), (0, 0.2)]), 0.02),  # a sharp wedge (11 degrees)
        (Rectangle((0, 0), (1, 1)) - Rectangle((0.2, 0.5), (0.8, 0.5005)), 0.05),  # a slit-like hole
        (Rectangle((0, 0), (1, 1)), 0.6),  # h larger than half the width
    ],
    ids=["channel", "notch", "wedge", "slit", "coarse"],
)
def test_thin_parts_are_not_claimed_thick(domain, size) -> None:
    assert not _claims_thick(domain, size)


def test_uniform_size_on_a_thick_domain_needs_no_grid(monkeypatch) -> None:
    """No background grid at all: effective_size returns h restricted to the domain."""
    import injmesh.sizing.features as features

    def no_grid(*args, **kwargs):
        raise AssertionError("the background grid was built")

    monkeypatch.setattr(features, "sampled_grid", no_grid)
    square = Rectangle((0, 0), (1, 1))
    h = effective_size(0.01, square)
    assert h.domain is square and h.constant == 0.01


def test_no_feature_layers_means_gradation_only() -> None:
    jump = lambda p: np.where(p[:, 0] < 0.5, 0.02, 0.2)  # noqa: E731
    channel = Rectangle((0, 0), (2, 0.1))
    h = effective_size(jump, channel, layers=None)
    # Limited from the jump, not lowered by the channel's width (0.1 / 2).
    assert h(np.array([[1.9, 0.05]]))[0] > 0.1
    mesh = injmesh.generate(Rectangle((0, 0), (1, 1)), 0.2, feature_layers=None)
    assert mesh.n_points > 0


@pytest.mark.parametrize("name", ["unit_disc", "square_with_hole", "l_shape", "square_with_four_holes"])
def test_paper_cases_are_claimed_thick(name: str) -> None:
    """The paper's cases have no thin part at their sizes: effective_size skips the feature grid
    (the four-hole square's holes are exactly 2 h from its sides: a tie, thick)."""
    from injmesh.cases import CASES

    case = CASES[name]
    assert _claims_thick(case.geometry, case.size)


def test_thin_feature_size_skips_only_parts_that_are_thick_for_h() -> None:
    """A part no two of whose walls face each other within a few h needs no feature grid
    (None); a thin part gets the grid, and it agrees with feature_size; a variable h is
    bounded by its sample."""
    from injmesh.sizing.features import thin_feature_size

    disc = Circle((0.0, 0.0), 1.0)
    assert thin_feature_size(disc, 0.1, 2.0) is None
    assert thin_feature_size(disc, lambda p: 0.05 + 0.05 * np.hypot(p[:, 0], p[:, 1]), 2.0) is None
    # The same disc for an h of its own size: thinner than two layers.
    fs = thin_feature_size(disc, 1.5, 2.0)
    assert isinstance(fs, GriddedSize)
    centre = np.array([[0.0, 0.0]])
    assert abs(fs(centre)[0] - feature_size(disc)(centre)[0]) < 1e-12
    strip = Rectangle((0.0, 0.0), (4.0, 0.2))
    assert isinstance(thin_feature_size(strip, 0.12, 2.0), GriddedSize)
    assert thin_feature_size(strip, 0.01, 2.0) is None


def _full_search_thick(monkeypatch, domain, width, needed, back_to_back) -> bool:
    """thick_everywhere as it was before the narrow first search: one search at the full
    width plus ``step``, ``needed`` asked at every facing pair at once."""
    import injmesh.sizing.features as features

    with monkeypatch.context() as m:
        m.setattr(features, "_pair_reach", lambda v, seg_len, step, width: step)
        m.setattr(features, "THICK_QUICK", ())
        m.setattr(features, "THICK_BATCH", 10**9)
        return features.thick_everywhere(domain, width, 30.0, needed, back_to_back=back_to_back)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_narrow_first_search_answers_as_the_full_one(monkeypatch, seed: int) -> None:
    """The narrow search and the batches of ``needed`` only shortcut a False: the answer is that
    of the full search, on outlines whose facing walls lie below, within and above the narrow
    width, with uniform and varying ``needed``, with and without back-to-back walls."""
    from injmesh import shapes
    from injmesh.sizing.features import THICK_QUICK, thick_everywhere

    answers = set()
    for domain, width in product(
        (shapes.FAMILIES["neck"](seed).domain(),
         shapes.coastline(seed, n_vertices=300, n_islands=2, strait=0.05).domain()),
        (0.02, 0.06, 0.12, 0.3),
    ):
        for scale in (0.2, 0.5, 0.9):
            for needed in (
                lambda p, s=scale, w=width: np.full(len(p), s * w),
                lambda p, s=scale, w=width: s * w * (0.6 + 0.4 * np.sin(7 * p[:, 0]) ** 2),
            ):
                for back in (0.0, 0.01, 1.5 * width):
                    got = thick_everywhere(domain, width, 30.0, needed, back_to_back=back)
                    assert got == _full_search_thick(monkeypatch, domain, width, needed, back)
                    answers.add(got)
    assert answers == {True, False}
    assert min(THICK_QUICK) > 1


def test_walls_beyond_the_narrow_width_still_count(monkeypatch) -> None:
    """A channel wider than the narrow search's width but narrower than ``needed``: the narrow
    search finds nothing and the full one decides."""
    import injmesh.sizing.features as features

    channel = Rectangle((0, 0), (4, 0.2))
    width = 0.3
    assert 0.2 > width / min(features.THICK_QUICK)
    searched = []
    walls = features._outline()
    original = walls.facing_walls

    def spy(*args):
        searched.append(args[7])  # the width searched
        return original(*args)

    monkeypatch.setattr(walls, "facing_walls", spy)
    assert not features.thick_everywhere(channel, width, 30.0, lambda p: np.full(len(p), 0.25))
    assert searched == [*(width / d for d in features.THICK_QUICK), width]
    searched.clear()
    assert features.thick_everywhere(channel, width, 30.0, lambda p: np.full(len(p), 0.15))
    assert searched == [*(width / d for d in features.THICK_QUICK), width]


def test_a_thin_detailed_outline_asks_needed_at_few_points() -> None:
    """On a detailed outline with necks far below the width, the narrow search and the first
    batch settle it: ``needed`` is asked at five points of a few pairs, not at every pair."""
    from injmesh import shapes
    from injmesh.sizing.features import THICK_BATCH, thick_everywhere

    domain = shapes.large(0, n_vertices=2000).domain()
    asked = []

    def needed(p):
        asked.append(len(p))
        return np.full(len(p), 0.05)

    assert not thick_everywhere(domain, 0.06, 30.0, needed)
    assert sum(asked) <= 5 * THICK_BATCH


@pytest.mark.parametrize("seed", [0, 1])
def test_facing_pairs_lie_within_the_width_plus_the_longest_segment(seed: int) -> None:
    """The kernel finds the same facing and back-to-back pairs when it looks for partners within
    the width plus the longest segment (``_pair_reach``) as within the width plus ``step``."""
    import math

    from injmesh import shapes
    from injmesh.kernels.outline import facing_walls
    from injmesh.sizing.background import densify
    from injmesh.sizing.features import _pair_reach, wall_frames

    # A detailed outline (segments much shorter than the larger steps) and a coarse one.
    rings = [shapes.large(seed, n_vertices=2000).rings[0],
             shapes.coastline(seed, n_vertices=400, n_islands=0, strait=0.05).rings[0]]
    cos = math.cos(math.radians(40.0))
    shorter, found = 0, 0
    for ring, step in product(rings, (0.002, 0.01, 0.05)):
        # Far from the origin too: the margin must cover the rounding of large coordinates.
        for offset in (0.0, 1e4):
            v = densify(np.ascontiguousarray(ring, dtype=float) + offset, step)
            n = len(v)
            idx = np.arange(n)
            nxt, prv = (idx + 1) % n, (idx - 1) % n
            seg, seg_len, v_n, seg_n = wall_frames(v, nxt, prv)
            for width, back in ((4 * step, 0.0), (4 * step, step), (step, 0.0)):
                reach = _pair_reach(v, seg_len, step, width)
                assert reach <= step
                wide = facing_walls(v, prv, seg, seg_len, v_n, seg_n, max(width, back) + step,
                                    width, back, cos, False)
                tight = facing_walls(v, prv, seg, seg_len, v_n, seg_n, max(width, back) + reach,
                                     width, back, cos, False)
                assert wide[0] == tight[0]
                as_set = [{(int(i), float(x), float(y), float(d)) for i, (x, y), d in
                           zip(r[1], r[2], r[3], strict=True)} for r in (wide, tight)]
                assert as_set[0] == as_set[1]
                shorter += reach < 0.5 * step
                found += len(as_set[0]) > 0
    assert shorter > 0 and found > 0


def _nearest_reference(p, seg_a, seg_b, prev):
    """``_nearest_on_boundary`` as it was: the default k-d tree's three nearest vertices."""
    from scipy.spatial import cKDTree

    _, near = cKDTree(seg_a).query(p, k=3)
    return _segments_reference(p, np.concatenate([near, prev[near]], axis=1), seg_a, seg_b)


def _segments_reference(p, cand, seg_a, seg_b):
    """The nearest of the candidate segments, in NumPy: foot a + t (b - a), t clamped."""
    a, b = seg_a[cand], seg_b[cand]
    ab = b - a
    L2 = np.maximum(np.einsum("nkj,nkj->nk", ab, ab), np.finfo(float).tiny)
    t = np.clip(np.einsum("nkj,nkj->nk", p[:, None, :] - a, ab) / L2, 0.0, 1.0)
    foot = a + t[..., None] * ab
    dist = np.hypot(*(p[:, None, :] - foot).transpose(2, 0, 1))
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(p))
    return dist[rows, best], foot[rows, best]


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.integers(3, 60), st.integers(1, 200), st.integers(1, 8),
       st.booleans())
def test_nearest_of_segments_is_the_numpy_form(seed: int, m: int, n: int, c: int, flat: bool) -> None:
    """The compiled nearest-of-candidates gives the NumPy form's distances and feet bit for
    bit (first candidate on ties), zero-length segments included."""
    from injmesh.kernels.outline import nearest_of_segments

    rng = np.random.default_rng(seed)
    seg_a = rng.random((m, 2))
    seg_b = np.roll(seg_a, -1, axis=0)
    if flat:
        seg_b[0] = seg_a[0]
    p = rng.random((n, 2)) * 1.5 - 0.25
    cand = rng.integers(0, m, (n, c))
    cand[:, -1] = cand[:, 0]  # a repeated candidate: a tie
    d, f = nearest_of_segments(p, cand, seg_a, seg_b)
    d_ref, f_ref = _segments_reference(p, cand, seg_a, seg_b)
    assert np.array_equal(d, d_ref) and np.array_equal(f, f_ref)


@pytest.mark.parametrize("name", ["plates", "square", "large"])
def test_nearest_boundary_points_are_those_of_the_default_tree(name: str) -> None:
    """The faster tree gives the same nearest boundary points, also where several vertices are
    equally far (grid nodes against grid-aligned walls, where the order of equidistant vertices
    depends on the tree)."""
    from scipy.spatial import cKDTree

    from injmesh import shapes
    from injmesh.sizing.background import make_background
    from injmesh.sizing.features import _boundary, _nearest_on_boundary

    domain = {"plates": shapes.FAMILIES["plates"](1).domain(), "square": Rectangle((0, 0), (1, 1)),
              "large": shapes.large(0, n_vertices=2000).domain()}[name]
    grid = make_background(domain, domain.diameter / 200)
    seg_a, seg_b, prev = _boundary(domain, grid)
    p = grid.nodes(grid.inside | grid.band)
    dist, foot = _nearest_on_boundary(p, seg_a, seg_b, prev)
    ref_dist, ref_foot = _nearest_reference(p, seg_a, seg_b, prev)
    assert np.array_equal(dist, ref_dist) and np.array_equal(foot, ref_foot)
    if name != "large":  # the case the fallback is for does occur
        d = cKDTree(seg_a).query(p, k=4)[0]
        assert np.any(d[:, 1:] == d[:, :-1])


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 120), st.integers(0, 300),
       st.sampled_from(["random", "grid", "ring"]), st.floats(0.05, 50.0))
def test_nearest_vertices_are_exact(seed: int, n: int, m: int, layout: str, cell: float) -> None:
    """The compiled search's k nearest vertices, where it answers (``clear``), are the exact
    k nearest in order of distance, whatever the cell size; it leaves to the caller the
    points with (nearly) equal distances and those beyond its rings; and the feature grid's
    nearest points through it are those of the default k-d tree, ties and far points
    included."""
    from injmesh.kernels.feature import nearest_vertices
    from injmesh.sizing.features import NEAREST_RINGS, NEAREST_TIE, _nearest_on_boundary

    rng = np.random.default_rng(seed)
    if layout == "grid":  # equidistant vertices: ties
        v = np.round(rng.random((n, 2)) * 8) / 8
    elif layout == "ring":
        t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        v = np.stack([np.cos(t), np.sin(t)], axis=1)
    else:
        v = rng.normal(size=(n, 2))
    p = rng.uniform(v.min(axis=0) - 2, v.max(axis=0) + 2, (m, 2))
    if layout == "grid":
        p = np.round(p * 16) / 16
    p = np.concatenate([p, v[: min(n, 10)]])  # points on vertices: distance zero
    k = min(3, n)
    size = cell * float(np.ptp(v, axis=0).max() + 1e-3) / 20
    near, status = nearest_vertices(p, v, k, size, NEAREST_TIE, NEAREST_RINGS)
    clear = status == 0
    d2 = ((p[:, None, :] - v[None, :, :]) ** 2).sum(axis=2)
    order = np.argsort(d2, axis=1, kind="stable")[:, :k]
    assert np.array_equal(near[clear], order[clear])
    kq = min(k + 1, n)
    srt = np.sort(d2, axis=1)[:, :kq]
    tied = np.any(srt[:, 1:] == srt[:, :-1], axis=1)
    assert not np.any(clear & tied)
    seg_b = np.roll(v, -1, axis=0)
    prev = (np.arange(n) - 1) % n
    dist, foot = _nearest_on_boundary(p, v, seg_b, prev)
    ref_dist, ref_foot = _nearest_reference_k(p, v, seg_b, prev, k)
    assert np.array_equal(dist, ref_dist) and np.array_equal(foot, ref_foot)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.integers(4, 80), st.integers(1, 200), st.booleans())
def test_nearest_feet_answer_ties_only_where_the_order_cannot_matter(seed: int, n: int, m: int,
                                                                     grid: bool) -> None:
    """Where the compiled search answers a point whose nearest vertices are (nearly) equally
    far, the answer is the same for every order of them: the three nearest by squared
    distance with ties broken either way (lowest or highest index first) give it bit for
    bit; elsewhere it is the plain nearest-of-segments answer."""
    from injmesh.kernels.feature import nearest_feet, nearest_vertices
    from injmesh.kernels.outline import nearest_of_segments
    from injmesh.sizing.features import NEAREST_RINGS, NEAREST_TIE

    rng = np.random.default_rng(seed)
    t = np.sort(rng.random(n)) * 2 * np.pi
    v = np.stack([np.cos(t), np.sin(t)], axis=1)
    p = rng.uniform(-1.2, 1.2, (m, 2))
    if grid:  # a square's walls and grid nodes: equidistant vertices
        side = np.arange(n) / n
        v = np.concatenate([np.stack([side, 0 * side], 1), np.stack([1 + 0 * side, side], 1),
                            np.stack([1 - side, 1 + 0 * side], 1), np.stack([0 * side, 1 - side], 1)])
        p = np.round(rng.uniform(-0.2, 1.2, (m, 2)) * n) / n
    v = np.ascontiguousarray(v)
    seg_b = np.ascontiguousarray(np.roll(v, -1, axis=0))
    prev = (np.arange(len(v)) - 1) % len(v)
    size = 2.0 / np.sqrt(len(v))
    dist, foot, status = nearest_feet(p, v, seg_b, prev, 3, size, NEAREST_TIE, NEAREST_RINGS)
    _, old_status = nearest_vertices(p, v, 3, size, NEAREST_TIE, NEAREST_RINGS)
    assert np.all((status == 0) | (status == old_status))
    d2 = ((p[:, None, :] - v[None, :, :]) ** 2).sum(axis=2)
    idx = np.arange(len(v))[None, :].repeat(len(p), 0)
    for near in (np.lexsort((idx, d2))[:, :3], np.lexsort((-idx, d2))[:, :3]):
        d, f = nearest_of_segments(p, np.concatenate([near, prev[near]], axis=1), v, seg_b)
        ok = status == 0
        assert np.array_equal(d[ok], dist[ok]) and np.array_equal(f[ok], foot[ok])


def test_nearest_feet_settle_most_ties_of_straight_walls() -> None:
    """Grid nodes against the paper's four-hole square (walls traced on the grid, then
    projected): the vertex a node projects onto and its two equidistant neighbours are the
    three nearest in either order, with one foot; the compiled search answers most of the
    points it used to leave to the tree."""
    from injmesh.cases import CASES
    from injmesh.kernels.feature import nearest_feet, nearest_vertices
    from injmesh.sizing.background import make_background
    from injmesh.sizing.features import NEAREST_RINGS, NEAREST_TIE, _boundary

    domain = CASES["square_with_four_holes"].geometry
    grid = make_background(domain, domain.diameter / 200)
    seg_a, seg_b, prev = _boundary(domain, grid)
    p = grid.nodes(grid.inside | grid.band)
    size = 2.0 / np.sqrt(len(seg_a))
    _, old_status = nearest_vertices(p, seg_a, 3, size, NEAREST_TIE, NEAREST_RINGS)
    _, _, status = nearest_feet(p, seg_a, seg_b, prev.astype(np.int64), 3, size, NEAREST_TIE, NEAREST_RINGS)
    assert np.sum(status == 1) < 0.5 * np.sum(old_status == 1)


def test_feature_values_are_the_numpy_form() -> None:
    """The compiled last step of the feature grid (d_MA to the nearest crossing, 2 (r + d_MA),
    clipped) and its gather of the seeds' feet are the NumPy form's numbers bit for bit."""
    from injmesh.kernels.feature import feature_values, gather_feet

    rng = np.random.default_rng(5)
    ny, nx = 23, 31
    x, y = np.cumsum(rng.random(nx)), np.cumsum(rng.random(ny))
    r = rng.random((ny, nx)) * 3
    axis = rng.random((ny, nx, 2)) * 20
    mj, mi = rng.integers(0, ny, (ny, nx)).astype(np.int32), rng.integers(0, nx, (ny, nx)).astype(np.int32)
    inside = rng.random((ny, nx)) < 0.6
    near = inside | (rng.random((ny, nx)) < 0.2)
    fs = feature_values(x, y, r, axis, mj, mi, inside, near, 0.5, 30.0)
    at = axis[mj, mi]
    d_ma = np.hypot(x[None, :] - at[..., 0], y[:, None] - at[..., 1])
    ref = np.full((ny, nx), np.inf)
    ref[near] = np.clip(2.0 * (np.where(inside[near], r[near], -r[near]) + d_ma[near]), 0.5, 30.0)
    assert np.array_equal(fs, ref)
    assert np.array_equal(gather_feet(axis, mj, mi), axis[mj, mi])


def _nearest_reference_k(p, seg_a, seg_b, prev, k):
    """:func:`_nearest_reference` with ``k`` nearest vertices (fewer than three vertices)."""
    from scipy.spatial import cKDTree

    near = cKDTree(seg_a).query(p, k=k)[1].reshape(len(p), k)
    return _segments_reference(p, np.concatenate([near, prev[near]], axis=1), seg_a, seg_b)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.integers(4, 200), st.floats(0.01, 0.5), st.floats(0.0, 1e-6))
def test_gap_pairs_are_the_numpy_tests(seed: int, n: int, width: float, slack: float) -> None:
    """The compiled first pass of :func:`thinnest_gap` keeps the vertex pairs the NumPy form
    of its tests keeps (each pair once, i < j)."""
    from scipy.spatial import cKDTree

    from injmesh.kernels.feature import gap_pairs
    from injmesh.sizing.features import GAP_DETOUR, _arc_positions

    rng = np.random.default_rng(seed)
    cut = [int(rng.integers(2, n - 1))] if rng.random() < 0.5 else []  # two loops, or one
    v = rng.random((n, 2))
    normal = rng.normal(size=(n, 2))
    normal /= np.hypot(*normal.T)[:, None]
    seg_a = v
    loops = np.split(np.arange(n), cut)
    prev = np.concatenate([np.roll(lp, 1) for lp in loops])
    seg_b = np.concatenate([np.roll(v[lp], -1, axis=0) for lp in loops])
    loop, along, total = _arc_positions(seg_a, seg_b, prev)
    cos = 0.5
    i, j = gap_pairs(v, normal, loop, along, total, width, cos, slack, GAP_DETOUR)
    pairs = cKDTree(v).query_pairs(width * 2, output_type="ndarray")
    a, b = pairs[:, 0], pairs[:, 1]
    dist = np.hypot(*(v[b] - v[a]).T)
    e = (v[b] - v[a]) / np.where(dist > 0, dist, 1.0)[:, None]
    arc = np.abs(along[b] - along[a])
    arc = np.where(loop[b] == loop[a], np.minimum(arc, total[a] - arc), np.inf)
    keep = ((dist > 0) & (dist < width * (1 + slack)) & (np.einsum("kj,kj->k", e, normal[a]) > cos - slack)
            & (-np.einsum("kj,kj->k", e, normal[b]) > cos - slack) & (arc > GAP_DETOUR * dist * (1 - slack)))
    assert {(int(x), int(y)) for x, y in zip(i, j, strict=True)} == {
        (int(x), int(y)) for x, y in zip(a[keep], b[keep], strict=True)}
    assert np.all(i < j)


def _marks_reference(x, y, feet, inside, exact, spacing, jump, limit):
    """The feature grid's medial-axis candidates and marks in NumPy (slices of the grid), as
    ``feature_grid`` computed them before they were compiled."""
    xy = np.stack(np.meshgrid(x, y), axis=-1)
    ny, nx = inside.shape
    pairs = [((slice(0, ny - dj), slice(max(0, -di), nx - max(0, di))),
              (slice(dj, ny), slice(max(0, di), nx + min(0, di))))
             for dj, di in ((0, 1), (1, 0), (1, 1), (1, -1))]
    r0 = np.hypot(*(xy - feet).transpose(2, 0, 1))
    cand = np.zeros(inside.shape, dtype=bool)
    for sa, sb in pairs:
        gap = np.hypot(*(feet[sa] - feet[sb]).transpose(2, 0, 1))
        hit = inside[sa] & inside[sb] & (gap > np.maximum(jump * spacing, 0.5 * np.minimum(r0[sa], r0[sb])))
        cand[sa] |= hit
        cand[sb] |= hit
    grown = cand.copy()
    grown[1:, :] |= cand[:-1, :]
    grown[:-1, :] |= cand[1:, :]
    cand = grown.copy()
    cand[:, 1:] |= grown[:, :-1]
    cand[:, :-1] |= grown[:, 1:]
    todo = cand & inside & ~exact
    r = np.hypot(*(xy - feet).transpose(2, 0, 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where((r > 0)[..., None], (xy - feet) / r[..., None], 0.0)
    deep = inside & (r > 0.5 * spacing)
    marked = np.zeros(inside.shape, dtype=bool)
    axis = np.zeros(inside.shape + (2,))
    for sa, sb in pairs:
        hit = deep[sa] & deep[sb] & (np.einsum("...j,...j->...", unit[sa], unit[sb]) < limit)
        marked[sa] |= hit
        marked[sb] |= hit
        step = xy[sb][hit] - xy[sa][hit]
        grow_a = np.einsum("kj,kj->k", step, unit[sa][hit])
        grow_b = -np.einsum("kj,kj->k", step, unit[sb][hit])
        total = grow_a + grow_b
        t = np.where(total > 0, (r[sb][hit] - r[sa][hit] + grow_b) / np.where(total > 0, total, 1.0), 0.5)
        crossing = xy[sa][hit] + np.clip(t, 0.0, 1.0)[:, None] * step
        for sl in (sa, sb):
            view = axis[sl]
            view[hit] = crossing
            axis[sl] = view
    return todo, marked, r, axis


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.integers(2, 40), st.integers(2, 40), st.floats(0.0, 1.0))
def test_medial_kernels_are_the_numpy_form(seed: int, ny: int, nx: int, snap: float) -> None:
    """The compiled candidates and marks of the feature grid give the NumPy form's nodes,
    distances and crossings bit for bit (random feet, some on the nodes themselves, some
    snapped to a few points so that neighbours share them)."""
    from injmesh.kernels.feature import medial_candidates, medial_marks

    rng = np.random.default_rng(seed)
    x = np.cumsum(np.full(nx, 0.1)) - 0.3
    y = np.cumsum(np.full(ny, 0.1)) + 0.2
    feet = rng.uniform(-0.5, 4.5, (ny, nx, 2))
    few = rng.random((ny, nx)) < snap
    feet[few] = np.round(feet[few])
    on = rng.random((ny, nx)) < 0.05
    gx, gy = np.meshgrid(x, y)
    feet[on] = np.stack([gx[on], gy[on]], axis=1)
    inside = rng.random((ny, nx)) < 0.8
    exact = rng.random((ny, nx)) < 0.3
    limit = -np.cos(np.radians(30.0))
    todo_ref, marked_ref, r_ref, axis_ref = _marks_reference(x, y, feet, inside, exact, 0.1, 2.0, limit)
    todo = medial_candidates(x, y, feet, inside, exact, 0.1, 2.0)
    marked, r, axis = medial_marks(x, y, feet, inside, 0.1, limit)
    assert np.array_equal(todo, todo_ref) and np.array_equal(marked, marked_ref)
    assert np.array_equal(r, r_ref) and np.array_equal(axis, axis_ref)


@settings(max_examples=300, deadline=None)
@given(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3),
       st.sampled_from([0.0, 1e-300, 1e-17, 1e-16, 1e-12, 1e-9, 1e-3]), st.booleans(),
       st.sampled_from([1.0, 1e-140, 1e140]))
def test_longer_is_the_hypot_test(dx: float, dy: float, rel: float, below: bool, scale: float) -> None:
    """The candidates' jump test from the squares, with the hypot where they are too close to
    call: the answer of ``hypot(dx, dy) > length`` (the libm hypot NumPy and the kernels call)
    at lengths within a hair of the hypot."""
    from injmesh.kernels.feature import _longer

    dx, dy = dx * scale, dy * scale
    g = float(np.hypot(dx, dy))
    for length in (g * (1.0 - rel if below else 1.0 + rel), g, np.nextafter(g, 0.0), np.nextafter(g, np.inf)):
        assert _longer(dx, dy, float(length)) == bool(np.hypot(dx, dy) > length)


# --- plain signed distances: the traced boundary stands in for the exact one -----------------


def _plain(domain):
    from injmesh.geometry import as_domain

    return as_domain(domain.sdf, bbox=domain.bbox)


def _claims_thick_plain(domain, size) -> bool:
    """effective_size's test for a plain signed distance: the curves traced on its grid."""
    from injmesh.sizing.background import sampled_grid
    from injmesh.sizing.features import FEATURE_CELLS, _loops, _thick

    h = injmesh.sizing.as_size_function(size)
    grid, h0 = sampled_grid(h, domain, None, 10**6, 0.2, domain.diameter / FEATURE_CELLS)
    return _thick(domain, float(h0[grid.inside].max()), 2.0, 30.0, grid.spacing, h.restricted(domain),
                  _loops(domain, grid))


@pytest.mark.parametrize("domain, size", _thick_cases())
def test_thick_claim_on_traced_loops_implies_the_feature_size_changes_nothing(domain, size) -> None:
    """The same guarantee as for exact boundaries, for the domains given as plain functions."""
    plain = _plain(domain)
    if _claims_thick_plain(plain, size):
        assert _feature_term_changes_nothing(plain, size)


@pytest.mark.parametrize(
    "domain, size",
    [
        (Rectangle((0, 0), (2, 0.1)), 0.05),
        (Polygon([(0, 0), (1, 0), (1, 0.45), (0.55, 0.5), (1, 0.55), (1, 1), (0, 1)]), 0.05),
        (Polygon([(0, 0), (1, 0), (0, 0.2)]), 0.02),
        (Rectangle((0, 0), (1, 1)), 0.6),
    ],
    ids=["channel", "notch", "wedge", "coarse"],
)
def test_thin_plain_domains_are_not_claimed_thick(domain, size) -> None:
    assert not _claims_thick_plain(_plain(domain), size)


@pytest.mark.parametrize("name", ["unit_disc", "square_with_hole", "circle_with_hole",
                                  "two_circles_and_square", "l_shape"])
def test_paper_plain_cases_skip_the_feature_grid(name: str, monkeypatch) -> None:
    """Table 10's plain functions need no feature grid at the paper's sizes (as the composed
    domains), and effective_size returns h itself."""
    import injmesh.sizing.features as features
    from injmesh.cases import CASES

    def no_grid(*args, **kwargs):
        raise AssertionError("the feature grid was computed")

    monkeypatch.setattr(features, "feature_grid", no_grid)
    case = CASES[name]
    h = effective_size(case.size, case.sdf, bbox=case.bbox)
    assert h.function is injmesh.sizing.as_size_function(case.size).function


def test_thinned_loops_keep_corners_and_spacing() -> None:
    from injmesh.sizing.background import densify
    from injmesh.sizing.features import _thinned

    square = densify(Rectangle((0, 0), (1, 1)).boundary_loops(0.001)[0], 0.001)
    kept = _thinned(square, 0.1)
    for corner in [(0, 0), (1, 0), (1, 1), (0, 1)]:
        assert np.hypot(*(kept - corner).T).min() < 1e-12
    gaps = np.hypot(*(np.roll(kept, -1, axis=0) - kept).T)
    assert gaps.max() <= 0.1 + 0.001 + 1e-9 and 36 <= len(kept) <= 48  # a step and a segment


def test_thinnest_gap_first_pass_answers_as_the_neighbour_search(monkeypatch) -> None:
    """With the pairs pass disabled (every pair kept), the neighbour search gives the same gap."""
    import injmesh.sizing.features as features
    from injmesh.sizing.background import resolving_background

    strait = Polygon([(0, 0), (2, 0), (2, 0.9925), (2.3, 0.9925), (2.3, 0), (4.3, 0), (4.3, 2), (2.3, 2),
                      (2.3, 1.0075), (2, 1.0075), (2, 2), (0, 2)])  # 0.015 wide

    def first_pass_never_settles(*args):
        return True

    for domain, expect_finite in [(strait, True), (CASES_GEOMETRY("square_with_four_holes"), False)]:
        grid = resolving_background(domain, domain.diameter / features.FEATURE_CELLS, 10**6, explicit=False)
        gap = features.thinnest_gap(domain, grid, 30.0)
        monkeypatch.setattr(features, "_any_gap", first_pass_never_settles)
        assert features.thinnest_gap(domain, grid, 30.0) == gap
        monkeypatch.undo()
        assert np.isfinite(gap) == expect_finite
        # A boundary of more vertices than GAP_FIRST_PASS_MAX skips the pass: the same answer.
        monkeypatch.setattr(features, "GAP_FIRST_PASS_MAX", 0)
        assert features.thinnest_gap(domain, grid, 30.0) == gap
        monkeypatch.undo()


def CASES_GEOMETRY(name: str):
    from injmesh.cases import CASES

    return CASES[name].geometry
