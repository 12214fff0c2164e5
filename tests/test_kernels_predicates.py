"""The exact predicates against rational arithmetic on near-degenerate inputs."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh.kernels.predicates import incircle, incircle_many, orient2d, orient2d_many


def sign(x: float | Fraction) -> int:
    return int(x > 0) - int(x < 0)


def orient_exact(a, b, c) -> Fraction:  # type: ignore[no-untyped-def]
    ax, ay, bx, by, cx, cy = (Fraction(float(v)) for v in (*a, *b, *c))
    return (ax - cx) * (by - cy) - (ay - cy) * (bx - cx)


def incircle_exact(a, b, c, d) -> Fraction:  # type: ignore[no-untyped-def]
    ax, ay, bx, by, cx, cy, dx, dy = (Fraction(float(v)) for v in (*a, *b, *c, *d))
    adx, ady, bdx, bdy, cdx, cdy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
    return (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )


def nudge(x: float, ulps: int) -> float:
    """x moved by ``ulps`` units in the last place (0 stays 0: its ulp is subnormal)."""
    if abs(x) < 1e-30:
        return x
    for _ in range(abs(ulps)):
        x = float(np.nextafter(x, np.inf if ulps > 0 else -np.inf))
    return x


offsets = st.sampled_from([0.0, 1.0, -3.5e5, 1e9, -1e9, 1e-12])
scales = st.sampled_from([1.0, 1e-3, 1e-9, 1e-20, 1e3])
# The predicates are exact while no product underflows (see the module docstring): keep
# magnitudes above 1e-30 (or exactly 0) so the inputs stay in the documented range.
def _normal(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi).map(lambda v: 0.0 if abs(v) < 1e-30 else v)


unit = _normal(-1.0, 1.0)
ulps = st.integers(-4, 4)


@settings(max_examples=400, deadline=None)
@given(offsets, scales, unit, unit, unit, unit, _normal(-2.0, 3.0), ulps, ulps)
def test_orient2d_on_nearly_collinear_points(off, scale, x0, y0, x1, y1, s, ex, ey) -> None:  # type: ignore[no-untyped-def]
    a = (off + scale * x0, off + scale * y0)
    b = (off + scale * x1, off + scale * y1)
    # c on the line through a and b (rounded), then a few ulps off it.
    c = (nudge(a[0] + s * (b[0] - a[0]), ex), nudge(a[1] + s * (b[1] - a[1]), ey))
    assert sign(orient2d(*a, *b, *c)) == sign(orient_exact(a, b, c))
    # Swapping two points flips the sign; a cyclic shift keeps it.
    assert sign(orient2d(*b, *a, *c)) == -sign(orient_exact(a, b, c))
    assert sign(orient2d(*b, *c, *a)) == sign(orient_exact(a, b, c))


@settings(max_examples=400, deadline=None)
@given(
    offsets,
    scales,
    st.lists(_normal(0.0, 2 * np.pi), min_size=4, max_size=4),
    st.floats(0.1, 10.0),
    ulps,
    ulps,
)
def test_incircle_on_nearly_cocircular_points(off, scale, angles, r, ex, ey) -> None:  # type: ignore[no-untyped-def]
    pts = [(off + scale * r * np.cos(t), off + scale * r * np.sin(t)) for t in angles]
    a, b, c = pts[:3]
    d = (nudge(pts[3][0], ex), nudge(pts[3][1], ey))
    assert sign(incircle(*a, *b, *c, *d)) == sign(incircle_exact(a, b, c, d))


@settings(max_examples=200, deadline=None)
@given(
    st.sampled_from([0.0, 1e9, -7.0, 2.0**40]),
    st.lists(st.integers(-3, 3), min_size=8, max_size=8),
    st.sampled_from([1.0, 0.5, 2.0**-30, 3.0]),
)
def test_lattice_points_give_exact_zeros(off, ints, step) -> None:  # type: ignore[no-untyped-def]
    """Integer lattices (cocircular squares, collinear rows) far from the origin."""
    a, b, c, d = ((off + step * ints[2 * i], off + step * ints[2 * i + 1]) for i in range(4))
    assert sign(orient2d(*a, *b, *c)) == sign(orient_exact(a, b, c))
    assert sign(incircle(*a, *b, *c, *d)) == sign(incircle_exact(a, b, c, d))


def test_known_degenerate_cases() -> None:
    # A unit square's corners are cocircular, also a billion away from the origin.
    for off in (0.0, 1e9, -1e9):
        sq = [(off, off), (off + 1, off), (off + 1, off + 1), (off, off + 1)]
        assert incircle(*sq[0], *sq[1], *sq[2], *sq[3]) == 0.0
        assert orient2d(*sq[0], *sq[1], off + 2.0, off) == 0.0
    # Shewchuk's classic failure of the naive formula: points near (0.5, 0.5) on y = x.
    naive_wrong = 0
    for i in range(64):
        for j in range(64):
            px = nudge(0.5, i)
            py = nudge(0.5, j)
            got = sign(orient2d(px, py, 12.0, 12.0, 24.0, 24.0))
            exact = sign(orient_exact((px, py), (12.0, 12.0), (24.0, 24.0)))
            naive = sign((px - 24.0) * (12.0 - 24.0) - (py - 24.0) * (12.0 - 24.0))
            naive_wrong += naive != exact
            assert got == exact
    assert naive_wrong > 0  # the inputs do defeat plain floating point


def test_vectorised_wrappers_match_scalars() -> None:
    rng = np.random.default_rng(3)
    a, b, c, d = (rng.integers(-2, 3, (200, 2)).astype(float) + 1e9 for _ in range(4))
    o = orient2d_many(a, b, c)
    i = incircle_many(a, b, c, d)
    for k in range(200):
        assert o[k] == orient2d(*a[k], *b[k], *c[k])
        assert i[k] == incircle(*a[k], *b[k], *c[k], *d[k])
        assert sign(o[k]) == sign(orient_exact(a[k], b[k], c[k]))
        assert sign(i[k]) == sign(incircle_exact(a[k], b[k], c[k], d[k]))
