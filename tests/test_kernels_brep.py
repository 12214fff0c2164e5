"""The B-rep nearest-point kernel against brute force over every piece: the distance, the sign,
the foot and the piece, for segments and circular arcs (sweeps below, at and above pi, full
turns either way), at points far away, near the boundary, at arc centres and on the rays from
a centre through an arc's ends (where the arc test switches between the arc and its end
points)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from injmesh import Circle, Rectangle
from injmesh.geometry.brep import BRep

SETTINGS = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)

Inside = Callable[[np.ndarray], np.ndarray]


def _disc(q: np.ndarray, c: tuple[float, float], r: float) -> np.ndarray:
    return np.hypot(q[:, 0] - c[0], q[:, 1] - c[1]) < r


def _pacman(sign: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A unit disc without the wedge |angle| < pi/4: a segment from the centre, an arc
    sweeping 3 pi/2, a segment back (``sign`` -1: the same loop reversed, for a hole)."""
    a, b = np.array([math.cos(0.25 * math.pi), math.sin(0.25 * math.pi)]), np.array(
        [math.cos(0.25 * math.pi), -math.sin(0.25 * math.pi)])
    o = np.zeros(2)
    p0 = np.array([o, a, b])
    p1 = np.array([a, b, o])
    sw = np.array([0.0, 1.5 * math.pi, 0.0])
    if sign < 0:
        p0, p1, sw = p1[::-1].copy(), p0[::-1].copy(), -sw[::-1]
    return p0, p1, np.zeros((3, 2)), sw


def _in_pacman(q: np.ndarray) -> np.ndarray:
    return _disc(q, (0.0, 0.0), 1.0) & (np.abs(np.arctan2(q[:, 1], q[:, 0])) > 0.25 * math.pi)


def _shapes() -> dict[str, tuple[BRep, Inside]]:
    shapes: dict[str, tuple[BRep, Inside]] = {}
    p0, p1, c, sw = _pacman(1.0)
    shapes["pacman"] = (BRep(p0, p1, c, sw, np.array([0, 3])), _in_pacman)
    # A square with two holes: the pacman reversed and a full clockwise circle in one piece.
    sq = np.array([[-2.0, -2.0], [2.0, -2.0], [2.0, 2.0], [-2.0, 2.0]])
    h0, h1, hc, hsw = _pacman(-1.0)
    ring = np.array([[1.4, 1.1]])
    shapes["square, pacman and circle holes"] = (
        BRep(np.concatenate([sq, h0, ring]), np.concatenate([np.roll(sq, -1, axis=0), h1, ring]),
             np.concatenate([np.zeros((4, 2)), hc, [[1.4, 1.4]]]),
             np.concatenate([np.zeros(4), hsw, [-2 * math.pi]]), np.array([0, 4, 7, 8])),
        lambda q: (np.abs(q) < 2).all(axis=1) & ~_in_pacman(q) & ~_disc(q, (1.4, 1.4), 0.3),
    )
    shapes["full circle"] = (
        BRep(np.array([[0.5, -1.0]]), np.array([[0.5, -1.0]]), np.array([[0.5, 0.0]]),
             np.array([2 * math.pi]), np.array([0, 1])),
        lambda q: _disc(q, (0.5, 0.0), 1.0),
    )
    two_holes = Rectangle((0, 0), (1, 1)) - Circle((0.3, 0.3), 0.15) - Circle((0.7, 0.65), 0.2)
    shapes["square minus two circles"] = (
        two_holes.exact_brep(),
        lambda q: (q >= 0).all(axis=1) & (q <= 1).all(axis=1) & ~_disc(q, (0.3, 0.3), 0.15)
        & ~_disc(q, (0.7, 0.65), 0.2),
    )
    bulge = (Rectangle((0, 0), (1, 1)) | Circle((1.1, 0.5), 0.3)) - Circle((0, 0), 0.4)
    shapes["square with a bulge and a bite"] = (
        bulge.exact_brep(),
        lambda q: (((q >= 0).all(axis=1) & (q <= 1).all(axis=1)) | _disc(q, (1.1, 0.5), 0.3))
        & ~_disc(q, (0.0, 0.0), 0.4),
    )
    return shapes


SHAPES = _shapes()


def _brute(b: BRep, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared distance from every point to every piece, ``(n, m)``, in plain NumPy with the
    sweep tested by angles (atan2), independent of the kernel; and the pieces' arrays."""
    o, g = b.kernel_data()
    p0, p1, c, r, a0, sw = g[:6]
    x = q - o
    e = p1 - p0
    l2 = np.maximum(np.sum(e * e, axis=1), 1e-300)
    t = np.clip(np.einsum("nmk,mk->nm", x[:, None, :] - p0, e) / l2, 0, 1)
    seg = np.sum((x[:, None, :] - (p0 + t[..., None] * e)) ** 2, axis=2)
    v = x[:, None, :] - c
    rho = np.hypot(v[..., 0], v[..., 1])
    phi = np.arctan2(v[..., 1], v[..., 0])
    s = np.where(sw > 0, phi - a0, a0 - phi) % (2 * math.pi)
    within = (s <= np.abs(sw) * (1 + 1e-15)) & (rho > 0)
    ends = np.minimum(np.sum((x[:, None, :] - p0) ** 2, axis=2), np.sum((x[:, None, :] - p1) ** 2, axis=2))
    arc = np.where(within, (rho - r) ** 2, ends)
    return np.where(sw == 0, seg, arc), o


def _check(b: BRep, inside: Inside, q: np.ndarray) -> None:
    q = np.ascontiguousarray(q, dtype=float)
    d, foot, piece = b._query(q)
    d2, o = _brute(b, q)
    ref = np.sqrt(d2.min(axis=1))
    scale = 1e-12 * max(1.0, float(np.abs(q).max()))
    np.testing.assert_allclose(np.abs(d), ref, rtol=1e-12, atol=scale)
    # The foot is at that distance and on the piece reported.
    np.testing.assert_allclose(np.hypot(*(q - foot).T), ref, rtol=1e-12, atol=scale)
    on_piece = _brute(b, foot)[0][np.arange(len(q)), piece]
    assert np.all(np.sqrt(on_piece) <= scale)
    # The sign wherever it is not decided at rounding level.
    clear = ref > 1e-9
    np.testing.assert_array_equal((d < 0)[clear], inside(q)[clear])
    assert np.all(d[ref == 0] == 0)


def _special_points(b: BRep) -> np.ndarray:
    """Arc centres, piece ends, and points on each arc's end rays inside and beyond it."""
    o, g = b.kernel_data()
    p0, p1, c, sw = g[0], g[1], g[2], g[5]
    arc = sw != 0
    pts = [p0, p1, c[arc]]
    for end in (p0[arc], p1[arc]):
        for t in (0.25, 0.5, 0.999, 1.001, 1.5, 3.0):
            pts.append(c[arc] + t * (end - c[arc]))
    return np.concatenate(pts) + o


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_nearest_matches_brute_force(name: str) -> None:
    b, inside = SHAPES[name]
    rng = np.random.default_rng(7)
    lo, hi = np.array(b.bbox[:2]), np.array(b.bbox[2:])
    span = hi - lo
    far = lo - span + 3 * span * rng.random((3000, 2))
    # Near the boundary: points on the pieces (from the brute force's own feet) moved off them.
    on = b.project(lo + span * rng.random((3000, 2)))
    near = on + rng.normal(size=on.shape) * rng.choice([1e-9, 1e-6, 1e-3, 0.1], size=(len(on), 1))
    _check(b, inside, np.concatenate([far, near, _special_points(b)]))


@given(
    name=st.sampled_from(sorted(SHAPES)),
    u=st.lists(st.tuples(st.floats(-0.5, 1.5), st.floats(-0.5, 1.5)), min_size=1, max_size=40),
)
@SETTINGS
def test_nearest_matches_brute_force_anywhere(name: str, u: list[tuple[float, float]]) -> None:
    b, inside = SHAPES[name]
    lo, hi = np.array(b.bbox[:2]), np.array(b.bbox[2:])
    _check(b, inside, lo + (hi - lo) * np.array(u))


def test_nearest_is_deterministic_and_order_free() -> None:
    """The same points give bit-identical answers, and a point's answer does not depend on the
    other points queried with it (up to ties between equally near pieces)."""
    b, _ = SHAPES["square, pacman and circle holes"]
    q = np.random.default_rng(3).uniform(-2.5, 2.5, (5000, 2))
    d, foot, piece = b._query(q)
    d2, foot2, piece2 = b._query(q)
    assert np.array_equal(d, d2) and np.array_equal(foot, foot2) and np.array_equal(piece, piece2)
    single = np.array([b._query(q[i:i + 1])[0][0] for i in range(0, 5000, 50)])
    np.testing.assert_allclose(single, d[::50], rtol=1e-14, atol=1e-15)


def test_nearest_point_from_any_hint() -> None:
    """The search climbs from the hint's leaf to the root: any leaf slot, however far from the
    point, gives the same distance and foot as the search without a hint."""
    import numba

    from injmesh import Polygon
    from injmesh.kernels import brep as kb

    @numba.njit
    def from_hints(q, hints, g):  # type: ignore[no-untyped-def]
        stack = np.empty(2 * kb._STACK)
        tie_j = np.empty(kb._TIES, dtype=np.int64)
        tie_w = np.empty(kb._TIES, dtype=np.int64)
        out = np.empty((len(q), 3))
        for i in range(len(q)):
            d, fx, fy, _, _ = kb.nearest_point(q[i, 0], q[i, 1], hints[i], g, stack, tie_j, tie_w)
            out[i, 0], out[i, 1], out[i, 2] = d, fx, fy
        return out

    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(0, 2 * np.pi, 400))
    rad = 1 + 0.3 * np.sin(7 * t) + 0.05 * rng.random(400)
    outer = np.stack([rad * np.cos(t), rad * np.sin(t)], axis=1)
    hole = 0.2 * np.stack([np.cos(-t[::8]), np.sin(-t[::8])], axis=1)
    dom = Polygon(outer, holes=[hole])
    origin, g = dom.kernel_data()
    assert len(g[10]) > 63  # a hierarchy several levels deep
    q = np.ascontiguousarray(rng.uniform(-1.6, 1.6, (2000, 2)) - origin)
    d, foot, _ = dom._query(q + origin)
    for hints in (np.full(len(q), -1), rng.integers(0, dom.n_pieces, len(q))):
        out = from_hints(q, hints, g)
        np.testing.assert_array_equal(out[:, 0], d)
        np.testing.assert_array_equal(out[:, 1:] + origin, foot)
