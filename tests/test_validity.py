"""A mesh is never silently broken: the checks of ``injmesh.validate``, ``strict``, boundary
recovery and the topological inside/outside classification."""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import Delaunay

import injmesh
from conftest import assert_valid_mesh
from injmesh import Circle, MeshError, Polygon, Rectangle
from injmesh.quality import signed_areas
from injmesh.triangulation import classify_by_walls, delaunay, recover_segments
from injmesh.validate import mesh_defects

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.5, 0.5]])
FAN = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
WALLS = np.array([[0, 1], [1, 2], [2, 3], [3, 0]])


def kinds(defects) -> set[str]:
    return {d.kind for d in defects}


def test_a_valid_mesh_has_no_defects():
    sdf = Rectangle((0, 0), (1, 1)).sdf
    assert mesh_defects(SQUARE, FAN, walls=WALLS, sdf=sdf) == []


@pytest.mark.parametrize(
    ("points", "triangles", "walls", "kind", "where"),
    [
        (np.r_[SQUARE, [[3.0, 3.0]]], FAN, WALLS, "unused node", (3.0, 3.0)),
        (np.r_[SQUARE, [[0.5, 0.5]]], np.r_[FAN[:3], [[3, 0, 5]]], WALLS, "duplicate node", (0.5, 0.5)),
        (SQUARE, np.r_[FAN[:3], [[3, 4, 0]]], WALLS, "inverted or flat triangle", None),
        (SQUARE, FAN[:3], WALLS, "lost boundary segment", (0.0, 0.5)),
        (SQUARE, FAN[:3], WALLS, "boundary edge not on the domain boundary", None),
        (SQUARE, FAN, WALLS[[0, 1, 2]], "boundary edge not on the domain boundary", (0.0, 0.5)),
    ],
)
def test_each_defect_is_named_with_its_place(points, triangles, walls, kind, where):
    found = {d.kind: d for d in mesh_defects(points, triangles, walls=walls)}
    assert kind in found
    d = found[kind]
    assert d.count >= 1 and len(d.where) >= 1
    assert kind in str(d) and "(" in str(d)
    if where is not None:
        assert any(np.allclose(w, where) for w in d.where)


def test_degenerate_and_off_boundary_nodes():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-5], [0.5, 1.0]])
    t = np.array([[0, 2, 3], [2, 1, 3], [0, 1, 2]])
    assert "degenerate triangle (q < 0.001)" in kinds(mesh_defects(p, t))
    sdf = Circle((0, 0), 1).sdf
    found = kinds(mesh_defects(SQUARE - 0.5, FAN, walls=WALLS, sdf=sdf))
    assert "boundary node off the boundary" in found


def test_overlapping_triangles():
    t = np.r_[FAN, [[0, 1, 4]]]
    found = kinds(mesh_defects(SQUARE, t, walls=WALLS))
    assert {"overlapping triangles", "edge in more than two triangles"} <= found


def _broken(monkeypatch):
    """Make smoothing lose one triangle, as a bug would."""
    import injmesh.pipeline as pipeline

    real = pipeline.smooth

    def smooth(*args, **kwargs):
        r = real(*args, **kwargs)
        return replace(r, triangles=r.triangles[1:])

    monkeypatch.setattr(pipeline, "smooth", smooth)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 300), eps=st.sampled_from([1e-9, 0.05, 0.3]),
       decimals=st.integers(0, 2))
def test_duplicate_nodes_are_the_pairs_within_eps(seed, n, eps, decimals):
    """The compiled sweep finds exactly the pairs within eps (all pairs, measured directly),
    also on lattices whose columns share one x (rounded coordinates) or differ from it by
    rounding noise."""
    from injmesh.validate import _duplicates

    rng = np.random.default_rng(seed)
    q = np.round(rng.random((n, 2)) * rng.integers(1, 20), decimals)
    q[rng.integers(0, n, 5)] += rng.normal(0.0, eps / 2, (5, 2))
    q[rng.integers(0, n, 5), 0] += 1e-16 * rng.integers(-2, 3, 5)
    i, j = np.triu_indices(n, 1)
    near = np.hypot(*(q[i] - q[j]).T) <= eps
    expected = set(zip(i[near].tolist(), j[near].tolist(), strict=True))
    found = {tuple(r) for r in np.sort(_duplicates(q, eps), axis=1).tolist()}
    assert found == expected


def test_strict_raises_naming_defects(monkeypatch):
    _broken(monkeypatch)
    with pytest.raises(MeshError, match=r"boundary edge not on the domain boundary at \(") as info:
        injmesh.generate(Circle((0, 0), 1), 0.3)
    assert isinstance(info.value, ValueError)
    assert info.value.defects and all(d.count >= 1 for d in info.value.defects)


def test_strict_false_returns_the_mesh_flagged(monkeypatch):
    _broken(monkeypatch)
    with pytest.warns(UserWarning, match="invalid"):
        mesh = injmesh.generate(Circle((0, 0), 1), 0.3, strict=False)
    assert not mesh.stats.valid
    assert "boundary edge not on the domain boundary" in kinds(mesh.stats.defects)


def test_valid_meshes_say_so():
    mesh = injmesh.generate(Circle((0, 0), 1) - Circle((0.2, 0), 0.3), 0.15)
    assert mesh.stats.valid and mesh.stats.defects == ()


def test_classification_drops_triangles_bridging_a_notch():
    # A comb: Delaunay of its vertices bridges the slots; flood fill from the walls does not.
    x = np.repeat(np.arange(6) * 0.2, 2)
    top = np.where(np.arange(12) % 4 < 2, 1.0, 0.2)
    comb = np.c_[x, top]
    comb[1::2, 0] += 0.02
    v = np.r_[[[0.0, 0.0], [1.02, 0.0]], comb[::-1]]
    poly = Polygon(v)
    p = poly.vertices
    tri = delaunay(p)
    walls = np.c_[np.arange(len(p)), np.roll(np.arange(len(p)), -1)]
    full, failed = recover_segments(p, tri, walls)
    assert len(failed) == 0
    inside, open_ = classify_by_walls(full, walls)
    assert not open_.any()
    assert signed_areas(p, full[inside]).sum() == pytest.approx(poly.area, rel=1e-12)
    c = p[full[inside]].mean(axis=1)
    assert poly.sdf(c).max() < 0


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(20, 120))
def test_recover_segments_keeps_a_valid_triangulation(seed, n):
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 1, (n, 2))
    tri = delaunay(p)
    # A chain of random non-crossing segments: a monotone path through sorted points.
    order = np.argsort(p[:, 0])[:: max(1, n // 8)]
    seg = np.c_[order[:-1], order[1:]]
    out, failed = recover_segments(p, tri, seg)
    assert len(failed) == 0
    assert np.all(signed_areas(p, out) > 0)
    assert signed_areas(p, out).sum() == pytest.approx(signed_areas(p, tri).sum(), rel=1e-9)
    assert len(out) == len(Delaunay(p).simplices)
    edges = {tuple(sorted(e)) for t in out.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert all(tuple(sorted(s)) in edges for s in seg.tolist())
    half = np.concatenate([out[:, [0, 1]], out[:, [1, 2]], out[:, [2, 0]]])
    assert len(np.unique(half, axis=0)) == len(half)


def _notch(h: float, degrees: float, depth: float) -> Polygon:
    d = depth * np.tan(np.radians(degrees / 2))
    return Polygon([(0, 0), (1, 0), (1, 1), (0.5 + d, 1), (0.5, 1 - depth), (0.5 - d, 1), (0, 1)])


@pytest.mark.parametrize("degrees", [9.0, 6.0, 3.0])
def test_narrow_notches_are_never_bridged(degrees):
    h = 0.05
    poly = _notch(h, degrees, 6.5 * h)
    mesh = injmesh.generate(poly, h)
    assert_valid_mesh(mesh, poly)
    assert mesh.areas().sum() == pytest.approx(poly.area, rel=1e-9)


def test_a_six_degree_slit_with_graded_size_is_valid():
    """A random graded case whose 6-degree notch made sliding nodes jump across it."""
    v = [[0.834, 0.4419], [0.4899, 0.2744], [0.5089, 0.2862], [0.6130, 0.6585], [0.5246, 0.5663],
         [0.3431, 0.3804], [-0.2030, 0.6289], [-0.4474, 0.8157], [-0.6030, 0.1653],
         [-0.7266, -0.3939], [0.0079, -0.4580], [0.0692, -0.8335]]
    poly = Polygon(v)

    def h(p):
        return 0.03 + 0.3 * np.hypot(p[:, 0] - 0.3, p[:, 1] - 0.2)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # it may not converge; it must be valid
        mesh = injmesh.generate(poly, h)
    assert_valid_mesh(mesh, poly)
    # Vertices turning less than 20 degrees are curve samples, not corners: chords cut them.
    assert mesh.areas().sum() == pytest.approx(poly.area, rel=1e-3)


def test_distmesh_style_size_negative_outside():
    """DistMesh's square with a hole, its h as written: negative inside the hole."""

    def dcircle(p, cx, cy, r):
        return np.hypot(p[:, 0] - cx, p[:, 1] - cy) - r

    def fd(p):
        return np.maximum(Rectangle((-1, -1), (1, 1)).sdf(p), -dcircle(p, 0, 0, 0.5))

    def fh(p):
        return 0.05 + 0.3 * dcircle(p, 0, 0, 0.5)

    corners = [(-1, -1), (-1, 1), (1, -1), (1, 1)]
    mesh = injmesh.generate(fd, fh, bbox=(-1, -1, 1, 1), fixed_points=corners)
    assert_valid_mesh(mesh, fd, diameter=np.hypot(2, 2))
    assert mesh.size_report().relative < 0.2


def test_boundary_tags_are_stable_and_named_by_kind():
    from injmesh.io import boundary_names

    holes = [Circle((-0.5, 0), 0.2), Circle((0.5, 0.1), 0.3), Rectangle((-0.2, -0.8), (0.2, -0.5))]
    outer = Rectangle((-1, -1), (1, 1))
    meshes = []
    for order in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        dom = outer
        for k in order:
            dom = dom - holes[k]
        meshes.append(injmesh.generate(dom, 0.15))
    ref = meshes[0]
    assert boundary_names(ref.boundary_edges, ref.boundary_tags, ref.points) == {
        0: "outer boundary", 1: "hole 1", 2: "hole 2", 3: "hole 3"}
    for m in meshes:
        for tag in range(4):
            e = m.boundary_edges[m.boundary_tags == tag]
            a, b = m.points[e[:, 0]], m.points[e[:, 1]]
            ref_e = ref.boundary_edges[ref.boundary_tags == tag]
            ra, rb = ref.points[ref_e[:, 0]], ref.points[ref_e[:, 1]]
            area = 0.5 * np.sum(a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1])
            assert area == pytest.approx(0.5 * np.sum(ra[:, 0] * rb[:, 1] - rb[:, 0] * ra[:, 1]), rel=1e-2)
    # Largest hole first: the circle of radius 0.3.
    e = ref.boundary_edges[ref.boundary_tags == 1]
    assert np.allclose(np.hypot(*(ref.points[e[:, 0]] - [0.5, 0.1]).T), 0.3)


def test_islands_and_lakes_are_numbered_by_their_outer_boundary():
    from injmesh.io import boundary_names

    big = Rectangle((0, 0), (4, 4)) - Rectangle((1, 1), (3, 3))
    island = Rectangle((1.5, 1.5), (2.5, 2.5)) - Circle((2, 2), 0.2)
    for dom in (big | island, island | big):
        mesh = injmesh.generate(dom, 0.25)
        names = boundary_names(mesh.boundary_edges, mesh.boundary_tags, mesh.points)
        assert names == {0: "outer boundary", 1: "hole 1", 2: "outer boundary 2", 3: "hole 2"}
        e = mesh.boundary_edges[mesh.boundary_tags == 3]
        assert np.allclose(np.hypot(*(mesh.points[e[:, 0]] - 2).T), 0.2)


def test_converged_agrees_with_the_iteration_cap():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for cap in (5, 60, 150, 400):
            mesh = injmesh.generate(Circle((0, 0), 1), 0.1, max_iterations=cap)
            assert mesh.stats.iterations <= cap
            if mesh.stats.iterations >= cap:
                assert not mesh.converged


def _best_q(degrees: float) -> float:
    """The best q a triangle in a corner of this angle can have (isosceles)."""
    a = np.radians(degrees)
    return float(8 * np.sin(a / 2) * np.sin((np.pi - a) / 4) ** 2)


@pytest.mark.parametrize("degrees", [5.0, 10.0, 20.0])
def test_sharp_corner_gets_the_best_triangle_its_angle_allows(degrees):
    t = np.radians(degrees / 2)
    kite = Polygon([(0, 0), (np.cos(t), -np.sin(t)), (1.3, 0), (np.cos(t), np.sin(t))])
    mesh = injmesh.generate(kite, 0.05)
    assert_valid_mesh(mesh, kite)
    q = mesh.quality()
    tip = np.any(np.hypot(*mesh.points[mesh.triangles].transpose(2, 0, 1)) == 0, axis=1)
    assert tip.sum() == 1
    assert q[tip][0] == pytest.approx(_best_q(degrees), rel=0.02)
    # The strip next to the tip is the next worst: within 15 % of the tip here.
    assert q.min() >= 0.85 * _best_q(degrees)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 400), eps=st.sampled_from([1e-9, 0.05, 0.3]),
       decimals=st.integers(0, 2), crowd=st.booleans())
def test_duplicate_search_binned_or_sorted_gives_the_same_pairs_in_the_same_order(
        seed, n, eps, decimals, crowd):
    """The binned search (spread-out nodes) and the sorted scan (its fallback for nodes crowded
    into a few bins) list the same pairs, oriented and ordered alike."""
    import injmesh.validate as val

    rng = np.random.default_rng(seed)
    q = np.round(rng.random((n, 2)) * rng.integers(1, 20), decimals)
    q[rng.integers(0, n, 5)] += rng.normal(0.0, eps / 2, (5, 2))
    if crowd and n > 3:  # most nodes in one tiny cluster, a few far away
        q[: n - 3] = q[0] + rng.normal(0.0, eps, (n - 3, 2))
    q[rng.integers(0, n, 5), 0] += 1e-16 * rng.integers(-2, 3, 5)
    out = []
    for work in (10**15, -1):
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(val, "DUPLICATE_WORK", work)
            out.append(val._duplicates(q, eps))
    assert np.array_equal(out[0], out[1])


def _census(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every distinct edge (i < j, sorted) with its counts each way, by np.unique."""
    u = tri.ravel()
    v = tri[:, [1, 2, 0]].ravel()
    edges, inv = np.unique(np.stack([np.minimum(u, v), np.maximum(u, v)], axis=1), axis=0,
                           return_inverse=True)
    inv = inv.ravel()
    fwd = np.bincount(inv, weights=(u <= v), minlength=len(edges)).astype(np.int64)
    bwd = np.bincount(inv, weights=(u > v), minlength=len(edges)).astype(np.int64)
    return edges, fwd, bwd


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(3, 200), faults=st.integers(0, 6))
def test_unusual_edges_are_those_not_run_along_once_each_way(seed, n, faults):
    """Against a census of every edge by np.unique, on Delaunay meshes with triangles repeated,
    reversed, dropped and with a corner repeated."""
    from injmesh.kernels.mesh import unusual_edges
    from injmesh.triangulation import delaunay

    rng = np.random.default_rng(seed)
    tri = delaunay(rng.random((n, 2))).astype(np.int64)
    for _ in range(faults):
        k = int(rng.integers(0, len(tri)))
        kind = int(rng.integers(0, 4))
        if kind == 0:
            tri = np.concatenate([tri, tri[k:k + 1]])
        elif kind == 1:
            tri[k] = tri[k, ::-1]
        elif kind == 2 and len(tri) > 1:
            tri = np.delete(tri, k, axis=0)
        else:
            tri[k, 2] = tri[k, 0]
    edges, fwd, bwd = _census(tri)
    odd = ~((fwd == 1) & (bwd == 1))
    got = unusual_edges(np.ascontiguousarray(tri), n)
    assert np.array_equal(got[0], edges[odd])
    assert np.array_equal(got[1], fwd[odd])
    assert np.array_equal(got[2], bwd[odd])
