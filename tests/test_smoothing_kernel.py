"""The compiled Euler step of Step 3 (kernels/smooth.py) against a plain reference."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh import Circle, Implicit, Polygon, Rectangle, generate
from injmesh.kernels.smooth import adjacency, advance, bar_forces, boundary_query, mean_bar_size, rings
from injmesh.quality import unique_edges
from injmesh.smoothing import ATTRACTION, DT, smooth
from injmesh.triangulation import delaunay


def _mesh(seed: int = 0, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    p = np.random.default_rng(seed).random((n, 2))
    return p, delaunay(p).astype(np.int32)


def _reference_forces(p, bars, ld, attraction):
    """Bar forces by scatter over the bars: the textbook form of (2.4), (3.4)."""
    total = np.zeros_like(p)
    for (i, j), d in zip(bars, ld, strict=True):
        vec = p[i] - p[j]
        lc = np.hypot(*vec)
        c = -attraction / d if attraction > 0 else (d - lc) / (d * lc)
        total[i] += c * vec
        total[j] -= c * vec
    return total


def test_adjacency_matches_unique_edges() -> None:
    p, tri = _mesh()
    indptr, adj, eid, bars = adjacency(len(p), tri, 0)
    assert np.array_equal(bars, unique_edges(tri))
    for v in range(len(p)):
        row = adj[indptr[v]:indptr[v + 1]]
        assert np.all(np.diff(row) > 0), "rows are sorted without repeats"
        for e in range(indptr[v], indptr[v + 1]):
            assert sorted((v, int(adj[e]))) == bars[eid[e]].tolist()


def test_adjacency_leaves_unused_nodes_empty() -> None:
    p, tri = _mesh()
    indptr, adj, _, _ = adjacency(len(p) + 2, tri, 0)
    assert indptr[-1] == indptr[-3] == len(adj)


@pytest.mark.parametrize("attraction", [ATTRACTION, 0.0], ids=["attractive", "spring"])
def test_gather_forces_equal_scatter_reference(attraction: float) -> None:
    p, tri = _mesh(1)
    indptr, adj, eid, bars = adjacency(len(p), tri, 0)
    mid = 0.5 * (p[bars[:, 0]] + p[bars[:, 1]])
    ld = 0.1 + 0.05 * mid[:, 0]
    total = np.zeros_like(p)
    bar_forces(p, np.arange(len(p)), indptr, adj, eid, ld, attraction, total, np.ones(len(p)))
    np.testing.assert_allclose(total, _reference_forces(p, bars, ld, attraction), rtol=1e-12, atol=1e-14)
    # hbar is the mean desired length of the node's bars.
    hbar = mean_bar_size(indptr, eid, ld)
    deg = np.bincount(bars.ravel(), minlength=len(p))
    ref = (np.bincount(bars[:, 0], ld, len(p)) + np.bincount(bars[:, 1], ld, len(p))) / deg
    np.testing.assert_allclose(hbar, ref, rtol=1e-14)


def test_advance_steps_clamps_and_defers_near_nodes() -> None:
    p, tri = _mesh(2)
    indptr, adj, eid, bars = adjacency(len(p), tri, 0)
    ld = np.full(len(bars), 0.3)
    total = np.zeros_like(p)
    bar_forces(p, np.arange(len(p)), indptr, adj, eid, ld, 0.0, total, np.ones(len(p)))
    hbar = mean_bar_size(indptr, eid, ld)
    free = np.arange(5, len(p))
    deep = np.zeros(len(p), dtype=bool)
    deep[::2] = True
    q = p.copy()
    cand, near = np.empty((len(free), 2)), np.empty(len(free), dtype=np.intp)
    c, worst, at, drift, count = advance(q, free, total, hbar, DT, 0.05, deep, p, cand, near, 0.01)
    step = DT * hbar[:, None] * total
    length = np.hypot(*step.T)
    step *= np.minimum(1.0, 0.05 * hbar / np.maximum(length, 1e-300))[:, None]
    moved = free[deep[free]]
    np.testing.assert_allclose(q[moved], p[moved] + step[moved], rtol=0, atol=1e-15)
    assert np.array_equal(q[:5], p[:5]) and np.array_equal(q[~deep], p[~deep])
    assert np.array_equal(near[:c], free[~deep[free]])
    np.testing.assert_allclose(cand[:c], p[near[:c]] + step[near[:c]], rtol=0, atol=1e-15)
    assert worst <= 0.05 + 1e-12 and drift == pytest.approx(worst)
    assert count == np.count_nonzero(np.hypot(*(q[moved] - p[moved]).T) / hbar[moved] > 0.01)
    assert at in moved


def test_rings_grow_by_one_edge_per_step() -> None:
    p, tri = _mesh(3)
    indptr, adj, _, bars = adjacency(len(p), tri, 0)
    seeds = np.array([0], dtype=np.int64)
    assert np.flatnonzero(rings(indptr, adj, seeds, 0)).tolist() == [0]
    one = rings(indptr, adj, seeds, 1)
    assert np.array_equal(np.flatnonzero(one), np.union1d([0], adj[indptr[0]:indptr[1]]))
    two = rings(indptr, adj, seeds, 2)
    ref = one.copy()
    ref[bars[one[bars[:, 0]], 1]] = True
    ref[bars[one[bars[:, 1]], 0]] = True
    assert np.array_equal(two, ref)



@settings(max_examples=40, deadline=None)
@given(st.integers(2, 12), st.integers(40, 600), st.lists(st.integers(0, 10**6), max_size=60),
       st.booleans())
def test_one_ring_as_indices_is_the_ring_mask(k: int, n: int, raw: list[int], padded: bool) -> None:
    """``ring_one`` lists what ``rings(..., 1)`` marks, sorted, whatever the number of seeds
    (its two ways of listing: a sort of few, a scan of many), including rows with free slots
    and repeated seeds, and leaves its scratch mask zeroed."""
    from injmesh.kernels.smooth import ring_one

    p, tri = _mesh(k, n)
    indptr, adj, eid, _ = adjacency(len(p), tri, 3 if padded else 0)
    seeds = np.array([r % len(p) for r in raw], dtype=np.int64)
    mark = np.zeros(len(p), dtype=np.uint8)
    got = ring_one(indptr, adj, seeds, mark)
    assert np.array_equal(got, np.flatnonzero(rings(indptr, adj, seeds, 1)))
    assert not mark.any()


_RUN = """
import numpy as np, hashlib
from injmesh import Circle, Rectangle, generate
from injmesh.kernels import threads
threads.MIN_CHUNK = 256  # split these small meshes' steps as a million nodes' are
m = generate(Rectangle((0, 0), (1, 1)), 0.08)
# Graded 20:1 with a region: the slow tail's sub-mesh, local flips and sub-mesh repair run.
g = generate(Circle((0, 0), 1), lambda p: 0.004 * (1 + 19 * np.hypot(p[:, 0], p[:, 1])),
             regions={"r": Circle((0.4, 0), 0.2)})
digest = hashlib.sha256()
for mesh in (m, g):
    digest.update(mesh.points.tobytes() + mesh.triangles.tobytes())
print(digest.hexdigest())
"""


def test_smoothing_bit_identical_across_runs_and_thread_counts() -> None:
    src = str(Path(__file__).resolve().parents[1] / "src")
    out = []
    for threads in ("1", "2", "2"):
        env = dict(os.environ, NUMBA_NUM_THREADS=threads, PYTHONPATH=src)
        res = subprocess.run([sys.executable, "-c", _RUN], env=env, capture_output=True, text=True,
                             check=True, timeout=300)
        out.append(res.stdout.strip())
    assert len(out[0]) == 64 and out[0] == out[1] == out[2]


def test_smooth_keeps_free_nodes_inside_with_deep_skip() -> None:
    """The inside test is skipped for deep nodes: no node may end up outside anyway."""
    square = Rectangle((0, 0), (1, 1))
    rng = np.random.default_rng(4)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    p = np.concatenate([corners, 0.02 + 0.96 * rng.random((150, 2))])
    r = smooth(square, lambda x: np.full(len(x), 0.1), p, n_fixed=4)
    assert square.sdf(r.points).max() <= 1e-12


def test_depth_flags_from_the_lipschitz_bound_equal_the_exact_ones() -> None:
    """For an exact distance, deep flags come from ``d0 + drift`` where that bound settles
    them: after many connectivity updates they equal the test on d itself at the anchors, and
    d0 is d there for every node that is not deep, an upper bound of it for the others."""
    from injmesh.smoothing import DEEP, _Relaxation
    from injmesh.triangulation import delaunay as tri_of

    domain = Rectangle((0, 0), (1, 1)) - Rectangle((0.3, 0.3), (0.6, 0.5))
    assert domain.exact_distance
    rng = np.random.default_rng(7)
    inner = rng.random((900, 2))
    inner = inner[domain.sdf(inner) < -0.01]
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.3, 0.3], [0.6, 0.3], [0.6, 0.5], [0.3, 0.5]],
                       dtype=float)
    p = np.concatenate([corners, inner])
    t = tri_of(p)
    t = t[domain.sdf(p[t].mean(axis=1)) < 0]
    relax = _Relaxation(domain, lambda x: np.full(len(x), 0.05), p, 8, np.zeros((0, 3), dtype=np.intp),
                        np.zeros((0, 2), dtype=np.intp), None, 1000, tri=t)
    relax.run("spring", 60)
    assert relax.retriangulations > 3
    f = relax._free

    def check() -> None:
        exact = domain.sdf(relax.anchor[f])
        assert np.array_equal(relax._deep[f], exact < -DEEP * relax.hbar[f])
        shallow = ~relax._deep[f]
        assert np.array_equal(relax._d0[f][shallow], exact[shallow])
        assert (relax._d0[f] >= exact - 1e-12).all()
        assert domain.sdf(relax.p).max() <= 1e-12

    check()
    # final() moves the anchors without renewing the flags; stepping again renews them.
    relax.p[f] += rng.normal(0.0, 1e-3, (len(f), 2)) * (relax._d0[f] < -0.01)[:, None]
    relax.final()
    relax.run("spring", 5)
    check()


def test_repair_edits_keep_a_valid_triangulation() -> None:
    """Split an edge and collapse another on the triangle arrays, then Lawson flips: a valid
    Delaunay triangulation of the new nodes, same area, every node used."""
    from injmesh.kernels.repair import apply_edits
    from injmesh.quality import signed_areas
    from injmesh.smoothing import _made_delaunay

    square = Rectangle((0, 0), (1, 1))
    rng = np.random.default_rng(5)
    corners = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], dtype=float)
    p = np.concatenate([corners, 0.1 + 0.8 * rng.random((40, 2))])
    tri = delaunay(p).astype(np.int64)
    edges = unique_edges(tri).astype(np.int64)
    interior = edges[(edges >= 4).all(axis=1)]
    split = interior[:1]
    # A collapse whose two nodes share no node with the split.
    rest = interior[~np.isin(interior, split).any(axis=1)]
    collapse = rest[:1]
    kept = np.arange(len(p), dtype=np.int64)
    q, edited, new_kept, _, touched = apply_edits(p, tri, kept, np.zeros(len(p), dtype=np.int64),
                                                  collapse, split, 4)
    assert len(q) == len(p) and (new_kept == -1).sum() == 1
    assert np.allclose(q[-1], 0.5 * (p[split[0, 0]] + p[split[0, 1]]))
    t = _made_delaunay(square, q, edited, np.zeros((0, 2), np.intp))
    assert signed_areas(q, t).min() > 0
    assert np.array_equal(np.unique(t), np.arange(len(q)))
    assert signed_areas(q, t).sum() == pytest.approx(1.0, rel=1e-12)
    # Random nodes have no cocircular ties: the flips reach the one Delaunay triangulation.
    def rows(x: np.ndarray) -> set[tuple[int, ...]]:
        return {tuple(r) for r in np.sort(x, axis=1).tolist()}

    assert rows(t) == rows(delaunay(q))




def _seg_dist(q, a, b):
    ab = b - a
    t = np.clip(np.dot(q - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0)
    return float(np.hypot(*(q - a - t * ab)))


@pytest.mark.parametrize("seed", range(5))
def test_slide_kernels_follow_the_barriers(seed: int) -> None:
    """Boundary sliding on a circle: each step is the half-total plus boundary-spring force,
    and a projected move is kept exactly when the three barriers of Algorithm 3 allow it."""
    from injmesh.kernels.smooth import slide_accept, slide_targets

    rng = np.random.default_rng(seed)
    k = 24
    ang = np.sort(rng.uniform(0, 2 * np.pi, k))
    p = np.column_stack([np.cos(ang), np.sin(ang)])
    slide = np.column_stack([np.arange(k), np.roll(np.arange(k), 1), np.roll(np.arange(k), -1)])
    slide = slide[::2].copy()  # rows never share a node; their neighbours stay put
    total = rng.normal(scale=3.0, size=(k, 2))
    hbar = rng.uniform(0.1, 0.4, k)
    ld_prev, ld_next = rng.uniform(0.1, 0.4, len(slide)), rng.uniform(0.1, 0.4, len(slide))
    target = np.empty((len(slide), 2))
    slide_targets(p, slide, total, hbar, ld_prev, ld_next, DT, target)
    cand = target / np.hypot(*target.T)[:, None]  # the circle's projection
    before = p.copy()
    moved = np.empty(len(slide))
    slide_accept(p, slide, hbar, cand, moved)
    kept = 0
    for r, (b, bp, bn) in enumerate(slide):
        f = 0.5 * total[b]
        for o, d in ((bp, ld_prev[r]), (bn, ld_next[r])):
            vec = before[b] - before[o]
            lc = np.hypot(*vec)
            f = f + 0.5 * (d - lc) / (d * lc) * vec
        assert np.allclose(target[r], before[b] + DT * hbar[b] * f, rtol=1e-12, atol=1e-12)
        old, c = before[b], cand[r]
        gap = min(np.hypot(*(old - before[bp])), np.hypot(*(old - before[bn])))
        step = np.hypot(*(c - old))
        stray = min(_seg_dist(c, before[bp], old), _seg_dist(c, old, before[bn]))
        allow = 2 * _seg_dist(old, before[bp], before[bn]) + 0.1 * step
        new_gap = min(np.hypot(*(c - before[bp])), np.hypot(*(c - before[bn])))
        ok = step < 0.5 * gap and stray <= allow + 1e-9 * hbar[b] and new_gap >= min(gap, 0.5 * hbar[b])
        assert np.array_equal(p[b], c if ok else old)
        assert moved[r] == pytest.approx(step / hbar[b] if ok else 0.0, rel=1e-12)
        kept += ok
    untouched = np.setdiff1d(np.arange(k), slide[:, 0])
    assert np.array_equal(p[untouched], before[untouched])
    assert 0 < kept  # the random forces leave some steps inside the barriers


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(4, 200))
def test_edges_present_agrees_with_the_edge_list(seed: int, n: int) -> None:
    """The boundary-recovery test (is each segment a mesh edge?) against the set of edges."""
    from injmesh.kernels.mesh import edges_present

    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    tri = delaunay(p).astype(np.int64)
    edges = {tuple(e) for e in unique_edges(tri).tolist()}
    pairs = rng.integers(0, n, (3 * n, 2))
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    pairs = np.concatenate([pairs, np.array(sorted(edges))[: n // 2, ::-1]])
    found = edges_present(tri, np.ascontiguousarray(pairs, dtype=np.int64), n)
    assert found.tolist() == [(min(a, b), max(a, b)) in edges for a, b in pairs.tolist()]


def _lower_wins_reference(keep, lo, hi):
    """Sequential greedy in index order, written out plainly."""
    kept = np.zeros(len(keep), dtype=bool)
    for v in range(len(keep)):
        if keep[v]:
            kept[v] = not any(kept[a] for a, b in zip(lo, hi, strict=True) if b == v)
    return kept


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(3, 80), share=st.floats(0.0, 1.0))
def test_star_independent_is_the_greedy_independent_set(seed: int, n: int, share: float) -> None:
    # The quality pass moves an independent set of its candidates, best ranked first: the
    # greedy set over the candidate pairs joined by a triangle side, found from the stars.
    from injmesh.kernels.smooth import clear_stars, corners_by_node, star_independent

    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    tri = delaunay(p).astype(np.int64)
    start, corner = corners_by_node(tri, n)
    order = rng.permutation(np.flatnonzero(rng.random(n) < share)).astype(np.int64)
    rank = np.full(n, -1)
    rank[order] = np.arange(len(order))
    sides = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    sides = sides[(rank[sides] >= 0).all(axis=1)]
    ra, rb = rank[sides[:, 0]], rank[sides[:, 1]]
    want = _lower_wins_reference(np.ones(len(order), dtype=bool), np.minimum(ra, rb), np.maximum(ra, rb))
    scratch = np.zeros(n, dtype=np.bool_)
    got = star_independent(order, tri, start, corner, scratch)
    assert got.tolist() == want.tolist()
    assert not scratch.any()  # left zeroed for the next sweep
    # clear_stars: every node of the kept nodes' triangles, and no other.
    flags = np.ones(n, dtype=np.bool_)
    clear_stars(order[got], tri, start, corner, flags)
    touched = np.zeros(n, dtype=bool)
    for v in order[got]:
        touched[tri[(tri == v).any(axis=1)].ravel()] = True
    assert np.array_equal(~flags, touched)


def test_node_lists_follow_flips_in_place() -> None:
    """After nodes move and Lawson flips change some triangles, the padded node lists updated
    in place (adjacency's free slots, flip_update) hold exactly the new triangulation's neighbours, each
    entry pointing at a bar with those two ends."""
    from injmesh.kernels.delaunay import flips_logged
    from injmesh.kernels.mesh import neighbours
    from injmesh.kernels.smooth import flip_diff, flip_update

    key = np.int64(2**31)

    def side_keys(tri: np.ndarray) -> np.ndarray:
        a = tri.astype(np.int64)
        u = np.concatenate([a[:, 0], a[:, 1], a[:, 2]])
        v = np.concatenate([a[:, 1], a[:, 2], a[:, 0]])
        return np.unique(np.minimum(u, v) * key + np.maximum(u, v))

    exercised = 0
    for seed in range(60):
        rng = np.random.default_rng(seed)
        n = int(rng.integers(10, 150))
        p = rng.random((n, 2))
        t32 = np.ascontiguousarray(delaunay(p), dtype=np.int32)
        indptr, adj, eid, bars = adjacency(n, t32, 3)
        nbr = np.asarray(neighbours(t32.astype(np.int64), n), dtype=np.int32)
        vt = np.full(n, -1, dtype=np.int32)
        vt[t32.ravel()] = np.repeat(np.arange(len(t32), dtype=np.int32), 3)
        before = t32.copy()
        q = p + rng.normal(0.0, 0.02, p.shape)
        res, log = flips_logged(q, t32, nbr, np.zeros(t32.shape, dtype=np.uint8), vt,
                                np.empty(0, dtype=np.int32), True)
        if res <= 0:
            continue  # an inverted triangle (the caller re-triangulates) or nothing to flip
        assert len(log) == res
        changed = np.flatnonzero((t32 != before).any(axis=1))
        old_e, new_e = side_keys(before[changed]), side_keys(t32[changed])
        removed, added = np.setdiff1d(old_e, new_e), np.setdiff1d(new_e, old_e)
        assert len(removed) == len(added) > 0
        # The difference followed from the log is the sets' difference, in sorted order, and
        # its rows hold every row that changed (a row flipped back and forth may be listed).
        rows, removed2, added2 = flip_diff(log[:, :2].ravel(), log[:, 2:4], log[:, 4:6])
        assert set(changed.tolist()) <= set(rows.tolist())
        assert np.array_equal(rows, np.unique(log[:, :2]))
        # The same from the rows' contents before and after (a patch's rows replaced).

        def sides(t: np.ndarray) -> np.ndarray:
            return np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])

        every = np.arange(len(t32))
        rows3, removed3, added3 = flip_diff(every, sides(before), sides(t32))
        assert np.array_equal(rows3, every)
        assert np.array_equal(removed3, removed2) and np.array_equal(added3, added2)
        assert np.array_equal(removed2, np.stack([removed // key, removed % key], axis=1))
        assert np.array_equal(added2, np.stack([added // key, added % key], axis=1))
        ids = flip_update(indptr, adj, eid, bars, removed2, added2)
        if len(ids) != len(removed):
            continue  # a row ran out of free slots: the caller rebuilds
        exercised += 1
        expected = {tuple(e) for e in unique_edges(t32.astype(np.int64)).tolist()}
        got = set()
        for v in range(n):
            for e in range(indptr[v], indptr[v + 1]):
                if adj[e] >= 0:
                    assert tuple(sorted((v, int(adj[e])))) == tuple(bars[eid[e]])
                    got.add(tuple(sorted((v, int(adj[e])))))
        assert got == expected
    assert exercised >= 5


@pytest.mark.parametrize("neighbours", [6, 12, 24])
def test_a_node_pulled_by_many_stretched_bars_does_not_overshoot(neighbours: int) -> None:
    """A node in a hole (its bars five times their rest length) pulled from all sides: the
    plain Euler step (2.4) has gain DT * hbar * sum(1/ld) >= 2 there and swings across the
    hole for ever; the stability limit moves it towards its equilibrium without passing it."""
    from injmesh.kernels.smooth import stable_scale
    from injmesh.smoothing import DT, STABLE_GAIN

    ang = 2 * np.pi * np.arange(neighbours) / neighbours
    ring = 5.0 * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    p = np.concatenate([[[0.3, -0.2]], ring])
    tri = np.array([[0, 1 + k, 1 + (k + 1) % neighbours] for k in range(neighbours)], dtype=np.int32)
    indptr, adj, eid, bars = adjacency(len(p), tri, 0)
    ld = np.ones(len(bars))
    hbar = mean_bar_size(indptr, eid, ld)
    damp = np.ones(len(p))
    for _ in range(30):
        total = np.zeros_like(p)
        stable_scale(p, np.array([0]), indptr, adj, eid, ld, DT * hbar, STABLE_GAIN, damp)
        bar_forces(p, np.array([0]), indptr, adj, eid, ld, 0.0, total, damp)
        before = np.hypot(*p[0])
        p[0] += DT * hbar[0] * total[0]
        after = np.hypot(*p[0])
        assert after <= before + 1e-15  # no overshoot past the centre
    assert np.hypot(*p[0]) < 1e-6


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000))
def test_renew_neighbours_after_a_patch_is_rewritten(seed: int) -> None:
    """The slow tail's patch writes its flipped triangles over its own rows, in another order
    and starting corner: the neighbour table renewed from those rows alone equals the table
    built from scratch."""
    from injmesh.kernels.delaunay import flip_to_delaunay
    from injmesh.kernels.mesh import neighbours, renew_neighbours

    rng = np.random.default_rng(seed)
    n = int(rng.integers(20, 300))
    p = rng.random((n, 2))
    t32 = np.ascontiguousarray(delaunay(p), dtype=np.int32)
    nbr = np.asarray(neighbours(t32.astype(np.int64), n), dtype=np.int32)
    # A patch: the triangles near a random point; its interior nodes move, it re-flips alone.
    centre = rng.random(2)
    rows = np.flatnonzero(np.hypot(*(p[t32].mean(axis=1) - centre).T) < 0.3)
    if len(rows) == 0:
        return
    sub = t32[rows].copy()
    inner = np.setdiff1d(np.unique(sub), np.unique(t32[np.setdiff1d(np.arange(len(t32)), rows)]))
    q = p.copy()
    q[inner] += rng.normal(0.0, 0.01, (len(inner), 2))
    sub_nbr = np.asarray(neighbours(sub.astype(np.int64), n), dtype=np.int32)
    vt = np.full(n, -1, dtype=np.int32)
    vt[sub.ravel()] = np.repeat(np.arange(len(sub), dtype=np.int32), 3)
    if flip_to_delaunay(q, sub, sub_nbr, np.zeros(sub.shape, dtype=np.uint8), vt) < 0:
        return  # an inverted triangle: the caller falls back to the whole mesh
    order = rng.permutation(len(rows))
    t32[rows] = np.roll(sub[order], int(rng.integers(0, 3)), axis=1)
    renew_neighbours(t32, nbr, rows.astype(np.int64))
    assert np.array_equal(nbr, np.asarray(neighbours(t32.astype(np.int64), n), dtype=np.int32))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_quality_pass_raises_stars_and_keeps_the_mesh_valid(seed: int) -> None:
    """The compiled quality pass (smoothing._optimize) on a jittered mesh: no triangle turns
    over, the worst q does not drop and rises where there was room, immovable nodes stay,
    boundary nodes stay on the boundary, every node stays inside."""
    from injmesh import generate
    from injmesh.quality import signed_areas, triangle_quality
    from injmesh.smoothing import _optimize

    rng = np.random.default_rng(seed)
    square = Rectangle((0, 0), (1, 1))
    mesh = generate(square, 0.1)
    p, t = mesh.points.copy(), mesh.triangles
    on_boundary = np.abs(square.sdf(p)) < 1e-12
    movable = rng.random(len(p)) < 0.8
    jitter = rng.normal(0.0, 0.02, p.shape)
    jitter[on_boundary] = 0.0
    q_try = p + jitter
    if (signed_areas(q_try, t) <= 0).any():
        return  # the jitter turned a triangle over: not an input the pass is for
    out = _optimize(square, q_try, t, movable, on_boundary, mesh.boundary_edges)
    assert (signed_areas(out, t) > 0).all()
    assert np.array_equal(out[~movable], q_try[~movable])
    assert np.abs(square.sdf(out[on_boundary])).max() < 1e-9
    assert (square.sdf(out) <= 1e-12).all()
    before, after = triangle_quality(q_try, t), triangle_quality(out, t)
    assert after.min() >= before.min()
    assert after.mean() > before.mean()



def test_quality_pass_moves_each_node_a_bounded_number_of_times(monkeypatch: pytest.MonkeyPatch) -> None:
    """Neighbours can take turns raising their own star and lowering the other's for ever: the
    pass moves a node at most OPTIMIZE_MOVES times, so it ends on its own long before a large
    sweep cap, and still leaves the worst triangle no worse."""
    from injmesh import generate
    from injmesh import smoothing as S
    from injmesh.kernels import smooth as K
    from injmesh.quality import signed_areas, triangle_quality

    square = Rectangle((0, 0), (1, 1))
    mesh = generate(square, 0.05)
    p, t = mesh.points.copy(), mesh.triangles
    on_boundary = np.abs(square.sdf(p)) < 1e-12
    rng = np.random.default_rng(1)
    jitter = rng.normal(0.0, 0.006, p.shape)
    jitter[on_boundary] = 0.0
    q_try = p + jitter
    assert (signed_areas(q_try, t) > 0).all()
    moved: list[np.ndarray] = []
    restar = K.restar

    def spy(p, tri, start, by_node, q, star, nodes):  # type: ignore[no-untyped-def]
        moved.append(np.array(nodes))
        return restar(p, tri, start, by_node, q, star, nodes)

    monkeypatch.setattr(K, "restar", spy)
    monkeypatch.setattr(S, "OPTIMIZE_SWEEPS", 1000)
    out = S._optimize(square, q_try, t, ~on_boundary, on_boundary, mesh.boundary_edges)
    counts = np.bincount(np.concatenate(moved), minlength=len(p))
    assert 0 < counts.max() <= S.OPTIMIZE_MOVES
    assert len(moved) < 1000
    assert triangle_quality(out, t).min() >= triangle_quality(q_try, t).min()

def test_repair_keeps_each_part_at_its_best_round() -> None:
    """Bad triangles in two clusters far apart make a sub-mesh of two parts that share no
    node: each part keeps its own best round, so neither ends worse than it started (a single
    best round for both would keep the start as soon as one part got worse), and the result is
    a valid triangulation of the same region."""
    from injmesh import generate
    from injmesh.quality import signed_areas, triangle_quality
    from injmesh.smoothing import _Relaxation, _repair_rounds

    square = Rectangle((0, 0), (1, 1))
    mesh = generate(square, 0.04)
    p, t = mesh.points, mesh.triangles
    on = np.abs(square.sdf(p)) < 1e-12
    order = np.concatenate([np.flatnonzero(on), np.flatnonzero(~on)])
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    p, t = p[order].copy(), inv[t]
    rng = np.random.default_rng(3)
    start = p
    while True:  # jitter the two clusters, short of turning a triangle over
        p = start.copy()
        for centre in ((0.25, 0.25), (0.75, 0.7)):
            near = (np.hypot(*(p - centre).T) < 0.1) & (np.arange(len(p)) >= on.sum())
            p[near] += rng.normal(0.0, 0.008, (int(near.sum()), 2))
        if (signed_areas(p, t) > 0).all():
            break
    walls = inv[mesh.boundary_edges]
    relax = _Relaxation(square, lambda x: np.full(len(x), 0.04), p, int(on.sum()),
                        np.zeros((0, 3), dtype=np.intp), walls, None, 1000, tri=t, patch=True)
    q0 = triangle_quality(p, t)
    out_p, out_t, kept, _, _ = _repair_rounds(relax, np.arange(len(p)), int(on.sum()), walls)
    q1 = triangle_quality(out_p, out_t)
    assert (signed_areas(out_p, out_t) > 0).all()
    assert abs(float(np.abs(signed_areas(out_p, out_t)).sum()) - 1.0) < 1e-9
    assert len(np.unique(out_t)) == len(out_p)
    c0, c1 = p[t].mean(axis=1), out_p[out_t].mean(axis=1)
    for centre in ((0.25, 0.25), (0.75, 0.7)):
        before = q0[np.hypot(*(c0 - centre).T) < 0.2].min()
        after = q1[np.hypot(*(c1 - centre).T) < 0.2].min()
        assert after >= before - 1e-12
    assert q1.min() > q0.min()


def test_repair_scores_a_part_without_its_frozen_worst_triangle(monkeypatch: pytest.MonkeyPatch) -> None:
    """A part of the repair's sub-mesh whose worst triangle has three fixed nodes and no chord
    to split (its longest edge a segment: a sharp tip) keeps that triangle whatever a round
    does.  Scored with it, no round could be kept and the part was left alone; scored without
    it, the part's other bad triangles are offered for edits and come out no worse.  A second
    part far away, pinned by nothing, is repaired as before."""
    from injmesh import generate
    from injmesh import smoothing as S
    from injmesh.quality import signed_areas, triangle_quality

    square = Rectangle((0, 0), (1, 1))
    mesh = generate(square, 0.02)
    p = mesh.points.copy()
    rng = np.random.default_rng(5)
    for centre in ((0.25, 0.25), (0.75, 0.7)):  # jitter two clusters far apart
        near = (np.hypot(*(p - centre).T) < 0.1) & (np.abs(square.sdf(p)) > 1e-12)
        p[near] += rng.normal(0.0, 0.003, (int(near.sum()), 2))
    t = delaunay(p).astype(np.intp)  # the square is convex: every Delaunay triangle is inside
    q = triangle_quality(p, t)
    centres = p[t].mean(axis=1)
    first = np.hypot(*(centres - (0.25, 0.25)).T) < 0.2
    worst = np.flatnonzero(first)[np.argmin(q[first])]
    # Fixed: the boundary and the three nodes of the first cluster's worst triangle.
    fixed = np.abs(square.sdf(p)) < 1e-12
    fixed[t[worst]] = True
    order = np.concatenate([np.flatnonzero(fixed), np.flatnonzero(~fixed)])
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    p, t = p[order], inv[t]
    n_fixed = int(fixed.sum())
    near_first = np.hypot(*(p[t].mean(axis=1) - (0.25, 0.25)).T) < 0.2
    others = near_first & (t.max(axis=1) >= n_fixed)
    q = triangle_quality(p, t)
    pinned_q = q[near_first & (t.max(axis=1) < n_fixed)].min()
    assert pinned_q < q[others].min()

    # Its longest edge is a segment (an interior curve's, say): no chord to split.
    worst_row = np.flatnonzero(near_first & (t.max(axis=1) < n_fixed))[0]
    w = t[worst_row]
    ends = np.stack([w, np.roll(w, -1)], axis=1)
    wall = ends[np.argmax(np.hypot(*(p[ends[:, 0]] - p[ends[:, 1]]).T))][None, :]
    edited: list[np.ndarray] = []
    choose = S._choose_repairs

    def spy(relax, p, tri, bad, chord):  # type: ignore[no-untyped-def]
        edited.append(p[tri[bad]].mean(axis=1))
        return choose(relax, p, tri, bad, chord)

    monkeypatch.setattr(S, "_choose_repairs", spy)
    relax = S._Relaxation(square, lambda x: np.full(len(x), 0.02), p, n_fixed,
                          np.zeros((0, 3), dtype=np.intp), wall, None, 1000, tri=t)
    out_p, out_t, _, _, _ = S._repair(relax, np.arange(len(p)))
    edited_at = np.concatenate(edited)
    assert (np.hypot(*(edited_at - (0.25, 0.25)).T) < 0.2).any(), "the tip's part was not repaired"
    assert (np.hypot(*(edited_at - (0.75, 0.7)).T) < 0.2).any(), "the other part was not repaired"
    frozen = np.sort(t[worst_row])

    def rest_min(pp: np.ndarray, tt: np.ndarray) -> float:
        """q_min near the first cluster over every triangle but the frozen one."""
        near = np.hypot(*(pp[tt].mean(axis=1) - (0.25, 0.25)).T) < 0.2
        other = ~(np.sort(tt, axis=1) == frozen).all(axis=1)
        return float(triangle_quality(pp, tt)[near & other].min())

    # Fixed nodes keep their numbers and places.  The frozen triangle may be flipped away
    # (a free node moved into its circle); what replaces it counts in the score like the rest.
    assert np.array_equal(out_p[:n_fixed], p[:n_fixed])
    assert rest_min(out_p, out_t) >= rest_min(p, t)
    q1 = triangle_quality(out_p, out_t)
    c1 = out_p[out_t].mean(axis=1)
    assert q1[np.hypot(*(c1 - (0.25, 0.25)).T) < 0.2].min() >= pinned_q
    assert q1[np.hypot(*(c1 - (0.75, 0.7)).T) < 0.2].min() > q[
        np.hypot(*(p[t].mean(axis=1) - (0.75, 0.7)).T) < 0.2].min()
    assert (signed_areas(out_p, out_t) > 0).all()


def _reference_step(p, free, total, hbar, deep, anchor, d0, reach, sdf, cand, near, c, tol):
    """The near nodes' part of a step as the NumPy lines the fused kernels replaced: the anchor
    test, the domain's inside test for the rest, the accepted moves and their reductions."""
    idx, new = near[:c], cand[:c]
    ok = np.hypot(*(new - anchor[idx]).T) < -reach * d0[idx]
    asks = int(np.count_nonzero(~ok))
    rest = np.flatnonzero(~ok)
    if len(rest):
        ok[rest] = ~(sdf(new[rest]) > 0)
    idx, new = idx[ok], new[ok]
    worst, at, drift, count = -1.0, -1, 0.0, 0
    if len(idx):
        hb = hbar[idx]
        mv = np.hypot(*(new - p[idx]).T) / hb
        count = int(np.count_nonzero(mv > tol))
        p[idx] = new
        drift = float(np.max(np.hypot(*(new - anchor[idx]).T) / hb))
        a = int(np.argmax(mv))
        worst, at = float(mv[a]), int(idx[a])
    return asks, worst, at, drift, count


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(8, 120), attraction=st.sampled_from([ATTRACTION, 0.0]))
def test_fused_step_kernels_equal_the_separate_calls(seed: int, n: int, attraction: float) -> None:
    """step_free = bar_forces + advance + the anchor test, and take_near / fold_moves give the
    NumPy reductions they replace, bit for bit (the meshes must not change)."""
    from injmesh.kernels.smooth import fold_moves, near_inside, step_free, take_near

    rng = np.random.default_rng(seed)
    p, tri = _mesh(seed % 1000, n)
    indptr, adj, eid, bars = adjacency(n, tri, 0)
    ld = rng.uniform(0.05, 0.4, len(bars))
    hbar = mean_bar_size(indptr, eid, ld)
    hbar[hbar == 0] = 0.1
    n_fixed = min(3, n - 1)
    free = np.arange(n_fixed, n)
    moving = np.arange(n)
    deep = rng.random(n) < 0.5
    anchor = p + rng.normal(scale=0.01, size=p.shape)
    damp = rng.uniform(0.5, 1.0, n)

    def sdf(q):  # a square's (exact inside), a little smaller than the points': some steps are refused
        return np.max(np.abs(q - 0.5), axis=1) - 0.48

    d0 = np.minimum(sdf(anchor), 0.0)  # the depth of each anchor (0 outside)

    # Reference: the separate kernels, then NumPy.
    pr, totr = p.copy(), np.zeros_like(p)
    candr, nearr = np.empty((len(free), 2)), np.empty(len(free), dtype=np.intp)
    bar_forces(pr, moving, indptr, adj, eid, ld, attraction, totr, damp)
    c, w0, a0, dr0, n0 = advance(pr, free, totr, hbar, DT, 0.5, deep, anchor, candr, nearr, 0.003)
    asks_r, w1, a1, dr1, n1 = _reference_step(pr, free, totr, hbar, deep, anchor, d0, 0.5, sdf, candr, nearr,
                                              c, 0.003)
    worst_r, at_r = (w1, a1) if w1 > w0 else (w0, a0)
    # Fused.
    pf, totf = p.copy(), np.zeros_like(p)
    candf, nearf = np.empty((len(free), 2)), np.empty(len(free), dtype=np.intp)
    ok = np.empty(len(free), dtype=np.bool_)
    cf, w, a, dr, cnt, asks = step_free(pf, moving, free, indptr, adj, eid, ld, attraction, totf, damp, hbar,
                                        DT, 0.5, deep, anchor, d0, 0.5, candf, nearf, ok, 0.003)
    assert (cf, w, a, dr, cnt) == (c, w0, a0, dr0, n0)
    assert np.array_equal(totf, totr) and np.array_equal(candf[:c], candr[:c])
    assert np.array_equal(nearf[:c], nearr[:c])
    assert asks == asks_r == near_inside(candf, nearf, c, anchor, d0, 0.5, ok.copy())
    rest = np.flatnonzero(~ok[:c])
    ok[rest] = ~(sdf(candf[rest]) > 0)
    w, a, dr, cnt = take_near(pf, nearf, candf, c, ok, hbar, anchor, 0.003, w, a, dr, cnt)
    assert np.array_equal(pf, pr), "the same positions, bit for bit"
    assert (w, a, dr, cnt) == (worst_r, at_r, max(dr0, dr1), n0 + n1)
    moved_near = nearf[:c][ok[:c]]
    assert np.all(sdf(pf[moved_near]) <= 0), "no near node leaves the domain"
    # fold_moves: the sliding nodes' reductions.
    nodes = rng.choice(n, size=min(n, 10), replace=False)
    mv = rng.uniform(0.0, 0.01, len(nodes))
    got = fold_moves(nodes, mv, pf, anchor, hbar, 0.003, -1.0, -1, 0.0, 0)
    k = int(np.argmax(mv))
    ref_drift = float(np.max(np.hypot(*(pf[nodes] - anchor[nodes]).T) / hbar[nodes]))
    assert got == (float(mv[k]), int(nodes[k]), ref_drift, int(np.count_nonzero(mv > 0.003)))


def test_repair_splits_the_chord_of_a_flat_cap_but_never_a_tip_or_a_segment() -> None:
    """A triangle of three boundary nodes whose longest edge is a chord (inside the domain, not
    a segment) gets that chord to split (``_chords``); a sharp tip's triangle, whose chord is its
    shortest edge, and a triangle whose longest edge is a segment get none; nor does a cap whose
    neighbour across the chord has three boundary nodes too (a strip one triangle wide: the new
    node would have nowhere to go)."""
    from injmesh.smoothing import _chords, _keys

    # Boundary nodes 0-4; node 5 free.  (0, 1, 2): a flat cap, chord 0-2 the longest edge;
    # (2, 3, 4): a sharp tip at 3, its chord 2-4 its shortest edge; (0, 2, 5), (2, 4, 5):
    # triangles with the free node.
    p = np.array([(0.0, 0.0), (0.5, -0.3), (1.0, 0.0), (3.0, 0.4), (1.0, 0.5), (0.4, 0.6)])
    tri = np.array([(0, 1, 2), (2, 3, 4), (0, 2, 5), (2, 4, 5)])
    walls = np.array([(0, 1), (1, 2), (2, 3), (3, 4)])
    chord = _chords(p, tri, 5, _keys(walls))
    assert chord.tolist() == [2, -1, -1, -1]  # edge (tri[0][2], tri[0][0]) = 0-2 only
    # The same cap with its chord a segment: nothing.
    assert (_chords(p, tri, 5, _keys(np.concatenate([walls, [(2, 0)]]))) < 0).all()
    # Node 5 on the boundary too: (0, 2, 5) across the cap's chord has no free node.
    assert _chords(p, tri, 6, _keys(walls))[0] == -1


@pytest.mark.parametrize("h", [0.03, 0.05, 0.07, 0.1])
def test_square_corners_have_no_flat_cap(h: float) -> None:
    """At a right-angled corner whose two boundary neighbours are joined by an edge, the cap is
    a right isosceles triangle (q 0.828) that no node move can change; the repair splits its
    chord, and the corner's two triangles of 45 degrees do better (q_min 0.91 at these h)."""
    from injmesh import generate
    from injmesh.smoothing import REPAIR_Q

    square = Rectangle((0, 0), (1, 1))
    mesh = generate(square, h)
    p, t = mesh.points, mesh.triangles
    on = np.abs(square.sdf(p)) < 1e-9
    q = mesh.quality()
    caps = on[t].all(axis=1) & (q < REPAIR_Q)
    assert not caps.any()
    assert q.min() > 0.85


_KINDS = {
    "circle": lambda: Circle((0.3, -0.2), 0.7),
    "rectangle": lambda: Rectangle((-1, -0.5), (2, 1)),
    "polygon": lambda: Polygon([(0, 0), (2, 0), (2, 1), (1, 0.4), (0, 1)]),
    "csg": lambda: Rectangle((-1, -1), (1, 1)) - Circle((0.2, 0.1), 0.4),
}


@pytest.mark.parametrize("name", list(_KINDS))
@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_compiled_boundary_answers_as_the_methods(name: str, seed: int) -> None:
    """boundary_query gives the numbers of the domain's sdf and project, bit for bit (the
    compiled relaxation must make the meshes the Python loop made)."""
    dom = _KINDS[name]()
    kb = dom.kernel_boundary()
    assert kb is not None
    rng = np.random.default_rng(seed)
    x0, y0, x1, y1 = dom.bbox
    q = rng.uniform([x0 - 0.3, y0 - 0.3], [x1 + 0.3, y1 + 0.3], (40, 2))
    q[:5] = dom.project(q[:5])  # on the boundary: the sign and foot of the tie cases
    foot = np.empty_like(q)
    d = boundary_query(q, *kb, foot)
    assert np.array_equal(d, dom.sdf(q))
    assert np.array_equal(foot, dom.project(q))


def test_a_domain_with_its_own_methods_has_no_compiled_boundary() -> None:
    class Wobbly(Circle):
        def sdf(self, p):  # type: ignore[no-untyped-def]
            return super().sdf(p) * 1.0

    assert Wobbly((0, 0), 1).kernel_boundary() is None
    assert Implicit(lambda p: np.hypot(p[:, 0], p[:, 1]) - 1, (-1, -1, 1, 1)).kernel_boundary() is None


_REGIONS = {
    "inclusions": {"regions": {"disc": Circle((0.6, -0.6), 0.25),
                               "wedge": Polygon([(-0.9, -0.9), (-0.3, -0.9), (-0.6, -0.4)])}},
    "crack": {"curves": {"crack": np.array([(-0.8, 0.6), (-0.2, 0.5), (0.3, 0.8)])}},
}


@pytest.mark.parametrize("name", [*_KINDS, *_REGIONS])
def test_compiled_steps_make_the_mesh_of_the_python_loop(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The relaxation's compiled runs and updates (kernels.smooth.run_steps, relink, resize)
    and the quality pass's compiled trials (optimize_trials), and the loops over kernels and
    the domain's and curves' methods give the same mesh, bit for bit, graded h, repair rounds
    and regions' interior curves included."""
    import injmesh.smoothing as S

    dom = _KINDS["csg"]() if name in _REGIONS else _KINDS[name]()
    kw = _REGIONS.get(name, {})
    x0, y0 = dom.bbox[:2]

    def h(p: np.ndarray) -> np.ndarray:
        return 0.08 + 0.1 * np.hypot(p[:, 0] - x0, p[:, 1] - y0)

    used = []
    init = S._Relaxation.__init__

    def spy(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        init(self, *args, **kwargs)
        used.append(self._kernel_boundary is not None)

    monkeypatch.setattr(S._Relaxation, "__init__", spy)
    compiled = generate(dom, h, **kw)
    assert all(used)  # every relaxation stepped in compiled calls
    monkeypatch.undo()

    # No projector offers the kernels its boundaries: every step, update and quality-pass
    # trial goes through the Python loops and the domain's and curves' methods.
    for cls in (S._OnDomain, S._OnCurves, S._Renumbered):
        monkeypatch.setattr(cls, "compiled", lambda self, domain, nodes: None)
    loop = generate(dom, h, **kw)
    assert compiled.stats.iterations == loop.stats.iterations
    assert np.array_equal(compiled.points, loop.points)
    assert np.array_equal(compiled.triangles, loop.triangles)
    if kw:
        assert np.array_equal(compiled.triangle_tags, loop.triangle_tags)


@pytest.mark.parametrize("seed", range(4))
def test_relaxation_set_up_kernels_equal_the_numpy_lines(seed: int) -> None:
    """``moving_nodes`` and ``vertex_rows`` (a relaxation's set-up in fewer calls) against the
    NumPy lines they replace."""
    from injmesh.kernels.smooth import moving_nodes, vertex_rows

    rng = np.random.default_rng(seed)
    p, t32 = _mesh(seed, 80)
    n, n_fixed = len(p), 10
    b = np.arange(n_fixed, dtype=np.int64)
    slide = np.stack([b, np.roll(b, 1), np.roll(b, -1)], axis=1)
    for active in (np.zeros(0, dtype=np.bool_), rng.random(n) < 0.5):
        free, sl, moving, is_free = moving_nodes(n, n_fixed, active, slide)
        ref_free = np.arange(n_fixed, n)
        ref_sl = slide
        if len(active):
            ref_free = ref_free[active[n_fixed:]]
            ref_sl = slide[active[slide[:, 0]]]
        ref_is_free = np.zeros(n, dtype=bool)
        ref_is_free[ref_free] = True
        assert np.array_equal(free, ref_free) and np.array_equal(sl, ref_sl)
        assert np.array_equal(moving, np.concatenate([ref_free, ref_sl[:, 0]]))
        assert np.array_equal(is_free, ref_is_free)
    vt = np.full(n + 1, -1, dtype=np.int32)  # the last node is in no triangle
    vt[t32.ravel()] = np.repeat(np.arange(len(t32), dtype=np.int32), 3)
    assert np.array_equal(vertex_rows(t32, n + 1), vt)
