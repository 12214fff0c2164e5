"""Gradation limiting (Persson 2006) by fast marching on a background grid.

Invariants on the output grid: the upwind gradient is at most the rate at every node (so every
grid edge changes by at most rate * spacing), the output never exceeds the input and equals it
where the input already satisfies the limit; the user's h is only evaluated inside the domain.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import injmesh
from injmesh import Circle, Rectangle, SizeError
from injmesh.sizing import GriddedSize, limit_gradation

SQUARE = Rectangle((0, 0), (1, 1))


def jump(p: np.ndarray) -> np.ndarray:
    """A size jumping 20:1 across the line x = 0.5."""
    return np.where(p[:, 0] < 0.5, 0.02, 0.4)


def nodes(g: GriddedSize) -> np.ndarray:
    X, Y = np.meshgrid(g.x, g.y)
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def upwind_gradient(g: GriddedSize) -> np.ndarray:
    """Godunov's upwind |grad h| at every node (Persson's eq. 11), ``(ny, nx)``."""
    v = g.values
    dx, dy = np.diff(g.x).mean(), np.diff(g.y).mean()
    big = np.inf
    pad = np.pad(v, 1, constant_values=big)
    west, east = pad[1:-1, :-2], pad[1:-1, 2:]
    south, north = pad[:-2, 1:-1], pad[2:, 1:-1]
    gx = np.maximum(v - np.minimum(west, east), 0) / dx
    gy = np.maximum(v - np.minimum(south, north), 0) / dy
    return np.hypot(gx, gy)


@pytest.mark.parametrize("rate", [0.1, 0.2, 0.5])
def test_gradient_is_limited_everywhere_on_the_grid(rate: float) -> None:
    g = limit_gradation(jump, SQUARE, rate)
    assert upwind_gradient(g).max() <= rate * (1 + 1e-9)
    step = g.spacing[0]
    assert np.abs(np.diff(g.values, axis=1)).max() <= rate * step * (1 + 1e-9)
    assert np.abs(np.diff(g.values, axis=0)).max() <= rate * step * (1 + 1e-9)


def test_output_is_below_the_input_and_equal_where_the_limit_holds() -> None:
    wide = Rectangle((0, 0), (3, 1))
    g = limit_gradation(jump, wide, 0.2)
    p = nodes(g)
    inside = wide.sdf(p) <= 0
    out, given = g.values.ravel()[inside], jump(p[inside])
    assert np.all(out <= given)
    # Far from the jump the cone 0.02 + 0.2 r rises above 0.4: the input is kept exactly.
    far = p[inside][:, 0] > 0.5 + (0.4 - 0.02) / 0.2 + 2 * g.spacing[0]
    assert far.sum() > 100 and np.array_equal(out[far], given[far])
    assert np.any(out < given)
    # Near the jump the small side is untouched and the large side follows the cone.
    small = p[inside][:, 0] < 0.5
    assert np.array_equal(out[small], given[small])


def test_a_size_within_the_limit_is_returned_unchanged() -> None:
    h = lambda p: 0.05 + 0.1 * p[:, 0] + 0.05 * p[:, 1]  # noqa: E731  slope 0.11 < 0.2
    g = limit_gradation(h, SQUARE, 0.2)
    p = nodes(g)
    inside = SQUARE.sdf(p) <= 0
    assert np.array_equal(g.values.ravel()[inside], h(p[inside]))


def test_point_refinement_becomes_a_cone_of_slope_rate() -> None:
    h = lambda p: np.where(np.hypot(p[:, 0] - 0.5, p[:, 1] - 0.5) < 0.05, 0.01, 1.0)  # noqa: E731
    g = limit_gradation(h, SQUARE, 0.25)
    q = np.random.default_rng(0).uniform(0, 1, (2000, 2))
    r = np.hypot(q[:, 0] - 0.5, q[:, 1] - 0.5)
    cone = np.minimum(1.0, 0.01 + 0.25 * np.maximum(r - 0.05, 0))
    # First-order fast marching: within a few grid spacings of the exact cone.
    assert np.all(g(q) <= cone + 0.25 * 2 * g.spacing[0] + 1e-12)
    assert np.all(g(q) >= cone * 0.97 - 0.25 * 2 * g.spacing[0])


def test_user_size_is_only_evaluated_inside() -> None:
    """DistMesh's example: h is negative inside the hole, and must never be asked there."""
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.5)
    seen: list[np.ndarray] = []

    def h(p: np.ndarray) -> np.ndarray:
        seen.append(p.copy())
        return 0.05 + 0.3 * (np.hypot(p[:, 0], p[:, 1]) - 0.5)

    g = limit_gradation(h, ring, 0.2)
    asked = np.concatenate(seen)
    assert ring.sdf(asked).max() <= 1e-6 * ring.diameter
    assert g.values.min() > 0 and np.isfinite(g.values).all()


def test_spacing_and_cell_cap() -> None:
    g = limit_gradation(0.001, SQUARE, 0.2, max_cells=10_000)
    assert g.values.size <= 10_000
    inside = SQUARE.sdf(nodes(g)) <= 0
    assert np.all(g.values.ravel()[inside] == 0.001)
    g = limit_gradation(jump, SQUARE, 0.2, spacing=0.05)
    assert g.spacing[0] == pytest.approx(0.05)


def test_huge_size_is_clamped_to_the_diameter() -> None:
    g = limit_gradation(1e300, SQUARE, 0.2)
    assert g.values.max() == pytest.approx(SQUARE.diameter)


def test_plain_callable_domain() -> None:
    d = lambda p: np.hypot(p[:, 0], p[:, 1]) - 1  # noqa: E731
    g = limit_gradation(lambda p: np.where(p[:, 0] < 0, 0.02, 0.3), d, 0.2, bbox=(-1, -1, 1, 1))
    assert upwind_gradient(g).max() <= 0.2 * (1 + 1e-9)


def test_deterministic() -> None:
    a = limit_gradation(jump, SQUARE, 0.2)
    b = limit_gradation(jump, SQUARE, 0.2)
    assert np.array_equal(a.values, b.values) and np.array_equal(a.x, b.x)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rate": 0}, "rate must be positive"),
        ({"rate": -0.2}, "rate must be positive"),
        ({"rate": float("nan")}, "rate must be positive"),
        ({"rate": "0.2"}, "rate must be a positive number"),
        ({"rate": True}, "rate must be a positive number"),
        ({"spacing": 0.0}, "spacing must be a positive"),
        ({"spacing": 1e-6}, "more than max_cells"),
        ({"max_cells": 3}, "max_cells must be an integer"),
    ],
)
def test_bad_options(kwargs: dict, match: str) -> None:
    with pytest.raises(SizeError, match=match):
        limit_gradation(jump, SQUARE, **kwargs)


def test_bad_size_inside_is_named() -> None:
    with pytest.raises(SizeError, match=r"positive and finite; h\(0\.\d+, 0\.\d+\) = -1\.0"):
        limit_gradation(lambda p: np.where(p[:, 0] > 0.7, -1.0, 0.1), SQUARE)


def test_jump_meshes_well_shaped_after_limiting() -> None:
    """Issue 9's target: a 20:1 jump gives q_min >= 0.7 once limited (before: slivers)."""
    mesh = injmesh.generate(SQUARE, limit_gradation(jump, SQUARE, 0.2))
    assert mesh.quality().min() >= 0.7


@settings(max_examples=30, deadline=None)
@given(
    ny=st.integers(1, 25),
    nx=st.integers(1, 25),
    rate=st.floats(0.05, 2.0),
    seed=st.integers(0, 2**32 - 1),
)
def test_kernel_invariants_on_random_grids(ny: int, nx: int, rate: float, seed: int) -> None:
    """Below h0, within the upwind limit everywhere, and a fixed point (limiting twice = once)."""
    from injmesh.kernels.fastmarch import limit_gradient

    rng = np.random.default_rng(seed)
    h0 = rng.uniform(0.01, 1.0, (ny, nx))
    h0[rng.uniform(size=(ny, nx)) < 0.2] = np.inf  # nodes that impose nothing
    if not np.isfinite(h0).any():
        h0[0, 0] = 0.5
    dx, dy = rng.uniform(0.01, 0.1, 2)
    h = limit_gradient(h0, dx, dy, rate)
    assert np.all(h <= h0) and np.all(np.isfinite(h))
    g = GriddedSize(np.arange(nx + 1) * dx, np.arange(ny + 1) * dy, np.pad(h, ((0, 1), (0, 1)), mode="edge"))
    assert upwind_gradient(g)[:ny, :nx].max() <= rate * (1 + 1e-9)
    assert np.array_equal(limit_gradient(h, dx, dy, rate), h)


@settings(max_examples=300, deadline=None)
@given(st.floats(0.0, 10.0), st.floats(0.0, 1.0), st.floats(1e-4, 1.0), st.floats(-1e-6, 1e-6),
       st.sampled_from([0.0, 1e-300, 1e-12, 1e-9, 1e-7]), st.booleans())
def test_first_pass_shortcut_claims_only_true_answers(a: float, db: float, g: float, rel: float,
                                                      nudge: float, swap: bool) -> None:
    """``_not_below(a, b, c)`` (the limiter's first-pass test without divisions) is True only
    where the update it stands for, computed as the kernel computes it, is at least c: tried
    at sizes c within a hair of that update (the knife edge of a size whose slope is exactly
    the rate), both sides."""
    from injmesh.kernels.fastmarch import _not_below, _update

    b = a + db * g
    if swap:
        a, b = b, a
    u = _update(a, b, g, g)
    for c in (u * (1.0 + rel), u * (1.0 - nudge), u * (1.0 + nudge), u, max(a, b), np.nextafter(u, np.inf),
              np.nextafter(u, 0.0)):
        if _not_below(a, b, c, g, g):
            assert _update(a, b, g, g) >= c


def test_first_pass_shortcut_leaves_the_limit_unchanged() -> None:
    """A cone of slope exactly the rate (every node on the knife edge of the first pass's test)
    and a steeper one: the limited sizes still satisfy the limit and equal h0 where it holds."""
    from injmesh.kernels.fastmarch import limit_gradient

    y, x = np.mgrid[0:120, 0:130] * 0.01
    for slope, rate in [(0.2, 0.2), (0.5, 0.2), (0.1, 0.3)]:
        h0 = 0.04 + slope * np.hypot(x - 0.7, y - 0.3)
        h0[:10, :10] = np.inf
        out = limit_gradient(h0, 0.01, 0.01, rate)
        assert np.all(out <= h0)
        assert np.all(np.abs(np.diff(out, axis=0)) <= rate * 0.01 * (1 + 1e-9))
        assert np.all(np.abs(np.diff(out, axis=1)) <= rate * 0.01 * (1 + 1e-9))
        if slope < rate:
            assert np.array_equal(out[10:, 10:], h0[10:, 10:])


def _textbook_limit(h0: np.ndarray, dx: float, dy: float, rate: float) -> np.ndarray:
    """Fast marching as the textbook writes it (``heapq``, stale entries skipped): every node
    whose update from its neighbours' h0 is below its h0 starts tentative, nodes are accepted
    in the order of (key, node number), and each accepted node updates its neighbours from
    those not tentative."""
    import heapq

    from injmesh.kernels.fastmarch import _update

    ny, nx = h0.shape
    key = h0.ravel().copy()
    tentative = np.zeros(ny * nx, dtype=bool)

    def update(node: int) -> float:
        j, i = divmod(node, nx)
        xs = [key[node + s] for s, ok in ((-1, i > 0), (1, i < nx - 1)) if ok and not tentative[node + s]]
        ys = [key[node + s] for s, ok in ((-nx, j > 0), (nx, j < ny - 1)) if ok and not tentative[node + s]]
        return float(_update(min(xs, default=np.inf), min(ys, default=np.inf), rate * dx, rate * dy))

    heap = []
    for node in range(ny * nx):
        u = update(node)
        if u < key[node]:
            key[node] = u
            tentative[node] = True
            heap.append((u, node))
    heapq.heapify(heap)
    while heap:
        k, node = heapq.heappop(heap)
        if not tentative[node] or k != key[node]:
            continue
        tentative[node] = False
        j, i = divmod(node, nx)
        around = ((node - 1, i > 0), (node + 1, i < nx - 1), (node - nx, j > 0), (node + nx, j < ny - 1))
        for nb, ok in around:
            if ok and key[nb] > key[node]:
                u = update(nb)
                if u < key[nb]:
                    key[nb] = u
                    tentative[nb] = True
                    heapq.heappush(heap, (u, nb))
    return key.reshape(ny, nx)


@settings(max_examples=40, deadline=None)
@given(
    ny=st.integers(1, 30),
    nx=st.integers(1, 30),
    rate=st.sampled_from([0.1, 0.2, 0.3, 1.0]),
    coarse=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_kernel_is_the_textbook_march_bit_for_bit(ny: int, nx: int, rate: float, coarse: bool,
                                                  seed: int) -> None:
    """The kernel's heap (keys beside the nodes, several children per node) and its first-pass
    shortcut change only how fast nodes are accepted, not which comes first: the output is the
    textbook algorithm's, bit for bit, ties (rounded sizes) included."""
    from injmesh.kernels.fastmarch import limit_gradient

    rng = np.random.default_rng(seed)
    h0 = rng.uniform(0.01, 1.0, (ny, nx))
    if coarse:
        h0 = np.round(h0, 1) + 0.1  # many equal keys: the node number decides
    h0[rng.uniform(size=(ny, nx)) < 0.3] = np.inf
    if not np.isfinite(h0).any():
        h0[0, 0] = 0.5
    dx = float(rng.uniform(0.01, 0.1))
    dy = dx if seed % 2 else float(rng.uniform(0.01, 0.1))
    out = limit_gradient(h0, dx, dy, rate)
    assert np.array_equal(out.view(np.int64), _textbook_limit(h0, dx, dy, rate).view(np.int64))


@pytest.mark.parametrize("make_domain", [
    lambda: Rectangle((0.375, 0.5), (0.5, 0.75)),
    lambda: Rectangle((0.25, 0.0), (0.5, 0.5)) | Rectangle((0.3, 0.45), (0.45, 0.6)),
    lambda: (lambda p: np.maximum(np.abs(p[:, 0] - 0.375) - 0.125, np.abs(p[:, 1] - 0.5) - 0.25)),
])
def test_a_size_that_jumps_on_the_boundary_is_limited_there(make_domain) -> None:
    """h jumps from 0.02 to 0.08 exactly on the domain's side x = 0.5.  No grid node lies on
    that line, so every node inside agreed with h and h came back unchanged: the side was
    meshed at 0.08 against 0.02 inside, q_min 0.01 (found by fuzzing)."""
    domain = make_domain()
    h = lambda p: np.where(p[:, 0] < 0.5, 0.02, 0.08)  # noqa: E731
    bbox = (0.25, 0.25, 0.5, 0.75) if not isinstance(domain, injmesh.Domain) else None
    mesh = injmesh.generate(domain, h, bbox=bbox)
    assert mesh.quality().min() > 0.7
    p, e = mesh.points, mesh.boundary_edges
    on_side = np.all(np.abs(p[e][:, :, 0] - 0.5) < 1e-9, axis=1)
    assert on_side.sum() > 0
    assert np.hypot(*(p[e[on_side, 1]] - p[e[on_side, 0]]).T).max() < 0.04
