"""The Delaunay kernel: validity, the empty-circle property (exact), Qhull, live operations."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull, Delaunay

from injmesh.kernels.delaunay import (
    DEAD,
    GHOST,
    BlockedSegmentError,
    DelaunayError,
    InvertedTriangleError,
    LiveTriangulation,
    delaunay,
    flip_to_delaunay,
)
from injmesh.kernels.predicates import incircle_many, orient2d_many

SRC = str(Path(__file__).resolve().parents[1] / "src")


# ---------------------------------------------------------------------------------------------
# Invariants


def canonical(tri: np.ndarray) -> set[tuple[int, ...]]:
    return {tuple(r) for r in np.sort(np.asarray(tri), axis=1).tolist()}


def opposite(tri: np.ndarray, nbr: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every (t, k) with a neighbour u: t, k and the vertex of u opposite the shared edge."""
    t, k = np.nonzero(nbr >= 0)
    u = nbr[t, k]
    back = nbr[u] == t[:, None]
    assert np.all(back.sum(axis=1) == 1), "neighbours are not symmetric"
    l = np.argmax(back, axis=1)
    return t, k, tri[u, l]


def assert_valid(points: np.ndarray, tri: np.ndarray, nbr: np.ndarray, *, used=None) -> None:  # type: ignore[no-untyped-def]
    """A triangulation of the convex hull of the used points, with consistent neighbours."""
    p = np.asarray(points)
    assert tri.dtype == np.int32 and nbr.dtype == np.int32 and tri.shape == nbr.shape
    assert len(tri) > 0
    # Every triangle counter-clockwise by the exact predicate.
    o = orient2d_many(p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]])
    assert o.min() > 0, f"{np.sum(o <= 0)} triangles are not strictly counter-clockwise"
    # Neighbour k is across the edge opposite corner k, sharing it in reverse direction.
    t, k, _ = opposite(tri, nbr)
    u = nbr[t, k]
    a, b = tri[t, (k + 1) % 3], tri[t, (k + 2) % 3]
    assert np.all(np.any((tri[u] == b[:, None]) & (np.roll(tri[u], -1, axis=1) == a[:, None]), axis=1))
    # Each directed edge once; undirected edges in one or two triangles.
    half = np.concatenate([tri[:, [1, 2]], tri[:, [2, 0]], tri[:, [0, 1]]])
    assert len(np.unique(half, axis=0)) == len(half), "a directed edge occurs twice (fold)"
    und, count = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    assert count.max() <= 2
    # -1 exactly on the hull edges (those in one triangle).
    assert np.sum(nbr < 0) == np.sum(count == 1)
    # Euler: V - E + F = 1 for a triangulated disc.
    verts = np.unique(tri)
    assert len(verts) - len(und) + len(tri) == 1
    if used is not None:
        assert np.array_equal(verts, np.sort(used)), "some points are missing from the triangulation"
    # The union of the triangles is the convex hull: same area (relative to a vertex, exactly
    # enough even 1e9 from the origin), and the hull's vertices are on hull edges.
    q = p[verts] - p[verts[0]]
    hull = ConvexHull(q)
    e1 = p[tri[:, 1]] - p[tri[:, 0]]
    e2 = p[tri[:, 2]] - p[tri[:, 0]]
    area = 0.5 * np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    assert area == pytest.approx(hull.volume, rel=1e-9)


def assert_delaunay(points: np.ndarray, tri: np.ndarray, nbr: np.ndarray, skip=None) -> None:  # type: ignore[no-untyped-def]
    """Every interior edge passes the exact in-circle test with <= 0 (empty circles)."""
    p = np.asarray(points)
    t, k, d = opposite(tri, nbr)
    if skip is not None:
        a, b = tri[t, (k + 1) % 3], tri[t, (k + 2) % 3]
        pairs = zip(np.minimum(a, b).tolist(), np.maximum(a, b).tolist(), strict=True)
        keep = np.array([pair not in skip for pair in pairs], dtype=bool)
        t, d = t[keep], d[keep]
    tt = tri[t]
    ic = incircle_many(p[tt[:, 0]], p[tt[:, 1]], p[tt[:, 2]], p[d])
    assert ic.max(initial=0.0) <= 0, f"{np.sum(ic > 0)} edges are not locally Delaunay"


def assert_live(live: LiveTriangulation, *, delaunay_skip=None) -> None:  # type: ignore[no-untyped-def]
    """Validity and the Delaunay property of the compact form, and the internal structure too."""
    p = live.points
    tri, nbr = live.triangles, live.neighbors
    used = np.flatnonzero(live.arrays()[4] >= 0)
    assert_valid(p, tri, nbr, used=used)
    assert_delaunay(p, tri, nbr, skip=delaunay_skip)
    # Internal: ghosts close the hull, vt points at a triangle holding its vertex.
    _, itri, inbr, _, vt = live.arrays()
    live_rows = itri[:, 0] != DEAD
    ghosts = np.any(itri == GHOST, axis=1) & live_rows
    assert np.sum(ghosts) == np.sum(nbr < 0)
    assert np.all(inbr[live_rows] >= 0)
    for v in used.tolist():
        assert v in itri[vt[v]]


def edges_of(tri: np.ndarray) -> set[tuple[int, int]]:
    """Undirected edges (i < j) of the triangles."""
    e = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    return set(map(tuple, e.tolist()))


def hull_edges(tri: np.ndarray, nbr: np.ndarray) -> set[tuple[int, int]]:
    t, k = np.nonzero(nbr < 0)
    return set(zip(tri[t, (k + 1) % 3].tolist(), tri[t, (k + 2) % 3].tolist(), strict=True))


def lattice(k: int, offset: float = 0.0, step: float = 1.0) -> np.ndarray:
    g = np.arange(k, dtype=float) * step + offset
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel()])


# ---------------------------------------------------------------------------------------------
# Construction


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_points_match_qhull(seed: int) -> None:
    p = np.random.default_rng(seed).random((300, 2))
    live = LiveTriangulation(p)
    assert_live(live)
    assert canonical(live.triangles) == canonical(Delaunay(p).simplices)


def test_drop_in_function() -> None:
    p = np.random.default_rng(5).normal(size=(200, 2))
    t = delaunay(p)
    assert t.dtype == np.intp and t.shape[1] == 3
    assert canonical(t) == canonical(Delaunay(p).simplices)


@pytest.mark.parametrize("offset", [0.0, 1e9, -1e9])
def test_cocircular_lattice(offset: float) -> None:
    """Every square of a lattice has four cocircular corners: any diagonal is Delaunay."""
    p = lattice(12, offset)
    live = LiveTriangulation(p)
    assert_live(live)
    assert len(live.triangles) == 2 * 11 * 11
    # Same number of triangles and area as Qhull (whose diagonals may differ).
    q = Delaunay(p - offset).simplices
    assert len(q) == len(live.triangles)


def test_random_points_far_from_origin() -> None:
    rng = np.random.default_rng(7)
    p = 1e9 + rng.random((300, 2))
    live = LiveTriangulation(p)
    assert_live(live)
    # Qhull on the same points shifted to the origin (exactly: the spacing here is 2^-23).
    q = Delaunay(p - 1e9).simplices
    assert canonical(live.triangles) == canonical(q)


def test_tiny_coordinates() -> None:
    p = np.random.default_rng(8).random((200, 2)) * 1e-20
    live = LiveTriangulation(p)
    assert_live(live)
    assert canonical(live.triangles) == canonical(Delaunay(p * 1e20).simplices)


def test_collinear_points_with_a_few_off_the_line() -> None:
    x = np.arange(40) / 39.0
    line = np.column_stack([x, 0.5 * x + 0.125])  # y exact: every point exactly on the line
    off = np.array([[0.3, 0.9], [0.7, -0.2], [0.5, 0.35]])
    p = np.concatenate([line, off])
    live = LiveTriangulation(p)
    assert_live(live)
    assert len(live.triangles) == len(Delaunay(p).simplices)
    # All on one line: no triangle exists.
    with pytest.raises(DelaunayError, match="collinear"):
        LiveTriangulation(np.column_stack([np.arange(40) / 64, 0.5 * np.arange(40) / 64 + 0.125]))
    with pytest.raises(DelaunayError, match="collinear"):
        delaunay(np.ones((5, 2)))


def test_collinear_boundary_rows() -> None:
    """A square's boundary sampled densely: many hull vertices on straight lines."""
    s = np.linspace(0, 1, 30)[:-1]
    one, zero = np.ones_like(s), np.zeros_like(s)
    ring = np.concatenate([np.c_[s, zero], np.c_[one, s], np.c_[1 - s, one], np.c_[zero, 1 - s]])
    p = np.concatenate([ring, np.random.default_rng(2).random((50, 2)) * 0.8 + 0.1])
    live = LiveTriangulation(p)
    assert_live(live)
    assert len(hull_edges(live.triangles, live.neighbors)) == len(ring)


def test_duplicates_are_reported_and_left_out() -> None:
    rng = np.random.default_rng(4)
    base = rng.random((100, 2))
    dup_of = rng.integers(0, 100, 30)
    p = np.concatenate([base, base[dup_of]])
    live = LiveTriangulation(p)
    d = live.duplicates
    assert np.sum(d >= 0) == 30
    # Each reported duplicate repeats the vertex named, and that vertex is in the mesh.
    for i in np.flatnonzero(d >= 0).tolist():
        assert np.array_equal(p[i], p[d[i]]) and d[i] not in np.flatnonzero(d >= 0)
    tri = live.triangles
    assert not np.isin(np.flatnonzero(d >= 0), tri).any()
    assert_live(live)
    # The same triangles as Qhull on the distinct points, up to which copy is kept.
    kept = np.flatnonzero(d < 0)
    remap = np.full(len(p), -1)
    remap[kept] = np.arange(len(kept))
    assert canonical(remap[tri]) == canonical(Delaunay(p[kept]).simplices)


def test_bad_input_is_named() -> None:
    with pytest.raises(DelaunayError, match="at least 3"):
        delaunay(np.zeros((2, 2)))
    with pytest.raises(DelaunayError, match="not finite"):
        delaunay(np.array([[0.0, 0.0], [1.0, np.nan], [0.0, 1.0]]))
    with pytest.raises(DelaunayError, match=r"\(n, 2\)"):
        delaunay(np.zeros((4, 3)))


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6)), min_size=3, max_size=40),
    st.sampled_from([0.0, 1e9]),
)
def test_small_integer_sets_with_many_ties(coords, offset) -> None:  # type: ignore[no-untyped-def]
    """Collinear rows, cocircular quads and duplicates all at once."""
    p = np.array(coords, dtype=float) + offset
    distinct = np.unique(p, axis=0)
    if len(distinct) < 3 or np.linalg.matrix_rank(distinct[1:] - distinct[0]) < 2:
        with pytest.raises(DelaunayError):
            LiveTriangulation(p)
        return
    live = LiveTriangulation(p)
    assert_live(live)
    assert np.sum(live.duplicates < 0) == len(distinct)


def test_repeat_runs_are_bit_identical() -> None:
    p = np.concatenate([lattice(10), np.random.default_rng(9).random((200, 2)) * 9])
    a, b = LiveTriangulation(p), LiveTriangulation(p)
    for x, y in zip(a.arrays()[1:], b.arrays()[1:], strict=True):
        assert np.array_equal(x, y)


def test_same_result_with_one_or_two_threads() -> None:
    code = (
        "import hashlib, numpy as np\n"
        "from injmesh.kernels.delaunay import delaunay\n"
        "g = np.arange(12.0); x, y = np.meshgrid(g, g)\n"
        "p = np.concatenate([np.c_[x.ravel(), y.ravel()], np.random.default_rng(1).random((300, 2)) * 11])\n"
        "print(hashlib.sha256(delaunay(p).tobytes()).hexdigest())\n"
    )
    out = []
    for threads in ("1", "2"):
        env = {**os.environ, "NUMBA_NUM_THREADS": threads, "PYTHONPATH": SRC}
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        out.append(run.stdout.strip())
    assert out[0] == out[1] and len(out[0]) == 64
    g = np.arange(12.0)
    x, y = np.meshgrid(g, g)
    p = np.concatenate([np.c_[x.ravel(), y.ravel()], np.random.default_rng(1).random((300, 2)) * 11])
    assert hashlib.sha256(delaunay(p).tobytes()).hexdigest() == out[0]


# ---------------------------------------------------------------------------------------------
# Live operations


def test_locate() -> None:
    rng = np.random.default_rng(11)
    p = rng.random((200, 2))
    live = LiveTriangulation(p)
    qhull = Delaunay(p)
    for q in rng.random((50, 2)) * 1.2 - 0.1:
        t = live.locate(q)
        inside = qhull.find_simplex(q) >= 0
        if t is None:
            assert not inside
            continue
        a, b, c = p[t]
        o = orient2d_many(np.array([a, b, c]), np.array([b, c, a]), np.array([q, q, q]))
        assert o.min() >= 0
    # A vertex and a point on an edge are found too.
    assert 17 in live.locate(p[17])
    tri = live.triangles[0]
    assert set(live.locate(p[tri[:2]].mean(axis=0)).tolist()) >= {int(tri[0]), int(tri[1])}


def test_insert_and_remove_keep_a_delaunay_triangulation() -> None:
    rng = np.random.default_rng(12)
    p = rng.random((60, 2))
    live = LiveTriangulation(p)
    # Inside, outside the hull (new hull vertices), on an existing edge, a duplicate.
    news = [live.insert(q) for q in rng.random((25, 2)) * 1.4 - 0.2]
    assert news == list(range(60, 85))
    assert_live(live)
    tri = live.triangles[3]
    mid = live.insert(0.5 * (p[tri[0]] + p[tri[1]]))
    assert_live(live)
    assert live.insert(p[5]) == 5
    assert live.n_points == 86
    assert canonical(live.triangles) == canonical(Delaunay(live.points).simplices)
    # Remove interior and hull vertices, one at a time.
    hull = sorted({v for e in hull_edges(live.triangles, live.neighbors) for v in e})
    inner = sorted(set(range(live.n_points)) - set(hull) - {mid})
    for v in [mid, inner[0], inner[5], hull[0], hull[3], inner[-1], hull[-1], inner[9]]:
        live.remove(v)
        assert_live(live)
    used = np.flatnonzero(live.arrays()[4] >= 0)
    remap = np.full(live.n_points, -1)
    remap[used] = np.arange(len(used))
    assert canonical(remap[live.triangles]) == canonical(Delaunay(live.points[used]).simplices)
    with pytest.raises(DelaunayError, match="not in the triangulation"):
        live.remove(inner[0])


def test_remove_on_a_cocircular_lattice() -> None:
    live = LiveTriangulation(lattice(8, 1e9))
    for v in [9, 27, 0, 63, 4, 36, 35]:
        live.remove(v)
        assert_live(live)
    assert live.triangles.size > 0


def test_remove_down_to_a_triangle() -> None:
    live = LiveTriangulation(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.4, 0.5]]))
    live.remove(4)
    live.remove(3)
    assert_live(live)
    assert len(live.triangles) == 1
    with pytest.raises(DelaunayError, match="no triangle"):
        live.remove(0)


def test_flip_edge() -> None:
    p = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [2.0, 0.5]])
    live = LiveTriangulation(p)
    tri = live.triangles
    # The square's diagonal flips back and forth (cocircular: both are Delaunay).
    diag = (0, 2) if (0, 2) in edges_of(tri) else (1, 3)
    other = (1, 3) if diag == (0, 2) else (0, 2)
    assert live.flip(*diag)
    assert other in edges_of(live.triangles)
    assert_live(live)
    # A hull edge, a non-edge, a non-convex quadrilateral: no flip.
    assert not live.flip(0, 1)
    assert not live.flip(0, 4)
    assert_valid(live.points, live.triangles, live.neighbors)


def test_flip_to_delaunay_after_a_small_move() -> None:
    rng = np.random.default_rng(13)
    p = lattice(15)
    interior = np.all((p > 0) & (p < 14), axis=1)
    p[interior] += rng.uniform(-0.02, 0.02, size=(interior.sum(), 2))
    live = LiveTriangulation(p)
    hull = hull_edges(live.triangles, live.neighbors)
    # Moves of at most 0.1 * sqrt(2): no triangle of height >= 0.68 can invert.
    q = p.copy()
    q[interior] += rng.uniform(-0.1, 0.1, size=(interior.sum(), 2))
    live.move(q)
    flips = live.flip_to_delaunay()
    assert flips > 0
    assert_live(live)
    assert hull_edges(live.triangles, live.neighbors) == hull
    assert canonical(live.triangles) == canonical(Delaunay(q).simplices)
    # Nothing left to flip.
    assert live.flip_to_delaunay() == 0


def test_flip_to_delaunay_moving_the_hull_too() -> None:
    """Hull vertices move too: some become reflex and the notch is filled by a flip."""
    rng = np.random.default_rng(14)
    p = lattice(15)
    interior = np.all((p > 0) & (p < 14), axis=1)
    p[interior] += rng.uniform(-0.1, 0.1, size=(interior.sum(), 2))
    live = LiveTriangulation(p)
    q = p + rng.uniform(-0.1, 0.1, size=p.shape)
    live.move(q)
    assert live.flip_to_delaunay() > 0
    assert_live(live)
    assert canonical(live.triangles) == canonical(Delaunay(q).simplices)


def test_flip_to_delaunay_on_compact_arrays() -> None:
    """The kernel also runs on the public arrays (no ghosts, -1 beyond the hull)."""
    rng = np.random.default_rng(15)
    p = lattice(10)
    inner = np.all((p > 0) & (p < 9), axis=1)
    p[inner] += rng.uniform(-0.01, 0.01, size=(inner.sum(), 2))
    tri, nbr = LiveTriangulation(p).triangles, LiveTriangulation(p).neighbors
    q = p.copy()
    q[inner] += rng.uniform(-0.1, 0.1, size=(inner.sum(), 2))
    hull = hull_edges(tri, nbr)
    vt = np.full(len(p), -1, np.int32)
    vt[tri.ravel()] = np.repeat(np.arange(len(tri), dtype=np.int32), 3)
    con = np.zeros(tri.shape, np.uint8)
    res = flip_to_delaunay(q, tri, nbr, con, vt)
    assert res > 0
    assert_valid(q, tri, nbr)
    assert hull_edges(tri, nbr) == hull
    assert_delaunay(q, tri, nbr)


def test_inverted_triangle_is_reported() -> None:
    p = lattice(5)
    live = LiveTriangulation(p)
    q = p.copy()
    q[12] = [3.6, 2.0]  # the centre node jumps past its right-hand neighbour
    live.move(q)
    with pytest.raises(InvertedTriangleError) as err:
        live.flip_to_delaunay()
    assert 12 in err.value.triangle
    assert canonical(live.triangles) == canonical(LiveTriangulation(p).triangles)  # untouched


def test_recover_edge() -> None:
    rng = np.random.default_rng(16)
    p = rng.random((400, 2))
    live = LiveTriangulation(p)
    # Long segments crossing many edges, and one that already exists.
    i, j = int(np.argmin(p[:, 0] + p[:, 1])), int(np.argmax(p[:, 0] + p[:, 1]))
    k, l = int(np.argmin(p[:, 0] - p[:, 1])), int(np.argmax(p[:, 0] - p[:, 1]))
    live.recover_edge(i, j)
    assert (min(i, j), max(i, j)) in edges_of(live.triangles)
    assert_live(live, delaunay_skip={(min(i, j), max(i, j))})
    e0 = live.triangles[0, :2].tolist()
    live.recover_edge(*e0)
    cons = {tuple(e) for e in live.constrained_edges.tolist()}
    assert cons == {(min(i, j), max(i, j)), tuple(sorted(e0))}
    assert_live(live, delaunay_skip=cons)
    # A segment crossing a constrained one is refused; flips never remove constrained edges.
    with pytest.raises(DelaunayError, match="constrained edge crosses"):
        live.recover_edge(k, l)
    live.move(p + rng.uniform(-1e-9, 1e-9, size=p.shape))
    live.flip_to_delaunay()
    assert {tuple(e) for e in live.constrained_edges.tolist()} == cons
    assert not live.flip(i, j)


def test_recover_edge_blocked_by_a_vertex() -> None:
    p = lattice(6, 1e9)
    live = LiveTriangulation(p)
    with pytest.raises(BlockedSegmentError) as err:
        live.recover_edge(0, 35)  # the diagonal runs through 7, 14, 21, 28
    assert err.value.vertex in (7, 14, 21, 28)
    live.recover_edge(0, 7)
    live.recover_edge(1, 32)  # a knight's-move direction: crosses edges, hits no vertex
    assert_live(live, delaunay_skip={tuple(e) for e in live.constrained_edges.tolist()})


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 5), st.integers(0, 5)), min_size=6, max_size=30, unique=True),
    st.lists(
        st.tuples(st.booleans(), st.integers(0, 40), st.integers(-1, 6), st.integers(-1, 6)), max_size=15
    ),
)
def test_random_insertions_and_removals_on_a_grid(coords, ops) -> None:  # type: ignore[no-untyped-def]
    """Many ties (collinear hull runs, cocircular squares): every state valid and Delaunay."""
    p = np.array(coords, dtype=float) * 0.5 + 1e9
    if np.linalg.matrix_rank(p[1:] - p[0]) < 2:
        return
    live = LiveTriangulation(p)
    for remove, v, x, y in ops:
        if remove:
            alive = np.flatnonzero(live.arrays()[4] >= 0)
            try:
                live.remove(int(alive[v % len(alive)]))
            except DelaunayError as exc:
                assert "no triangle" in str(exc)
        else:
            live.insert([x * 0.5 + 1e9, y * 0.5 + 1e9])
        assert_live(live)


def test_renumber_rows_keeps_the_triangulation() -> None:
    rng = np.random.default_rng(17)
    p = rng.random((300, 2))
    live = LiveTriangulation(p)
    for v in (5, 9, 100):
        live.remove(v)  # free rows inside the arrays
    before = canonical(live.triangles)
    live.renumber_rows()
    assert canonical(live.triangles) == before
    assert_live(live)
    # Still live: insert, remove, move and flip.
    v = live.insert([0.5, 0.5])
    live.remove(7)
    live.move(live.points + rng.uniform(-1e-4, 1e-4, size=(live.n_points, 2)))
    live.flip_to_delaunay()
    assert_live(live)
    assert v in live.triangles


@pytest.mark.parametrize("seed", range(4))
def test_flips_from_the_moved_vertices_rows_give_the_delaunay_mesh(seed: int) -> None:
    """Only some vertices move: flipping from their triangles alone gives the same mesh as a
    new Delaunay triangulation (generic points: it is unique)."""
    from injmesh.kernels.delaunay import flip_rows_to_delaunay
    from injmesh.kernels.mesh import neighbours
    from injmesh.triangulation import delaunay as tri_delaunay

    rng = np.random.default_rng(seed)
    # A jittered lattice (well-shaped triangles: moves of a tenth of the spacing need flips
    # but invert nothing).
    g = np.stack(np.meshgrid(np.arange(20.0), np.arange(20.0)), axis=-1).reshape(-1, 2)
    p = (g + rng.uniform(-0.1, 0.1, g.shape)) / 20
    t32 = tri_delaunay(p).astype(np.int32)
    moved = np.zeros(len(p), dtype=bool)
    # Away from the hull, where the lattice's nearly collinear rows make flat triangles.
    inner = np.flatnonzero(((g >= 2) & (g <= 17)).all(axis=1))
    moved[rng.choice(inner, 40, replace=False)] = True
    q = p.copy()
    q[moved] += rng.uniform(-0.005, 0.005, size=(moved.sum(), 2))
    nbr = neighbours(t32, len(p)).astype(np.int32)
    con = np.zeros(t32.shape, dtype=np.uint8)
    vt = np.full(len(p), -1, dtype=np.int32)
    vt[t32.ravel()] = np.repeat(np.arange(len(t32), dtype=np.int32), 3)
    rows = np.flatnonzero(moved[t32].any(axis=1)).astype(np.int32)
    res = flip_rows_to_delaunay(q, t32, nbr, con, vt, rows)
    assert res > 0
    expected = tri_delaunay(q)
    as_set = lambda t: {tuple(np.roll(r, -int(np.argmin(r)))) for r in t.tolist()}  # noqa: E731
    assert as_set(t32) == as_set(expected)
