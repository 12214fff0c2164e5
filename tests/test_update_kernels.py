"""The kernels of a connectivity update (kernels/smooth.py ``moved_bars``, ``renew_sizes``;
kernels/mesh.py ``by_least_vertex``, ``kept_neighbours``) against the calls they fuse or
replace: the same numbers, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh.kernels.mesh import by_least_vertex, kept_neighbours, neighbours
from injmesh.kernels.smooth import (
    adjacency,
    mean_bar_size_of,
    moved_bars,
    renew_sizes,
    ring_one,
    row_bars,
    stable_scale,
    threaded_renew_sizes,
)
from injmesh.kernels.threads import limit
from injmesh.smoothing import DT, STABLE_GAIN
from injmesh.triangulation import delaunay_with_neighbours


def _mesh(seed: int, n: int, lattice: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    if lattice:  # cocircular quadruples everywhere: ties in the triangulation
        k = max(3, int(np.sqrt(n)))
        g = np.arange(k, dtype=float)
        p = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    else:
        p = rng.random((n, 2))
    tri, nbr = delaunay_with_neighbours(p)
    return p, tri, nbr


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.integers(4, 400), st.booleans(), st.floats(0.0, 1.0))
def test_kept_neighbours_are_the_neighbours_of_the_triangles_kept(
    seed: int, n: int, lattice: bool, share: float
) -> None:
    """Any subset of a triangulation's triangles, in the least-vertex order the relaxation
    keeps them in: the table remapped from the whole one is the table found from scratch."""
    p, tri, nbr = _mesh(seed, n, lattice)
    keep = np.random.default_rng(seed + 1).random(len(tri)) < share
    rows = np.flatnonzero(keep)
    sub = tri[rows]
    order = by_least_vertex(sub, len(p))
    assert np.array_equal(order, np.argsort(sub.min(axis=1), kind="stable"))
    got = kept_neighbours(kept_neighbours(nbr, rows), order)
    t32 = np.ascontiguousarray(sub[order], dtype=np.int32)
    assert got.dtype == np.int32
    assert np.array_equal(got, neighbours(t32, len(p)))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10**6), st.integers(20, 500), st.lists(st.integers(0, 10**6), max_size=80),
       st.booleans(), st.booleans())
def test_fused_update_kernels_give_the_separate_kernels_numbers(
    seed: int, n: int, raw: list[int], graded: bool, threaded: bool
) -> None:
    """``moved_bars`` = ``ring_one`` + ``row_bars`` + the bars' midpoints, and
    ``renew_sizes`` = ``mean_bar_size_of`` then ``stable_scale`` with step ``DT * hbar``, bit
    for bit (also over chunks on threads), on padded rows with repeated seeds, and both leave
    their scratch arrays zeroed."""
    rng = np.random.default_rng(seed)
    p, tri, _ = _mesh(seed, n, False)
    indptr, adj, eid, bars = adjacency(len(p), tri.astype(np.int32), 3)
    nodes = np.unique(np.array([r % len(p) for r in raw], dtype=np.int64))
    mark = np.zeros(len(p), dtype=np.uint8)
    seen = np.zeros(len(bars), dtype=np.bool_)
    near, b, mid = moved_bars(indptr, adj, eid, bars, p, nodes, mark, seen, graded)
    assert not mark.any() and not seen.any()
    assert np.array_equal(near, ring_one(indptr, adj, nodes, mark))
    if graded:
        ref_b = row_bars(indptr, eid, nodes, seen)
        assert np.array_equal(b, ref_b)
        assert np.array_equal(mid, 0.5 * (p[bars[ref_b, 0]] + p[bars[ref_b, 1]]))
    else:
        assert len(b) == 0 and len(mid) == 0

    ld = 0.05 + 0.1 * rng.random(len(bars))
    hbar0 = 0.05 + 0.1 * rng.random(len(p))
    hbar_ref, damp_ref = hbar0.copy(), np.ones(len(p))
    if graded:
        mean_bar_size_of(indptr, eid, ld, near, hbar_ref)
    stable_scale(p, near, indptr, adj, eid, ld, DT * hbar_ref, STABLE_GAIN, damp_ref)
    hbar, damp = hbar0.copy(), np.ones(len(p))
    if threaded:
        from injmesh.kernels import threads

        old = threads.MIN_CHUNK
        threads.MIN_CHUNK = 4  # split these small lists as a large mesh's are
        try:
            with limit(2):
                threaded_renew_sizes(p, near, indptr, adj, eid, ld, DT, STABLE_GAIN, graded, hbar,
                                     damp)
        finally:
            threads.MIN_CHUNK = old
    else:
        renew_sizes(p, near, indptr, adj, eid, ld, DT, STABLE_GAIN, graded, hbar, damp)
    assert np.array_equal(hbar, hbar_ref)
    assert np.array_equal(damp, damp_ref)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 200), max_size=80), st.lists(st.integers(0, 220), max_size=12),
       st.booleans())
def test_nodes_joined_in_place_are_the_union(nodes: list[int], more: list[int], shuffled: bool) -> None:
    """``smoothing._with_nodes`` (the moved nodes and the flips' corners of an update) is
    ``np.union1d``, for sorted lists (inserted in place) and unsorted ones (a patch's)."""
    from injmesh.smoothing import _with_nodes

    a = np.unique(np.array(nodes, dtype=np.intp))
    if shuffled:
        a = np.random.default_rng(len(nodes)).permutation(a)
    b = np.array(more, dtype=np.int64)
    assert np.array_equal(_with_nodes(a, b), np.union1d(a, b))


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 300), st.booleans(), st.floats(0.0, 0.5))
def test_depth_bounds_are_the_vectorised_test(seed: int, n: int, exact: bool, nan_share: float) -> None:
    """``depth_bounds`` + ``mark_deep`` give ``_inside_depth``'s NumPy form bit for bit: the
    bound ``d0 + |p - anchor|`` kept where it is below ``-DEEP * hbar``, every other node (and
    any with a NaN anchor, or all without ``exact``) asked, then the deep flags."""
    from injmesh.kernels.smooth import depth_bounds, mark_deep
    from injmesh.smoothing import DEEP

    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    anchor = p + rng.normal(0.0, 0.05, p.shape)
    anchor[rng.random(n) < nan_share] = np.nan
    d0 = rng.normal(-0.5, 0.4, n)
    hbar = 0.05 + 0.2 * rng.random(n)
    free = np.flatnonzero(rng.random(n) < 0.7).astype(np.int64)
    d_of = rng.normal(-0.3, 0.3, n)  # what the domain would answer

    want_d0 = d0.copy()
    bound = d0[free] + np.hypot(*(p[free] - anchor[free]).T)
    if not exact:
        bound[:] = np.nan
    sure = bound < -DEEP * hbar[free]
    want_d0[free[sure]] = bound[sure]
    want_ask = free[~sure]
    want_d0[want_ask] = d_of[want_ask]
    want_deep = np.zeros(n, dtype=bool)
    want_deep[free] = want_d0[free] < -DEEP * hbar[free]

    got_d0 = d0.copy()
    ask = depth_bounds(p, anchor, got_d0, hbar, free, DEEP, exact)
    got_d0[ask] = d_of[ask]
    deep = np.zeros(n, dtype=np.bool_)
    mark_deep(got_d0, hbar, free, DEEP, deep)
    assert np.array_equal(ask, want_ask)
    assert np.array_equal(got_d0, want_d0, equal_nan=True)
    assert np.array_equal(deep, want_deep)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10**6), st.integers(3, 300), st.integers(0, 4), st.integers(0, 5),
       st.booleans())
def test_padded_adjacency_is_the_rows_with_free_slots(
    seed: int, n: int, slack: int, lonely: int, lattice: bool
) -> None:
    """``adjacency(n, tri, slack)``: each row of the unpadded lists followed by ``slack`` free
    slots (-1 in ``adj`` and ``eid``), the same bars, with nodes in no triangle too."""
    p, tri, _ = _mesh(seed, n, lattice)
    t32 = tri.astype(np.int32)
    m = len(p) + lonely
    indptr, adj, eid, bars = adjacency(m, t32, 0)
    got_ptr, got_adj, got_eid, got_bars = adjacency(m, t32, slack)
    assert np.array_equal(got_bars, bars)
    assert np.array_equal(np.diff(got_ptr), np.diff(indptr) + slack)
    for v in range(m):
        row = slice(got_ptr[v], got_ptr[v + 1])
        filled = got_ptr[v] + indptr[v + 1] - indptr[v]
        assert np.array_equal(got_adj[got_ptr[v]:filled], adj[indptr[v]:indptr[v + 1]])
        assert np.array_equal(got_eid[got_ptr[v]:filled], eid[indptr[v]:indptr[v + 1]])
        assert (got_adj[row][filled - got_ptr[v]:] == -1).all()
        assert (got_eid[row][filled - got_ptr[v]:] == -1).all()
