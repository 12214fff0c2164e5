"""The repair rounds' compiled bookkeeping (kernels/repair.py) against NumPy references.

Each reference is the NumPy form the kernel replaced in ``smoothing``; the kernels must give
the same arrays bit for bit (the meshes depend on every row order and tie)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from injmesh.kernels.delaunay import flip_rows_to_delaunay, flip_to_delaunay
from injmesh.kernels.mesh import by_least_vertex, neighbours, rows_with
from injmesh.kernels.repair import (
    apply_edits,
    canonical,
    choose_edits,
    chords,
    components,
    edge_midpoints,
    flip_near,
    patch_merge,
    patch_of,
    round_state,
    stitch,
    sub_mesh_of,
)
from injmesh.kernels.smooth import adjacency, rings
from injmesh.quality import triangle_quality
from injmesh.triangulation import delaunay

KEY = 1 << 31
NONE = np.zeros(0, dtype=np.int64)  # no excused triangle


def _mesh(seed: int, n: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """Random nodes (the first 12 on the unit square's sides: "boundary" nodes) and their
    Delaunay triangles, int64."""
    rng = np.random.default_rng(seed)
    s = rng.random(12)
    side = np.arange(12) % 4
    edge = np.stack([np.where(side == 0, s, np.where(side == 1, 1.0, np.where(side == 2, s, 0.0))),
                     np.where(side == 0, 0.0, np.where(side == 1, s, np.where(side == 2, 1.0, s)))],
                    axis=1)
    p = np.concatenate([edge, 0.05 + 0.9 * rng.random((n - 12, 2))])
    return p, np.ascontiguousarray(delaunay(p), dtype=np.int64)


def _ref_keys(edges: np.ndarray) -> np.ndarray:
    e = np.asarray(edges).reshape(-1, 2)
    return np.sort(np.minimum(e[:, 0], e[:, 1]).astype(np.int64) * KEY + np.maximum(e[:, 0], e[:, 1]))


def _ref_chords(p, tri, n_boundary, seg_keys):  # type: ignore[no-untyped-def]
    out = np.full(len(tri), -1, dtype=np.intp)
    cand = np.flatnonzero(tri.max(axis=1) < n_boundary)
    if not len(cand):
        return out
    t = tri[cand]
    b = t[:, [1, 2, 0]]
    k = np.argmax(np.hypot(*(p[t] - p[b]).transpose(2, 0, 1)), axis=1)
    rows = np.arange(len(t))
    a_, b_ = t[rows, k], b[rows, k]
    keys = np.minimum(a_, b_).astype(np.int64) * KEY + np.maximum(a_, b_)
    chord = ~np.isin(keys, seg_keys)
    cand, k = cand[chord], k[chord]
    if not len(cand):
        return out
    across = np.asarray(neighbours(np.ascontiguousarray(tri, dtype=np.int32), len(p)))[cand, (k + 2) % 3]
    walled_in = (across >= 0) & (tri[across].max(axis=1) < n_boundary)
    out[cand[~walled_in]] = k[~walled_in]
    return out


def _ref_part_min(q, tri, label, n_parts):  # type: ignore[no-untyped-def]
    out = np.full(n_parts, np.inf)
    np.minimum.at(out, label[tri[:, 0]], q)
    return out


def _ref_choose(p, tri, bad, chord, hv, n_fixed):  # type: ignore[no-untyped-def]
    t = tri[bad]
    a = t
    b = t[:, [1, 2, 0]]
    mid = (0.5 * (p[a] + p[b])).reshape(-1, 2)
    ratio = np.hypot(*(p[a] - p[b]).transpose(2, 0, 1)) / hv.reshape(a.shape)
    short = np.argmin(ratio, axis=1)
    long_ = np.argmax(ratio, axis=1)
    rows = np.arange(len(t))
    do_collapse = (1.0 - ratio[rows, short]) > (ratio[rows, long_] - 1.0)
    capped = chord[bad] >= 0
    do_collapse &= ~capped
    k = np.where(capped, chord[bad], np.where(do_collapse, short, long_))
    ea, eb = a[rows, k], b[rows, k]
    swap = do_collapse & (eb < n_fixed)
    ea, eb = np.where(swap, eb, ea), np.where(swap, ea, eb)
    movable = (eb >= n_fixed) | (~do_collapse & (ea >= n_fixed)) | capped
    # A too-long edge of two fixed nodes: the free node opposite, inside its diametral circle,
    # is collapsed into the nearer end, if that end sees its whole star.
    w = t[rows, (k + 2) % 3]
    squeezed = np.einsum("ij,ij->i", p[ea] - p[w], p[eb] - p[w]) < 0
    drop_w = ~movable & ~do_collapse & (w >= n_fixed) & squeezed
    near = np.where(np.hypot(*(p[ea] - p[w]).T) <= np.hypot(*(p[eb] - p[w]).T), ea, eb)
    drop_w &= np.array([_ref_sees_star(p, tri, kk, ww) for kk, ww in zip(near, w, strict=True)], dtype=bool)
    ea, eb = np.where(drop_w, near, ea), np.where(drop_w, w, eb)
    do_collapse = do_collapse | drop_w
    movable |= drop_w
    ea, eb, do_collapse = ea[movable], eb[movable], do_collapse[movable]
    empty = np.zeros((0, 2), dtype=np.int64)
    if len(ea) == 0:
        return mid, empty, empty
    nodes = np.stack([ea, eb], axis=1)
    first_use = np.full(len(p), len(nodes))
    order = np.arange(len(nodes))
    np.minimum.at(first_use, nodes[:, 0], order)
    np.minimum.at(first_use, nodes[:, 1], order)
    ok = (first_use[ea] == order) & (first_use[eb] == order)
    key = np.minimum(ea, eb) * len(p) + np.maximum(ea, eb)
    _, uniq = np.unique(key, return_index=True)
    once = np.zeros(len(ea), dtype=bool)
    once[uniq] = True
    ok &= once
    return mid, np.stack([ea, eb], axis=1)[ok & do_collapse], np.stack([ea, eb], axis=1)[ok & ~do_collapse]


def _ref_sees_star(p, tri, keep, drop):  # type: ignore[no-untyped-def]
    star = tri[(tri == drop).any(axis=1) & ~(tri == keep).any(axis=1)]
    moved = np.where(star == drop, keep, star)
    a, b, c = p[moved[:, 0]], p[moved[:, 1]], p[moved[:, 2]]
    u, v = b - a, c - a
    return bool(np.all(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0] > 0))


def _ref_edit(p, tri, kept, label, collapse, split, n_fixed):  # type: ignore[no-untyped-def]
    n = len(p)
    alive = np.ones(n, dtype=bool)
    p = p.copy()
    mid = collapse[collapse[:, 0] >= n_fixed]
    p[mid[:, 0]] = 0.5 * (p[mid[:, 0]] + p[mid[:, 1]])
    alive[collapse[:, 1]] = False
    new = 0.5 * (p[split[:, 0]] + p[split[:, 1]])
    index = np.cumsum(alive) - 1
    out_p = np.concatenate([p[alive], new])
    out_kept = np.concatenate([kept[alive], np.full(len(new), -1)])
    out_label = np.concatenate([label[alive], label[split[:, 0]]])
    touched = np.concatenate([index[collapse[:, 0]], index[split.ravel()],
                              alive.sum() + np.arange(len(new))])
    t = np.array(tri, dtype=np.intp, copy=True)
    if len(split):
        u = t.ravel()
        v = t[:, [1, 2, 0]].ravel()
        key = np.minimum(u, v).astype(np.int64) * n + np.maximum(u, v)
        lo, hi = np.minimum(split[:, 0], split[:, 1]), np.maximum(split[:, 0], split[:, 1])
        skey = lo.astype(np.int64) * n + hi
        order = np.argsort(skey, kind="stable")
        pos = np.minimum(np.searchsorted(skey[order], key), len(skey) - 1)
        hit = np.flatnonzero(skey[order[pos]] == key)
        rows, k = np.divmod(hit, 3)
        m = n + order[pos[hit]]
        a, b, w = u[hit], v[hit], t[rows, (k + 2) % 3]
        t[rows] = np.stack([a, m, w], axis=1)
        t = np.concatenate([t, np.stack([m, b, w], axis=1)])
    if len(collapse):
        rename = np.arange(n + len(split))
        rename[collapse[:, 1]] = collapse[:, 0]
        t = rename[t]
        t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 2] != t[:, 0])]
    index = np.concatenate([np.cumsum(alive) - 1, int(alive.sum()) + np.arange(len(split))])
    return out_p, index[t], out_kept, out_label, touched


def _random_edits(seed: int, p, tri, n_fixed):  # type: ignore[no-untyped-def]
    """Edits as the rounds choose them, for random desired lengths."""
    rng = np.random.default_rng(seed)
    bad = rng.permutation(len(tri))[: len(tri) // 3].astype(np.int64)
    chord = _ref_chords(p, tri, n_fixed, _ref_keys(np.zeros((0, 2), dtype=np.int64)))
    hv = rng.uniform(0.05, 0.3, 3 * len(bad))
    return bad, chord, hv


@pytest.mark.parametrize("seed", range(6))
def test_rows_with_flagged_nodes_match_numpy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    p, tri = _mesh(seed)
    mark = rng.random(len(p)) < [0.0, 0.02, 0.1, 0.3, 0.7, 1.0][seed]
    assert np.array_equal(rows_with(tri, mark), np.flatnonzero(mark[tri].any(axis=1)))


@pytest.mark.parametrize("seed", range(6))
def test_components_partition_as_scipy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    p, tri = _mesh(seed)
    tri = tri[rng.random(len(tri)) < 0.4]  # several parts, some nodes in no triangle
    label, parts = components(np.ascontiguousarray(tri), len(p))
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    n_ref, ref = connected_components(
        coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(p), len(p))),
        directed=False)
    assert parts == n_ref
    # The same parts, numbered by their least node as scipy numbers them.
    assert np.array_equal(label, ref)


@pytest.mark.parametrize("seed", range(8))
def test_chords_and_round_state_match_numpy(seed: int) -> None:
    p, tri = _mesh(seed, n=40)
    rng = np.random.default_rng(seed)
    n_boundary = 12 + int(rng.integers(0, 20))  # many triangles of "fixed" nodes
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]]])
    segs = edges[rng.random(len(edges)) < 0.3]
    seg_keys = _ref_keys(segs)
    chord = chords(p, tri, n_boundary, seg_keys, KEY)
    assert np.array_equal(chord, _ref_chords(p, tri, n_boundary, seg_keys))
    n_fixed = n_boundary + 3
    label = (np.arange(len(p)) % 3).astype(np.int64)
    pinned = np.array([False, rng.random() < 0.5, False])
    q, ch, changeable, score, score_c, bad = round_state(p, tri, n_boundary, n_fixed, seg_keys,
                                                         KEY, label, 3, pinned, 0.85, NONE)
    ref_q = triangle_quality(p, tri)
    assert np.array_equal(q, ref_q)
    assert np.array_equal(ch, chord)
    ref_changeable = (tri.max(axis=1) >= n_fixed) | (chord >= 0)
    assert np.array_equal(changeable, ref_changeable)
    assert np.array_equal(score, _ref_part_min(ref_q, tri, label, 3))
    assert np.array_equal(score_c, _ref_part_min(ref_q[ref_changeable], tri[ref_changeable], label, 3))
    ref_bad = np.flatnonzero((ref_q < 0.85) & ref_changeable)
    ref_bad = ref_bad[~pinned[label[tri[ref_bad, 0]]]]
    assert np.array_equal(bad, ref_bad[np.argsort(ref_q[ref_bad], kind="stable")])


def test_round_state_orders_ties_by_row() -> None:
    """Equal q (a regular grid's triangles): worst first, ties in row order."""
    x, y = np.meshgrid(np.arange(4.0), np.arange(4.0))
    p = np.stack([x.ravel(), y.ravel() * 0.5], axis=1)
    tri = np.ascontiguousarray(delaunay(p), dtype=np.int64)
    q, *_, bad = round_state(p, tri, 0, 0, np.zeros(0, dtype=np.int64), KEY,
                             np.zeros(len(p), dtype=np.int64), 1, np.zeros(1, dtype=np.bool_), 0.99,
                             NONE)
    assert np.array_equal(bad, np.argsort(q, kind="stable"))


@pytest.mark.parametrize("seed", range(10))
def test_choose_edits_match_numpy(seed: int) -> None:
    p, tri = _mesh(seed)
    n_fixed = 12 + seed
    bad, chord, hv = _random_edits(seed, p, tri, n_fixed)
    mid, ref_collapse, ref_split = _ref_choose(p, tri, bad, chord, hv, n_fixed)
    assert np.array_equal(edge_midpoints(p, tri, bad), mid)
    collapse, split = choose_edits(p, tri, bad, chord, hv, n_fixed)
    assert np.array_equal(collapse, ref_collapse) and np.array_equal(split, ref_split)
    assert len(collapse) + len(split) > 0


@pytest.mark.parametrize("seed", range(10))
def test_apply_edits_match_numpy(seed: int) -> None:
    p, tri = _mesh(seed)
    n_fixed = 12 + seed
    bad, chord, hv = _random_edits(seed, p, tri, n_fixed)
    collapse, split = choose_edits(p, tri, bad, chord, hv, n_fixed)
    rng = np.random.default_rng(seed)
    kept = rng.permutation(len(p)).astype(np.int64)
    label = rng.integers(0, 3, len(p)).astype(np.int64)
    out = apply_edits(p, tri, kept, label, collapse, split, n_fixed)
    ref = _ref_edit(p, tri, kept, label, collapse, split, n_fixed)
    for got, want in zip(out, ref, strict=True):
        assert np.array_equal(got, want)


@pytest.mark.parametrize("seed", range(8))
def test_flip_near_matches_numpy(seed: int) -> None:
    p, tri = _mesh(seed)
    rng = np.random.default_rng(seed)
    q = p.copy()
    q[12:] += rng.normal(0.0, 0.003, (len(p) - 12, 2))  # small moves: flips, no inversion
    near = np.unique(rng.integers(12, len(p), 10)).astype(np.int64)
    for start in (near, np.zeros(0, dtype=np.int64)):
        t32 = np.ascontiguousarray(tri, dtype=np.int32)
        nbr = np.asarray(neighbours(t32, len(q)), dtype=np.int32)
        vt = np.full(len(q), -1, dtype=np.int32)
        vt[t32.ravel()] = np.repeat(np.arange(len(t32), dtype=np.int32), 3)
        con = np.zeros(t32.shape, dtype=np.uint8)
        if len(start):
            mark = np.zeros(len(q), dtype=bool)
            mark[start] = True
            rows = np.flatnonzero(mark[t32].any(axis=1)).astype(np.int32)
            want = flip_rows_to_delaunay(q, t32, nbr, con, vt, rows)
        else:
            want = flip_to_delaunay(q, t32, nbr, con, vt)
        res, got = flip_near(q, tri.copy(), start, len(start) == 0)
        assert res == want
        assert np.array_equal(got, t32)
    assert flip_near(q, np.zeros((0, 3), dtype=np.int64), near, False)[0] < 0


def _ring_rows(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Sliding rows (node, previous, next) and segments of a loop of the first k nodes."""
    b = np.arange(k, dtype=np.int64)
    return np.stack([b, np.roll(b, 1), np.roll(b, -1)], axis=1), np.stack([b, np.roll(b, -1)], axis=1)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("given", [False, True])
def test_patch_of_matches_numpy(seed: int, given: bool) -> None:
    p, tri = _mesh(seed, n=150)
    rng = np.random.default_rng(seed)
    n_fixed = 12
    slide, walls = _ring_rows(n_fixed)
    touched = rng.integers(0, len(p), 3).astype(np.int64)
    ring = 2
    t32 = np.ascontiguousarray(tri, dtype=np.int32)
    if given:
        indptr, adj, _, _ = adjacency(len(p), t32, 3)  # with free slots, as a relaxation's
    else:
        indptr, adj = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int32)
    rows, nodes, pt32, pnbr, moving, sl, wl, nf = patch_of(tri, len(p), indptr, adj, touched, ring,
                                                           slide, walls, n_fixed)
    # The NumPy form it replaced (smoothing._patch_local, _restricted, _Relaxation's set-up).
    ip, ad, _, _ = adjacency(len(p), t32, 0)
    active = rings(ip, ad, touched, ring)
    near = rings(ip, ad, touched, ring + 1)
    in_patch = near[tri].any(axis=1)
    ref_nodes = np.unique(tri[in_patch])
    inv = np.full(len(p), -1, dtype=np.intp)
    inv[ref_nodes] = np.arange(len(ref_nodes))
    ref_slide = inv[slide[active[slide[:, 0]]]]
    ref_slide = ref_slide[(ref_slide >= 0).all(axis=1)]
    ref_walls = inv[walls]
    ref_walls = ref_walls[(ref_walls >= 0).all(axis=1)]
    local = inv[tri[in_patch]]
    local = local[by_least_vertex(local, len(ref_nodes))]
    assert np.array_equal(rows, np.flatnonzero(in_patch))
    assert np.array_equal(nodes, ref_nodes)
    assert np.array_equal(pt32, local) and pt32.dtype == np.int32
    assert np.array_equal(pnbr, np.asarray(neighbours(np.ascontiguousarray(local, dtype=np.int32),
                                                      len(ref_nodes)), dtype=np.int32))
    assert np.array_equal(moving, active[ref_nodes])
    assert np.array_equal(sl, ref_slide) and np.array_equal(wl, ref_walls)
    assert nf == int(np.searchsorted(ref_nodes, n_fixed))


def test_hypot_as_numpy() -> None:
    """The kernels measure edges with numba's math.hypot where the NumPy lines used np.hypot:
    both are libm's hypot, bit for bit."""
    import math

    from numba import njit

    @njit
    def lengths(x, y):  # type: ignore[no-untyped-def]
        out = np.empty(x.shape[0])
        for i in range(x.shape[0]):
            out[i] = math.hypot(x[i], y[i])
        return out

    rng = np.random.default_rng(0)
    x, y = rng.normal(0.0, 1.0, (2, 100_000)) * 10.0 ** rng.integers(-8, 8, (2, 100_000))
    assert np.array_equal(lengths(x, y), np.hypot(x, y))


@pytest.mark.parametrize("seed", range(4))
def test_canonical_is_the_sorted_set(seed: int) -> None:
    p, tri = _mesh(seed)
    rng = np.random.default_rng(seed)
    # The same set of triangles, rows shuffled and rotated: the same canonical form.
    shuffled = np.roll(tri[rng.permutation(len(tri))], int(rng.integers(1, 3)), axis=1)
    t = np.sort(tri, axis=1)
    want = t[np.lexsort(t.T[::-1])]
    assert np.array_equal(canonical(tri), want)
    assert np.array_equal(canonical(np.ascontiguousarray(shuffled)), want)
    # Repeated rows (not a triangulation, but a set of rows all the same).
    twice = np.concatenate([tri, shuffled])
    t2 = np.sort(twice, axis=1)
    assert np.array_equal(canonical(np.ascontiguousarray(twice)), t2[np.lexsort(t2.T[::-1])])


@pytest.mark.parametrize("seed", range(4))
def test_patch_merge_matches_numpy(seed: int) -> None:
    p, tri = _mesh(seed)
    rng = np.random.default_rng(seed)
    rows = np.flatnonzero(rng.random(len(tri)) < 0.3).astype(np.int64)
    nodes = np.unique(tri[rows])
    inv = np.full(len(p), -1, dtype=np.int64)
    inv[nodes] = np.arange(len(nodes))
    patch_tri = np.ascontiguousarray(inv[tri[rows]][::-1])
    patch_p = rng.random((len(nodes), 2))
    out, out_tri = patch_merge(p, tri, rows, nodes, patch_p, patch_tri)
    in_patch = np.zeros(len(tri), dtype=bool)
    in_patch[rows] = True
    want = p.copy()
    want[nodes] = patch_p
    assert np.array_equal(out, want)
    assert np.array_equal(out_tri, np.concatenate([tri[~in_patch], nodes[patch_tri]]))


@pytest.mark.parametrize("seed", range(6))
def test_sub_mesh_and_stitch_match_numpy(seed: int) -> None:
    """The repair's sub-mesh and the stitch of its result, as smoothing._repair cut them."""
    p, tri = _mesh(seed, n=300)
    rng = np.random.default_rng(seed)
    n_fixed = 12
    slide, walls = _ring_rows(n_fixed)
    curves = np.ascontiguousarray(tri[rng.integers(0, len(tri), 5)][:, :2])
    indptr, adj, _, _ = adjacency(len(p), np.ascontiguousarray(tri, dtype=np.int32), 3)
    q = triangle_quality(p, tri)
    repair_q = float(np.quantile(q, 0.03))
    reach, band = 2, 1
    got = sub_mesh_of(p, tri, indptr, adj, repair_q, reach, band, n_fixed, slide, walls, curves)
    nodes, n_boundary, nf, inner, t32, nbr, sl, wl, cv, outer_q = got
    # The NumPy lines it replaced.
    bad = q < repair_q
    seeds = np.unique(tri[bad]).astype(np.int64)
    movable = rings(indptr, adj, seeds, reach)
    span = rings(indptr, adj, seeds, reach + band)
    ref_inner = span[tri].all(axis=1)
    ref_nodes = np.unique(tri[ref_inner])
    free = ref_nodes >= n_fixed
    stay = free & ~movable[ref_nodes]
    ref_nodes = np.concatenate([ref_nodes[~free], ref_nodes[stay], ref_nodes[free & ~stay]])
    inv = np.full(len(p), -1, dtype=np.intp)
    inv[ref_nodes] = np.arange(len(ref_nodes))
    ref_slide = inv[slide[movable[slide[:, 0]]]]
    local = inv[tri[ref_inner]]
    local = local[by_least_vertex(local, len(ref_nodes))]
    assert np.array_equal(nodes, ref_nodes) and np.array_equal(inner, ref_inner)
    assert n_boundary == np.count_nonzero(~free) and nf == n_boundary + np.count_nonzero(stay)
    assert np.array_equal(t32, local) and t32.dtype == np.int32
    assert np.array_equal(nbr, np.asarray(neighbours(np.ascontiguousarray(local, dtype=np.int32),
                                                     len(ref_nodes)), dtype=np.int32))
    assert np.array_equal(sl, ref_slide[(ref_slide >= 0).all(axis=1)])
    assert np.array_equal(wl, inv[walls][(inv[walls] >= 0).all(axis=1)])
    assert np.array_equal(cv, inv[curves][(inv[curves] >= 0).all(axis=1)])
    assert outer_q == q[~ref_inner].min()
    assert len(sub_mesh_of(p, tri, indptr, adj, 0.0, reach, band, n_fixed, slide, walls, curves)[0]) == 0

    # A result of the rounds: a few nodes dropped, two new ones, triangles reshuffled.
    m = len(nodes)
    sub_kept = np.concatenate([rng.permutation(m)[: m - 3], [-1, -1]]).astype(np.int64)
    sub_p = rng.random((len(sub_kept), 2))
    sub_tri = rng.integers(0, len(sub_kept), (len(local) - 1, 3)).astype(np.int64)
    kept = rng.permutation(len(p)).astype(np.int64)
    out, out_tri, out_kept = stitch(p, tri, inner, kept, nodes, sub_p, sub_tri, sub_kept)
    survive = np.ones(len(p), dtype=bool)
    survive[nodes] = False
    old = sub_kept >= 0
    survive[nodes[sub_kept[old]]] = True
    index = np.cumsum(survive) - 1
    n_old = int(survive.sum())
    to_global = np.empty(len(sub_p), dtype=np.intp)
    to_global[old] = index[nodes[sub_kept[old]]]
    to_global[~old] = n_old + np.arange(int((~old).sum()))
    want = np.empty((n_old + int((~old).sum()), 2))
    want[:n_old] = p[survive]
    want[to_global] = sub_p
    assert np.array_equal(out, want)
    assert np.array_equal(out_tri, np.concatenate([index[tri[~inner]], to_global[sub_tri]]))
    assert np.array_equal(out_kept, np.concatenate([kept[survive], np.full(int((~old).sum()), -1)]))


def test_choose_edits_drops_a_free_node_squeezed_against_a_fixed_edge() -> None:
    """The edge to split joins two fixed nodes (a wall segment): the free node inside its
    diametral circle goes, into the nearer end, instead of nothing happening; not when the
    free node is outside that circle."""
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0], [0.45, 0.1]])
    tri = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]], dtype=np.int64)
    bad = np.array([0], dtype=np.int64)
    chord = np.full(3, -1, dtype=np.int64)
    hv = np.full(3, 0.6)
    collapse, split = choose_edits(p, tri, bad, chord, hv, 3)
    assert collapse.tolist() == [[0, 3]] and len(split) == 0
    p[3] = [0.45, 0.6]  # obtuse nowhere: left alone, as before
    collapse, split = choose_edits(p, tri, bad, chord, hv, 3)
    assert len(collapse) == 0 and len(split) == 0


def test_round_state_leaves_excused_triangles_out_of_the_scores() -> None:
    """A triangle of fixed nodes whose key is excused does not count in its part's least q,
    in any vertex order; every other triangle does."""
    from injmesh.kernels.repair import frozen_key, frozen_key_rows

    x, y = np.meshgrid(np.arange(4.0), np.arange(4.0))
    p = np.stack([x.ravel(), y.ravel()], axis=1)
    p[5] += [0.4, 0.35]  # one very flat triangle or two
    tri = np.ascontiguousarray(delaunay(p), dtype=np.int64)
    n = len(p)
    label = np.zeros(n, dtype=np.int64)
    q = triangle_quality(p, tri)
    worst = int(np.argmin(q))
    excused = np.unique(frozen_key_rows(tri[[worst]], n))
    a, b, c = tri[worst]
    assert frozen_key(c, a, b, n) == frozen_key(b, c, a, n) == excused[0]
    args = (p, tri, n, n, np.zeros(0, dtype=np.int64), KEY, label, 1, np.zeros(1, dtype=np.bool_), 0.85)
    score = round_state(*args, NONE)[3]
    score_excused = round_state(*args, excused)[3]
    assert score[0] == q[worst]
    assert score_excused[0] == np.delete(q, worst).min() > q[worst]
