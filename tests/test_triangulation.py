"""Delaunay, removal of outside triangles, boundary edges, and Lawson flips."""

from __future__ import annotations

import numpy as np
import pytest

from injmesh.quality import signed_areas, unique_edges
from injmesh.triangulation import TriangulationError, boundary_edges, delaunay, flip_to_delaunay


def _canonical(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t)
    r = np.argmin(t, axis=1)
    rolled = np.stack([t[np.arange(len(t)), (r + k) % 3] for k in range(3)], axis=1)
    return rolled[np.lexsort(rolled.T[::-1])]


def test_flips_after_small_moves_give_the_delaunay_triangulation() -> None:
    rng = np.random.default_rng(0)
    xs, ys = np.meshgrid(np.arange(20.0), np.arange(20.0))
    p = np.stack([xs.ravel(), ys.ravel()], axis=1) + 0.2 * rng.standard_normal((400, 2))
    tri = delaunay(p)
    # Interior nodes move by about 5 % of the spacing, as between two triangulations of the
    # smoothing: the old connectivity is no longer Delaunay, and flips must reach exactly what
    # Qhull computes from scratch.
    # Qhull's convex hull has slivers (not found in a domain mesh): leave their nodes still.
    hull = np.unique(boundary_edges(tri))
    near_hull = np.unique(tri[np.isin(tri, hull).any(axis=1)])
    moved = p.copy()
    inner = np.setdiff1d(np.arange(len(p)), near_hull)
    moved[inner] += 0.05 * rng.standard_normal((len(inner), 2))
    assert not np.array_equal(_canonical(tri), _canonical(delaunay(moved)))
    flipped = flip_to_delaunay(moved, tri)
    assert flipped is not None
    assert np.all(signed_areas(moved, flipped) > 0)
    assert np.array_equal(_canonical(flipped), _canonical(delaunay(moved)))


def test_flips_keep_the_boundary() -> None:
    """Edges with one triangle are never flipped: a non-convex mesh keeps its outline."""
    # An L made of two squares' worth of grid, with a poor diagonal choice everywhere.
    xs, ys = np.meshgrid(np.arange(5.0), np.arange(5.0))
    p = np.stack([xs.ravel(), ys.ravel()], axis=1)
    p += 0.01 * np.random.default_rng(1).standard_normal(p.shape)
    tri = delaunay(p)
    keep = ~np.all((p[tri][:, :, 0] >= 2) & (p[tri][:, :, 1] >= 2), axis=1)
    tri = tri[keep]
    before = {tuple(sorted(e)) for e in boundary_edges(tri)}
    flipped = flip_to_delaunay(p, tri)
    assert flipped is not None
    assert {tuple(sorted(e)) for e in boundary_edges(flipped)} == before
    assert len(unique_edges(flipped)) == len(unique_edges(tri))


def test_flips_decline_an_inverted_triangle() -> None:
    p = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=float)
    tri = delaunay(p)
    p[3] = [-1.0, -1.0]  # folds a triangle over
    assert flip_to_delaunay(p, tri) is None


def test_delaunay_rejects_too_few_points() -> None:
    with pytest.raises(TriangulationError, match="at least 3"):
        delaunay(np.zeros((2, 2)))


# ---------------------------------------------------------------------------------------------
# The public functions on the compiled kernels: Qhull and NumPy formulations as test oracles.

import hashlib  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from scipy.spatial import ConvexHull, Delaunay  # noqa: E402

from injmesh.kernels.predicates import incircle_many, orient2d_many  # noqa: E402
from injmesh.quality import edge_lengths, triangle_quality  # noqa: E402
from injmesh.triangulation import (  # noqa: E402
    classify_by_walls,
    inside_triangles,
    neighbours,
    recover_segments,
)

SRC = str(Path(__file__).resolve().parents[1] / "src")


def _sides(tri: np.ndarray) -> np.ndarray:
    return np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])


def _ref_neighbours(tri: np.ndarray) -> np.ndarray:
    """Across the side opposite each corner, by a dictionary of directed sides."""
    rows = tri.tolist()
    owner = {(r[(k + 1) % 3], r[(k + 2) % 3]): t for t, r in enumerate(rows) for k in range(3)}
    return np.array([[owner.get((int(tri[t, (k + 2) % 3]), int(tri[t, (k + 1) % 3])), -1) for k in range(3)]
                     for t in range(len(tri))]).reshape(-1, 3)


def assert_valid_triangulation(p: np.ndarray, tri: np.ndarray, *, hull: bool = True) -> None:
    """Strictly counter-clockwise (exact), no fold, each side in one or two triangles, a disc
    (Euler), and, with ``hull``, covering the convex hull of its vertices."""
    assert len(tri) > 0
    assert orient2d_many(p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]).min() > 0
    half = _sides(tri)
    assert len(np.unique(half, axis=0)) == len(half), "a directed side occurs twice"
    und, count = np.unique(np.sort(half, axis=1), axis=0, return_counts=True)
    assert count.max() <= 2
    verts = np.unique(tri)
    assert len(verts) - len(und) + len(tri) == 1
    if hull:
        q = p[verts] - p[verts[0]]
        e1, e2 = q[np.searchsorted(verts, tri[:, 1])] - q[np.searchsorted(verts, tri[:, 0])], \
            q[np.searchsorted(verts, tri[:, 2])] - q[np.searchsorted(verts, tri[:, 0])]
        area = 0.5 * np.sum(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
        assert area == pytest.approx(ConvexHull(q).volume, rel=1e-9)


def assert_empty_circles(p: np.ndarray, tri: np.ndarray, skip: set[tuple[int, int]] = frozenset()) -> None:  # type: ignore[assignment]
    """No interior side has the opposite node strictly inside the circumcircle (exact test)."""
    nbr = neighbours(tri)
    t, k = np.nonzero(nbr >= 0)
    u = nbr[t, k]
    a, b = tri[t, (k + 1) % 3], tri[t, (k + 2) % 3]
    keep = np.array([(min(x, y), max(x, y)) not in skip for x, y in zip(a.tolist(), b.tolist(), strict=True)],
                    dtype=bool)
    t, u = t[keep], u[keep]
    pairs = zip(t.tolist(), u.tolist(), strict=True)
    d = np.array([int(np.setdiff1d(tri[uu], tri[tt])[0]) for tt, uu in pairs], dtype=np.intp)
    if len(d):
        tt = tri[t]
        assert incircle_many(p[tt[:, 0]], p[tt[:, 1]], p[tt[:, 2]], p[d]).max() <= 0


def _outline(tri: np.ndarray) -> set[tuple[int, int]]:
    return {(a, b) for a, b in boundary_edges(tri).tolist()}


def _lattice(k: int, offset: float = 0.0) -> np.ndarray:
    g = np.arange(k, dtype=float) + offset
    x, y = np.meshgrid(g, g)
    return np.column_stack([x.ravel(), y.ravel()])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_delaunay_matches_qhull_on_random_points(seed: int) -> None:
    p = np.random.default_rng(seed).random((400, 2))
    tri = delaunay(p)
    assert tri.dtype == np.intp
    assert np.all(signed_areas(p, tri) > 0)
    qhull = Delaunay(p).simplices
    assert _canonical(np.sort(tri, axis=1)).tolist() == _canonical(np.sort(qhull, axis=1)).tolist()


def _family(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Points of a degenerate family and the indices expected in the triangulation."""
    rng = np.random.default_rng(3)
    if name == "random":
        p = rng.random((500, 2))
    elif name == "lattice":  # every square's corners are cocircular
        p = _lattice(15)
    elif name == "lattice 1e9":
        p = _lattice(15, 1e9)
    elif name == "random 1e9":
        p = 1e9 + rng.random((300, 2))
    elif name == "collinear":  # long exact rows with a few points off them
        x = np.arange(60) / 64.0
        p = np.concatenate([np.c_[x, 0.5 * x], np.c_[x, 0.5 * x + 0.25], [[0.3, 0.9], [0.7, -0.3]]])
    elif name == "duplicates":
        base = rng.random((200, 2))
        p = np.concatenate([base, base[rng.integers(0, 200, 40)]])
        return p, np.arange(200)
    else:
        raise AssertionError(name)
    return p, np.arange(len(p))


FAMILIES = ["random", "lattice", "lattice 1e9", "random 1e9", "collinear", "duplicates"]


@pytest.mark.parametrize("name", FAMILIES)
def test_delaunay_has_empty_circles_on_degenerate_families(name: str) -> None:
    p, used = _family(name)
    tri = delaunay(p)
    assert_valid_triangulation(p, tri)
    assert_empty_circles(p, tri)
    # Every distinct point is a vertex; an exact duplicate of an earlier point is left out.
    assert np.array_equal(np.unique(tri), used)
    # As many triangles as Qhull makes of the distinct points (ties may pick other diagonals).
    q = p[used] - p[used].min(axis=0)
    assert len(tri) == len(Delaunay(q).simplices)


def test_delaunay_names_bad_input() -> None:
    with pytest.raises(TriangulationError, match="collinear"):
        delaunay(np.c_[np.arange(10.0), 2 * np.arange(10.0)])
    with pytest.raises(TriangulationError, match="not finite"):
        delaunay(np.array([[0.0, 0.0], [1.0, np.inf], [0.0, 1.0]]))
    with pytest.raises(TriangulationError, match=r"\(n, 2\)"):
        delaunay(np.zeros((5, 3)))


def test_delaunay_is_scale_and_shift_invariant() -> None:
    """The insertion order depends on the bounding box only: same triangles when scaled."""
    p = np.concatenate([_lattice(9), np.random.default_rng(4).random((60, 2)) * 8])
    t = delaunay(p)
    assert np.array_equal(t, delaunay(p * 1024.0 + 2048.0))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), move=st.floats(0.0, 0.3))
def test_flips_keep_a_valid_delaunay_triangulation(seed: int, move: float) -> None:
    """After random moves of interior lattice nodes, flips give a valid Delaunay mesh of the same
    outline, or decline (None) when a move inverted a triangle."""
    rng = np.random.default_rng(seed)
    p = _lattice(10)
    inner = np.all((p > 0) & (p < 9), axis=1)
    p[inner] += rng.uniform(-0.2, 0.2, (inner.sum(), 2))
    tri = delaunay(p)
    moved = p.copy()
    moved[inner] += rng.uniform(-move, move, (inner.sum(), 2))
    out = flip_to_delaunay(moved, tri)
    if np.any(orient2d_many(moved[tri[:, 0]], moved[tri[:, 1]], moved[tri[:, 2]]) <= 0):
        assert out is None
        return
    assert out is not None
    assert_valid_triangulation(moved, out)
    assert_empty_circles(moved, out)
    assert _outline(out) == _outline(tri)


def test_flips_on_a_mesh_with_a_hole_keep_its_outline() -> None:
    p = _lattice(12)
    inner = np.all((p > 0) & (p < 11), axis=1)  # straight outer rows: no sliver on the hull
    p[inner] += np.random.default_rng(5).uniform(-0.1, 0.1, (inner.sum(), 2))
    tri = delaunay(p)
    c = p[tri].mean(axis=1)
    tri = tri[np.hypot(*(c - 5.5).T) > 2.5]  # a hole in the middle
    moved = p.copy()
    moved[inner] += np.random.default_rng(6).uniform(-0.05, 0.05, (inner.sum(), 2))
    out = flip_to_delaunay(moved, tri)
    assert out is not None
    assert np.all(signed_areas(moved, out) > 0)
    assert _outline(out) == _outline(tri)
    assert_empty_circles(moved, out)


def _circle_in_lattice(k: int = 24, spacing: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """A jittered lattice with a circle of long segments through it: Delaunay drops many."""
    rng = np.random.default_rng(7)
    p = _lattice(k) + rng.uniform(-0.2, 0.2, (k * k, 2))
    c, r = (k - 1) / 2, 0.35 * k
    n_seg = int(2 * np.pi * r / spacing)
    ang = 2 * np.pi * np.arange(n_seg) / n_seg
    ring = c + r * np.c_[np.cos(ang), np.sin(ang)]
    # Lattice nodes close to a segment would make it nearly collinear with them: drop them.
    d = np.abs(np.hypot(*(p - c).T) - r)
    p = np.concatenate([ring, p[d > 0.3]])
    walls = np.c_[np.arange(n_seg), np.roll(np.arange(n_seg), -1)]
    return p, walls


def test_recovery_keeps_every_boundary_segment_and_a_valid_triangulation() -> None:
    p, walls = _circle_in_lattice()
    tri = delaunay(p)
    have = {tuple(e) for e in unique_edges(tri).tolist()}
    assert sum(tuple(sorted(w)) not in have for w in walls.tolist()) > 5  # recovery has work
    out, failed = recover_segments(p, tri, walls)
    assert len(failed) == 0
    assert_valid_triangulation(p, out)
    edges = {tuple(e) for e in unique_edges(out).tolist()}
    assert all(tuple(sorted(w)) in edges for w in walls.tolist())
    # Constrained Delaunay: every side other than a segment has an empty circle.
    assert_empty_circles(p, out, skip={tuple(sorted(w)) for w in walls.tolist()})
    # The flood fill finds exactly the disc, with no open region.
    inside, open_ = classify_by_walls(out, walls)
    assert not open_.any()
    ring = p[walls[:, 0]]
    polygon = 0.5 * np.sum(ring[:, 0] * np.roll(ring[:, 1], -1) - np.roll(ring[:, 0], -1) * ring[:, 1])
    assert signed_areas(p, out[inside]).sum() == pytest.approx(polygon, rel=1e-12)
    kept = inside_triangles(p, out, lambda q: np.hypot(*(q - 11.5).T) - 8.4, walls)
    assert np.array_equal(kept, out[inside])


def test_recovery_of_hull_sides_and_blocked_segments() -> None:
    p = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0], [1.0, -1.0]])
    tri = delaunay(p)
    # 0-1 is a hull side held as 1 -> 0 by no triangle, 0 -> 1 by one; 0-2 runs through node 1;
    # 3-4 crosses the edge 0-1-2 row at node 1 too; 5 does not exist.
    out, failed = recover_segments(p, tri, np.array([[1, 0], [0, 2], [3, 4], [0, 5], [4, 2]]))
    assert failed.tolist() == [1, 2, 3]
    assert_valid_triangulation(p, out)


def test_edges_neighbours_and_boundary_match_the_numpy_formulation() -> None:
    p = np.random.default_rng(8).random((300, 2))
    full = delaunay(p)
    c = p[full].mean(axis=1)
    for tri in (full, full[np.hypot(*(c - 0.5).T) > 0.2], full[::-1].copy(), full.astype(np.int32)):
        e = np.sort(_sides(tri), axis=1)
        assert np.array_equal(unique_edges(tri), np.unique(e, axis=0))
        assert np.array_equal(neighbours(tri), _ref_neighbours(tri))
        key = np.sort(_sides(tri), axis=1)
        _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        assert np.array_equal(boundary_edges(tri), _sides(tri)[count[inv.reshape(-1)] == 1])
    assert unique_edges(np.zeros((0, 3), dtype=int)).shape == (0, 2)


def test_measures_match_the_formulas() -> None:
    p = np.random.default_rng(9).random((200, 2))
    tri = delaunay(p)[:, [0, 2, 1]]  # clockwise: negative areas
    x = p[tri]
    area = 0.5 * ((x[:, 1, 0] - x[:, 0, 0]) * (x[:, 2, 1] - x[:, 0, 1])
                  - (x[:, 1, 1] - x[:, 0, 1]) * (x[:, 2, 0] - x[:, 0, 0]))
    assert np.array_equal(signed_areas(p, tri), area)
    sides = np.stack([np.hypot(*(x[:, (k + 2) % 3] - x[:, (k + 1) % 3]).T) for k in range(3)], axis=1)
    np.testing.assert_allclose(edge_lengths(p, tri), sides, rtol=1e-15)
    a, b, c = sides.T
    q = (b + c - a) * (c + a - b) * (a + b - c) / (a * b * c)
    np.testing.assert_allclose(triangle_quality(p, tri), q, rtol=1e-12, atol=1e-14)
    assert triangle_quality(np.zeros((3, 2)), np.array([[0, 1, 2]])).tolist() == [0.0]
    with pytest.raises(IndexError, match="node 200"):
        signed_areas(p, np.array([[0, 1, 200]]))
    with pytest.raises(IndexError, match="node -1"):
        triangle_quality(p, np.array([[0, 1, -1]]))


def test_bit_identical_repeats_with_one_or_two_threads() -> None:
    code = (
        "import hashlib, numpy as np\n"
        "from injmesh.triangulation import delaunay, flip_to_delaunay, recover_segments\n"
        "from injmesh.quality import unique_edges\n"
        "g = np.arange(20.0); x, y = np.meshgrid(g, g)\n"
        "p = np.c_[x.ravel(), y.ravel()]\n"
        "inner = np.all((p > 0) & (p < 19), axis=1)\n"
        "p[inner] += np.random.default_rng(1).uniform(-0.3, 0.3, (inner.sum(), 2))\n"
        "t = delaunay(p)\n"
        "q = p.copy(); q[inner] += np.random.default_rng(2).uniform(-0.05, 0.05, (inner.sum(), 2))\n"
        "f = flip_to_delaunay(q, t)\n"
        "r, _ = recover_segments(p, t, np.array([[0, 399], [19, 380]]))\n"
        "blob = t.tobytes() + f.tobytes() + r.tobytes() + unique_edges(r).tobytes()\n"
        "print(hashlib.sha256(blob).hexdigest())\n"
    )
    out = []
    for threads in ("1", "2", "2"):
        env = {**os.environ, "NUMBA_NUM_THREADS": threads, "PYTHONPATH": SRC}
        run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        out.append(run.stdout.strip())
    assert len(out[0]) == 64 and out[0] == out[1] == out[2]
    namespace: dict[str, object] = {}
    exec(code.replace("print(", "digest = ("), namespace)
    assert namespace["digest"] == out[0]
    assert hashlib.sha256(b"").hexdigest() != out[0]


def _even_odd(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The plain loop over every segment that ``inside_polygon`` replaced."""
    out = np.zeros(len(q), dtype=bool)
    for i in range(len(a)):
        with np.errstate(invalid="ignore", divide="ignore"):
            cross = (a[i, 1] > q[:, 1]) != (b[i, 1] > q[:, 1])
            xint = a[i, 0] + (q[:, 1] - a[i, 1]) * (b[i, 0] - a[i, 0]) / (b[i, 1] - a[i, 1])
        out ^= cross & (q[:, 0] < xint)
    return out


@pytest.mark.parametrize("shape", ["fractal", "comb", "flat", "square"])
def test_inside_polygon_by_strips_matches_the_plain_even_odd_loop(shape: str) -> None:
    from injmesh import shapes
    from injmesh.triangulation import inside_polygon

    rng = np.random.default_rng(3)
    if shape == "fractal":
        ring = shapes.large(0, n_vertices=600).rings[0]
    elif shape == "comb":  # tall segments: every strip holds many of them
        xs = np.linspace(0, 1, 200)
        ring = np.stack([xs, np.tile([0.0, 1.0], 100)], axis=1)
    elif shape == "flat":  # no height at all
        ring = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    else:
        ring = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    a, b = ring, np.roll(ring, -1, axis=0)
    lo, hi = ring.min(axis=0) - 0.2, ring.max(axis=0) + 0.2
    q = np.concatenate([
        rng.uniform(lo, hi, (3000, 2)),
        ring, 0.5 * (a + b),  # on vertices and on segments
        np.stack([rng.uniform(lo[0], hi[0], len(ring)), ring[:, 1]], axis=1),  # at vertex heights
        [[0.5, np.nan], [np.inf, 0.5], [0.5, -np.inf]],
    ])
    got = inside_polygon(q, a, b)
    assert np.array_equal(got, _even_odd(q, a, b))
    if shape != "flat":
        assert got.any() and not got.all()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(3, 300),
       kind=st.sampled_from(["random", "lattice", "dups"]))
def test_delaunay_gives_the_neighbours_of_its_triangles(seed: int, n: int, kind: str) -> None:
    """The neighbour table delaunay_with_neighbours() hands on is the one neighbours() finds,
    on random points, cocircular lattices and points with exact duplicates (left out of the
    triangles); its triangles are delaunay()'s; and inside_triangles() given the table keeps
    the same triangles as without it."""
    from injmesh.kernels import mesh
    from injmesh.triangulation import delaunay_with_neighbours, inside_triangles

    rng = np.random.default_rng(seed)
    if kind == "lattice":
        k = max(2, int(np.sqrt(n)))
        p = np.stack(np.meshgrid(np.arange(k), np.arange(k)), axis=-1).reshape(-1, 2).astype(float)
    else:
        p = rng.random((n, 2))
        if kind == "dups":
            p = np.concatenate([p, p[rng.integers(0, n, n // 3 + 1)]])
    tri, nbr = delaunay_with_neighbours(p)
    assert np.array_equal(tri, delaunay(p))
    t64 = np.array(tri, dtype=np.int64)
    assert np.array_equal(nbr, mesh.neighbours(t64, len(p)))
    # The hull's edges as walls (counter-clockwise: the domain on their left).
    a = t64.ravel()
    b = t64[:, [1, 2, 0]].ravel()
    hull = (nbr[:, [2, 0, 1]].ravel() < 0)
    walls = np.stack([a[hull], b[hull]], axis=1)

    def outside(q):  # type: ignore[no-untyped-def]
        return np.full(len(q), 1.0)  # wrong everywhere: only the walls' flood fill keeps triangles

    kept = inside_triangles(p, tri, outside, walls, nbr)
    assert np.array_equal(kept, inside_triangles(p, tri, outside, walls))
    from injmesh.triangulation import FLAT

    _, _, flat = mesh.centroids_and_flatness(p, t64, FLAT)
    assert len(kept) == len(tri) - int(flat.sum())


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(10, 150), k=st.integers(3, 10))
def test_recovery_keeps_the_neighbour_table(seed: int, n: int, k: int) -> None:
    # constrained_triangles hands the triangulation's neighbour table to the flips and their
    # result to the inside test, instead of finding it twice more: the table the flips keep
    # must be the result's own, and the triangles those of recovery from scratch.
    from injmesh.kernels import mesh
    from injmesh.triangulation import _recover_segments, delaunay_with_neighbours

    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    ring = rng.choice(n, min(k, n), replace=False)
    seg = np.stack([ring, np.roll(ring, -1)], axis=1)
    tri, nbr = delaunay_with_neighbours(p)
    plain, failed = recover_segments(p, tri.copy(), seg)
    kept, failed_kept, table = _recover_segments(p, tri, seg, nbr)
    assert np.array_equal(plain, kept) and np.array_equal(failed, failed_kept)
    assert np.array_equal(table, mesh.neighbours(kept.astype(np.int64), n))
