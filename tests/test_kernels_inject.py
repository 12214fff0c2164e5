"""The background grid of Advancing Node Injection (kernels/inject.py) against brute force."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh import Circle, Rectangle
from injmesh.boundary import mesh_boundary
from injmesh.injection import CLEARANCE, MERGE, inject_nodes
from injmesh.kernels import inject as kern
from injmesh.sizing import as_size_function


def _grid(pts: np.ndarray, cell: float, box: tuple[float, float, float, float]):
    x0, y0, x1, y1 = box
    nx, ny = int((x1 - x0) / cell) + 1, int((y1 - y0) / cell) + 1
    head = np.full(nx * ny, -1, dtype=np.int64)
    link = np.empty(max(len(pts), 1), dtype=np.int64)
    kern.insert(pts, 0, len(pts), head, link, x0, y0, 1.0 / cell, nx, ny)
    return head, link, x0, y0, nx, ny


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 300),
    cell=st.sampled_from([0.01, 0.05, 0.13, 0.5, 2.0]),
    reach=st.sampled_from([0.0, 0.02, 0.1, 0.4, np.inf]),
)
def test_nearest_matches_brute_force(seed: int, n: int, cell: float, reach: float) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.random((n, 2))
    if n > 10:
        pts[5] = pts[3]  # a duplicate
    head, link, x0, y0, nx, ny = _grid(pts, cell, (0.0, 0.0, 1.0, 1.0))
    # Queries inside the box and some outside it (clamped to the border cells).
    q = rng.random((40, 2)) * 1.4 - 0.2
    stop = n if n < 5 else int(rng.integers(1, n + 1))
    for qx, qy in q:
        d, who = kern.nearest(qx, qy, reach, pts, stop, head, link, x0, y0, cell, nx, ny)
        dist = np.hypot(pts[:stop, 0] - qx, pts[:stop, 1] - qy)
        if stop == 0 or dist.min() >= reach:
            assert who == -1 and d == np.inf
        else:
            assert 0 <= who < stop
            assert d == pytest.approx(dist.min(), rel=1e-12, abs=1e-15)
            assert dist[who] == pytest.approx(dist.min(), rel=1e-12, abs=1e-15)


def _reference_admit(q, hq, keep, pts, hs, seg_a, seg_b):
    """The three rules of injection's step 3, by brute force."""
    keep = keep.copy()
    for t in np.flatnonzero(keep):
        ab = seg_b - seg_a
        u = np.clip(np.einsum("ij,ij->i", q[t] - seg_a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
        wall = np.hypot(*(q[t] - seg_a - u[:, None] * ab).T).min()
        if wall < CLEARANCE * hq[t]:
            keep[t] = False
            continue
        if len(pts):
            d = np.hypot(*(pts - q[t]).T)
            k = int(np.argmin(d))
            if d[k] < MERGE * 0.5 * (hq[t] + hs[k]):
                keep[t] = False
    kept: list[int] = []
    for t in np.flatnonzero(keep):
        if any(np.hypot(*(q[t] - q[s])) < MERGE * 0.5 * (hq[t] + hq[s]) for s in kept):
            keep[t] = False
        else:
            kept.append(t)
    return keep


@pytest.mark.parametrize("seed", range(8))
def test_admit_matches_brute_force(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # Walls: a square's sides cut into segments; old nodes and candidates scattered inside.
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    t = np.linspace(0, 1, 11)[:-1, None]
    ring = np.concatenate([c + t * (np.roll(corners, -1, axis=0)[i] - c) for i, c in enumerate(corners)])
    seg_a, seg_b = ring, np.roll(ring, -1, axis=0)
    old = rng.random((int(rng.integers(0, 200)), 2))
    h_old = rng.uniform(0.02, 0.08, len(old))
    q = rng.random((300, 2))
    hq = rng.uniform(0.02, 0.08, len(q))
    keep = rng.random(len(q)) < 0.9
    expected = _reference_admit(q, hq, keep, old, h_old, seg_a, seg_b)

    cell = float(rng.choice([0.01, 0.04, 0.3]))
    cap = len(old) + len(q)
    pts, hs = np.empty((cap, 2)), np.empty(cap)
    pts[: len(old)], hs[: len(old)] = old, h_old
    head, link, x0, y0, nx, ny = _grid(pts[: len(old)], cell, (0.0, 0.0, 1.0, 1.0))
    link = np.concatenate([link[: len(old)], np.empty(len(q), dtype=np.int64)])
    rows, items = kern.segment_lists(seg_a, seg_b, x0, y0, cell, nx, ny)
    got = keep.copy()
    h_max = float(h_old.max()) if len(old) else 0.0
    n = kern.admit(q, hq, got, MERGE, CLEARANCE, pts, hs, len(old), h_max, head, link, seg_a, seg_b,
                   rows, items, x0, y0, cell, nx, ny)
    assert np.array_equal(got, expected)
    assert n == len(old) + int(expected.sum())
    # The survivors were appended in candidate order, with their h, and are now found.
    assert np.array_equal(pts[len(old): n], q[expected])
    assert np.array_equal(hs[len(old): n], hq[expected])
    for k in range(len(old), n):
        d, who = kern.nearest(pts[k, 0], pts[k, 1], np.inf, pts, n, head, link, x0, y0, cell, nx, ny)
        assert d == 0.0


@pytest.mark.parametrize("domain", [Rectangle((0, 0), (1, 1)), Circle((0, 0), 1) - Circle((0.3, 0), 0.3)])
def test_injection_repeats_bit_for_bit(domain) -> None:
    h = as_size_function(lambda p: 0.03 + 0.05 * np.abs(p[:, 0]))
    b = mesh_boundary(domain, h, np.empty((0, 2)), max_nodes=10**6)
    runs = [inject_nodes(domain, h, b, b.points, max_nodes=10**6) for _ in range(2)]
    assert runs[0].tobytes() == runs[1].tobytes()
    # No injected node violates the merge rule against the nearest other node.
    allp = np.concatenate([b.points, runs[0]])
    from scipy.spatial import cKDTree

    d, _ = cKDTree(allp).query(runs[0], k=2)
    assert np.all(d[:, 1] >= MERGE * 0.5 * h(runs[0]).min() * 0.999)


def _reference_runs(points, lengths, closed, keep):
    """Runs of kept points per chain, in plain Python: a closed chain that lost a point starts
    right after its first lost point."""
    out, pos = [], 0
    for size, ring in zip(lengths, closed, strict=True):
        idx = list(range(pos, pos + size))
        pos += size
        lost = [k for k in idx if not keep[k]]
        if not lost:
            if idx:
                out.append(([points[k] for k in idx], bool(ring)))
            continue
        if ring:
            cut = idx.index(lost[0]) + 1
            idx = idx[cut:] + idx[:cut]
        run: list = []
        for k in idx + [None]:
            if k is not None and keep[k]:
                run.append(points[k])
            elif run:
                out.append((run, False))
                run = []
    return out


@settings(max_examples=80, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), keep_rate=st.sampled_from([0.2, 0.7, 0.95, 1.0]))
def test_survivors_match_plain_runs(seed: int, keep_rate: float) -> None:
    rng = np.random.default_rng(seed)
    lengths = rng.integers(0, 9, int(rng.integers(1, 6)))
    closed = rng.random(len(lengths)) < 0.5
    points = rng.random((int(lengths.sum()), 2))
    keep = rng.random(len(points)) < keep_rate
    start = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    pts, got_len, got_closed = kern.survivors(points, start, closed, keep)
    expected = _reference_runs(points, lengths, closed, keep)
    assert got_len.tolist() == [len(r) for r, _ in expected]
    assert got_closed.tolist() == [c for _, c in expected]
    flat = np.array([p for r, _ in expected for p in r]).reshape(-1, 2)
    assert np.array_equal(pts, flat)


def _edt_below(occupied: np.ndarray, cell_h: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """The distance transform's answer, and where the nearest occupied cells tie and disagree."""
    from scipy import ndimage

    dist, (jj, ii) = ndimage.distance_transform_edt(~occupied, return_indices=True)
    below = cell_h[jj, ii] < limit
    # Brute force over the occupied cells: the ones at the nearest distance, all of them.
    oj, oi = np.nonzero(occupied)
    yy, xx = np.indices(occupied.shape)
    d2 = (yy[..., None] - oj) ** 2 + (xx[..., None] - oi) ** 2
    nearest = d2 == d2.min(axis=-1, keepdims=True)
    v = cell_h[oj, oi] < limit
    agree = np.all(np.where(nearest, v, True), axis=-1) | np.all(np.where(nearest, ~v, True), axis=-1)
    assert np.array_equal(np.rint(dist**2), d2.min(axis=-1))  # the transform is exact
    return below, agree


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    shape=st.tuples(st.integers(1, 30), st.integers(1, 30)),
    density=st.sampled_from([0.01, 0.05, 0.3, 0.9]),
    levels=st.sampled_from([2, 5, 1000]),
    rings=st.sampled_from([0, 1, 3, 8, 100]),
)
def test_nearest_occupied_below_matches_the_distance_transform(
    seed: int, shape: tuple[int, int], density: float, levels: int, rings: int
) -> None:
    # Few distinct h values (levels=2) make many ties, some disagreeing; lattices of occupied
    # cells make many equidistant ones.
    rng = np.random.default_rng(seed)
    occupied = rng.random(shape) < density
    if seed % 3 == 0:
        occupied[:: 1 + seed % 4, :: 1 + seed % 5] = True
    if not occupied.any():
        occupied[rng.integers(shape[0]), rng.integers(shape[1])] = True
    cell_h = rng.integers(0, levels, shape).astype(float)
    limit = levels / 2
    want, agree = _edt_below(occupied, cell_h, limit)
    cj, ci = np.nonzero(~occupied | (rng.random(shape) < 0.2))
    below, settled = kern.nearest_occupied_below(occupied, cell_h, cj.astype(np.int64), ci.astype(np.int64),
                                                 limit, rings)
    # Settled exactly where the nearest cells agree and lie within the rings searched ...
    from scipy import ndimage

    dist = ndimage.distance_transform_edt(~occupied)[cj, ci]
    assert np.array_equal(settled, agree[cj, ci] & (dist <= rings))
    # ... and there with the distance transform's answer, whichever of them it picked.
    assert np.array_equal(below[settled], want[cj, ci][settled])


def test_nearest_occupied_below_on_an_empty_grid_settles_nothing() -> None:
    occupied = np.zeros((4, 5), dtype=bool)
    below, settled = kern.nearest_occupied_below(occupied, np.zeros((4, 5)), np.array([0, 3]),
                                                 np.array([0, 4]), 1.0, 10)
    assert not settled.any() and not below.any()


def _census_numpy(pts, hs, x0, y0, s, nx, ny, outside):
    """The NumPy formulation fill_census replaced: shifted slices of a grid with a margin."""
    ix = np.floor((pts[:, 0] - x0) / s).astype(np.int64)
    iy = np.floor((pts[:, 1] - y0) / s).astype(np.int64)
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    occupied = np.zeros((ny + 2, nx + 2), dtype=bool)
    occupied[iy[ok] + 1, ix[ok] + 1] = True
    near = np.zeros_like(occupied)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near[1:-1, 1:-1] |= occupied[1 + dy: ny + 1 + dy, 1 + dx: nx + 1 + dx]
    deep = ~near[1:-1, 1:-1]
    grown = np.zeros((ny + 2, nx + 2), dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            grown[1 + dy: ny + 1 + dy, 1 + dx: nx + 1 + dx] |= deep
    cells = grown[1:-1, 1:-1] & ~occupied[1:-1, 1:-1] & ~outside
    cell_h = np.zeros((ny, nx))
    cell_h[iy[ok], ix[ok]] = hs[ok]
    return occupied[1:-1, 1:-1], cells, cell_h, int(deep.sum()), int((cells & ~deep).sum())


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 400),
       shape=st.tuples(st.integers(1, 40), st.integers(1, 40)), on_lines=st.booleans())
def test_fill_census_matches_the_numpy_passes(seed: int, n: int, shape: tuple[int, int],
                                              on_lines: bool) -> None:
    """Against the 3 x 3 passes over shifted slices, with points outside the grid, on cell
    sides (``on_lines``: coordinates on multiples of s), several in one cell, and cells
    already known to be outside."""
    rng = np.random.default_rng(seed)
    ny, nx = shape
    s, x0, y0 = 0.25, -1.0, 2.0
    u = rng.random((n, 2)) * [nx + 2, ny + 2] - 1.0
    if on_lines:
        u = np.round(u)
    pts = np.ascontiguousarray([x0, y0] + s * u)
    hs = rng.random(n)
    outside = rng.random((ny, nx)) < 0.2
    got = kern.fill_census(pts, hs, x0, y0, s, nx, ny, outside)
    want = _census_numpy(pts, hs, x0, y0, s, nx, ny, outside)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[2], want[2])
    assert got[3] == want[3]
    if want[3]:  # without a deep cell nothing is offered (the caller stops there)
        assert np.array_equal(got[1], want[1]) and got[4] == want[4]
    else:
        assert not got[1].any()


def _relaid(rings: list[np.ndarray], closed: list[bool], window: int):
    """relay() over the chains ``rings`` with h = 1 (ds = the segments' lengths)."""
    points = np.concatenate(rings)
    start = np.concatenate([[0], np.cumsum([len(r) for r in rings])]).astype(np.int64)
    flags = np.array(closed)
    poly, pchain = kern.chain_polylines(points, start, flags)
    same = pchain[1:] == pchain[:-1]
    ds = np.where(same, np.hypot(*(poly[1:] - poly[:-1]).T), 0.0)
    out, count, stays = kern.relay(poly, pchain, ds, flags, points, start, window)
    lengths = [float(ds[pchain[1:] == c].sum()) for c in range(len(rings))]
    return out, count, stays, lengths


def _ring(n: int, radius: float, phase: float = 0.0) -> np.ndarray:
    a = phase + 2 * np.pi * np.arange(n) / n
    return np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)


def test_windows_keep_a_growing_ring_in_step() -> None:
    """A ring of 300 points 1.02 apart (a layer going out from a circle 48 h across) gains six:
    relaid with windows it keeps all but 6 * (window - 1) of its points where they are, and the
    six windows, evenly round it, are laid at equal spacing; uniformly, it keeps only the few
    where the slipping phase comes round."""
    n, spacing = 300, 1.02
    ring = _ring(n, spacing / (2 * np.sin(np.pi / n)))
    for window in (12, 0):
        out, count, stays, (length,) = _relaid([ring], [True], window)
        assert count[0] == round(length) == 306 and stays[0]
        d = np.min(np.hypot(*(out[:, None, :] - ring[None, :, :]).transpose(2, 0, 1)), axis=1)
        kept = int(np.sum(d < 1e-9))
        assert kept >= n - 6 * 11 if window else kept <= 7
    out, *_ = _relaid([ring], [True], 12)
    # In order round the ring, gaps of about 1.02 outside the windows, 12/13 of that inside.
    ang = np.unwrap(np.arctan2(out[:, 1], out[:, 0]))
    gaps = np.diff(np.r_[ang, ang[0] + 2 * np.pi]) * np.hypot(*ring[0])
    assert np.all(gaps > 0)
    assert np.allclose(np.sort(gaps)[:6 * 13], spacing * 12 / 13, rtol=1e-3)
    assert np.allclose(np.sort(gaps)[6 * 13:], spacing, rtol=1e-3)


def test_windows_take_the_slip_up_where_it_builds() -> None:
    """A loop round a crack, its straight sides in step (points 1 apart) and its round ends
    crowded (points 0.7 apart): the points it loses are taken up at the ends, and the middle of
    each side keeps every point where it is."""
    side = np.stack([np.arange(100, dtype=float), np.zeros(100)], axis=1)
    a = np.linspace(-np.pi / 2, np.pi / 2, 11)[1:-1]  # a half circle of radius 2: 9 points
    end_r = np.stack([99 + 2 * np.cos(a), 2 + 2 * np.sin(a)], axis=1)
    back = np.stack([np.arange(99, -1, -1, dtype=float), np.full(100, 4.0)], axis=1)
    end_l = np.stack([-2 * np.cos(a), 2 - 2 * np.sin(a)], axis=1)
    loop = np.concatenate([side, end_r, back, end_l])
    out, count, _, (length,) = _relaid([loop], [True], 12)
    assert count[0] == round(length) < len(loop)
    middle = (loop[:, 0] > 30) & (loop[:, 0] < 70)
    d = np.min(np.hypot(*(loop[middle][:, None, :] - out[None, :, :]).transpose(2, 0, 1)), axis=1)
    assert np.all(d < 1e-9)
    uniform, *_ = _relaid([loop], [True], 0)
    d = np.min(np.hypot(*(loop[middle][:, None, :] - uniform[None, :, :]).transpose(2, 0, 1)), axis=1)
    assert np.mean(d < 1e-9) < 0.2


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    chains=st.lists(st.tuples(st.integers(3, 400), st.booleans(), st.floats(0.3, 3.0)), min_size=1,
                    max_size=4),
    window=st.sampled_from([0, 4, 8, 12, 64]),
)
def test_relay_keeps_its_counts_and_stays_on_the_chains(seed: int, chains, window: int) -> None:
    """Windowed or not, every chain gets round(S) segments (closed: at least three, or collapses
    below 2.5), in order along it, every point on the chain's polyline."""
    rng = np.random.default_rng(seed)
    rings, closed = [], []
    for n, is_closed, jitter in chains:
        r = _ring(n, n / (2 * np.pi) * rng.uniform(0.8, 1.25), rng.uniform(0, 6.3))
        r = r * (1 + 0.1 * jitter * rng.random((n, 1)))
        rings.append(r)
        closed.append(is_closed)
    out, count, stays, lengths = _relaid(rings, closed, window)
    o = 0
    for ring, is_closed, length, k, stay in zip(rings, closed, lengths, count, stays, strict=True):
        if is_closed and length < 2.5:
            assert k == 1 and not stay
        else:
            want = round(length) if is_closed else round(length) + 1
            assert k == max(want, 3 if is_closed else 1)
            assert stay == is_closed
            pts = out[o:o + k]
            poly = np.concatenate([ring, ring[:1]]) if is_closed else ring
            a, b = poly[:-1], poly[1:]
            ab = b - a
            along = np.einsum("pij,ij->pi", pts[:, None, :] - a[None], ab)
            t = np.clip(along / np.einsum("ij,ij->i", ab, ab), 0, 1)
            foot = a[None] + t[..., None] * ab[None]
            dist = np.hypot(*(pts[:, None, :] - foot).transpose(2, 0, 1))
            seg = np.argmin(dist, axis=1)
            assert np.all(dist[np.arange(k), seg] < 1e-9 * max(1.0, np.abs(ring).max()))
            # In order along the chain: the arc length of each point increases.
            cum = np.r_[0, np.cumsum(np.hypot(*ab.T))]
            arc = cum[seg] + t[np.arange(k), seg] * np.hypot(*ab[seg].T)
            assert np.all(np.diff(arc) > -1e-9)
        o += k
