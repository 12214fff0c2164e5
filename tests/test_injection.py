"""Step 2: Advancing Node Injection (Algorithm 4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from conftest import CASE_NAMES
from injmesh import Circle, NodeBudgetError, Polygon, Rectangle, generate
from injmesh.boundary import estimate_nodes, mesh_boundary
from injmesh.cases import CASES
from injmesh.injection import inject_nodes
from injmesh.sizing import as_size_function

BUDGET = 10**6


def _inject(domain, size, **kwargs):
    h = as_size_function(size)
    b = mesh_boundary(domain, h, np.empty((0, 2)), max_nodes=BUDGET)
    return h, b, inject_nodes(domain, h, b, b.points, max_nodes=kwargs.pop("max_nodes", BUDGET), **kwargs)


def _check_spacing(h, boundary_points: np.ndarray, injected: np.ndarray) -> None:
    """No injected node closer than 0.5 h to any other node (h averaged over the pair)."""
    allp = np.concatenate([boundary_points, injected])
    hv = h(allp)
    pairs = cKDTree(allp).query_pairs(float(hv.max()), output_type="ndarray")
    pairs = pairs[pairs.max(axis=1) >= len(boundary_points)]  # at least one injected node
    dist = np.hypot(*(allp[pairs[:, 0]] - allp[pairs[:, 1]]).T)
    assert np.all(dist >= 0.5 * 0.5 * (hv[pairs[:, 0]] + hv[pairs[:, 1]]))


@pytest.mark.parametrize("name", CASE_NAMES)
def test_injection_on_paper_cases(name: str) -> None:
    case = CASES[name]
    h, b, inj = _inject(case.geometry, case.size)
    assert inj.ndim == 2 and inj.shape[1] == 2 and len(inj) > 0
    assert np.all(case.geometry.sdf(inj) < 0)
    _check_spacing(h, b.points, inj)
    _, expected = estimate_nodes(case.geometry, h)
    assert 0.8 * expected <= len(b.points) + len(inj) <= 1.3 * expected


@pytest.mark.parametrize(
    "domain",
    [
        Rectangle((0, 0), (2, 1)),
        Circle((0, 0), 1) - Circle((0.3, 0), 0.3),
        Polygon([(0, 0), (2, 0), (2, 0.3), (0.3, 0.3), (0.3, 2), (0, 2)]),  # thin arms
    ],
    ids=["rectangle", "eccentric-hole", "thin-l"],
)
def test_injection_spacing_uniform_h(domain) -> None:
    h, b, inj = _inject(domain, 0.1)
    assert np.all(domain.sdf(inj) < 0)
    _check_spacing(h, b.points, inj)
    _, interior = estimate_nodes(domain, h)
    # estimate_nodes counts area only; the boundary adds about half its own nodes (a thin arm,
    # 3 h wide, is mostly boundary).
    expected = interior + 0.5 * len(b.points)
    assert 0.8 * expected <= len(b.points) + len(inj) <= 1.2 * expected


def test_straight_front_injects_equilateral_rows() -> None:
    """From a straight side with constant h, the first layer sits sqrt(3)/2 h inside."""
    h, b, inj = _inject(Rectangle((0, 0), (4, 4)), 0.2)
    first = inj[np.abs(inj[:, 1] - np.sqrt(3) / 2 * 0.2) < 1e-9]
    assert len(first) >= 10


def test_injection_is_deterministic() -> None:
    case = CASES["square_with_four_holes"]
    a = _inject(case.geometry, case.size)[2]
    b = _inject(case.geometry, case.size)[2]
    assert np.array_equal(a, b)


def test_existing_nodes_are_avoided_and_not_modified() -> None:
    disc = Circle((0, 0), 1)
    h = as_size_function(0.1)
    b = mesh_boundary(disc, h, np.empty((0, 2)), max_nodes=BUDGET)
    centre = np.array([[0.0, 0.0]])
    existing = np.concatenate([b.points, centre])
    before = existing.copy()
    inj = inject_nodes(disc, h, b, existing, max_nodes=BUDGET)
    assert np.array_equal(existing, before)
    assert np.hypot(*inj.T).min() >= 0.5 * 0.1


def test_small_domain_needs_no_injection() -> None:
    """A disc only about 1.5 h across: the boundary nodes are all there is, or nearly."""
    h, b, inj = _inject(Circle((0, 0), 0.08), 0.1)
    assert len(inj) <= 1


def test_injection_budget() -> None:
    with pytest.raises(NodeBudgetError, match="max_nodes"):
        _inject(Rectangle((0, 0), (1, 1)), 0.05, max_nodes=200)


def test_injection_reports_layers() -> None:
    events = []
    _inject(Rectangle((0, 0), (1, 1)), 0.1, callback=events.append)
    assert events and all(e.stage == "injection" for e in events)
    steps = [e.step for e in events]
    # One event per layer, then a last one at the layer cap: the progress ends at 100 %.
    assert steps[:-1] == list(range(1, len(steps)))
    assert steps[-1] == events[-1].total > steps[-2]
    nodes = [e.info["nodes"] for e in events]
    assert nodes == sorted(nodes)


@pytest.mark.parametrize(("h_min", "grade"), [(0.0015, 40.0), (0.001, 80.0)])
def test_injection_reaches_where_h_is_smallest(h_min: float, grade: float) -> None:
    """h smallest far from the boundary: the fronts must reach it, not stop at a layer cap.

    A disc with h growing ``grade``:1 from its centre to its rim.  The layer cap used to come
    from the boundary's h alone and left a hole at the centre (a point 1.7 h and 5.7 h from
    the nearest node in these two cases).  No point of the disc may be further than h from a
    node.
    """
    size = lambda p: h_min * (1.0 + (grade - 1.0) * np.hypot(p[:, 0], p[:, 1]))  # noqa: E731
    h, b, inj = _inject(Circle((0, 0), 1.0), size)
    nodes = np.concatenate([b.points, inj])
    rng = np.random.default_rng(0)
    r, t = np.sqrt(rng.random(20_000)) * 0.99, rng.random(20_000) * 2 * np.pi
    q = np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
    gap, _ = cKDTree(nodes).query(q)
    assert np.max(gap / h(q)) < 1.0
    _check_spacing(h, b.points, inj)


def test_gaps_the_fronts_left_are_filled() -> None:
    from injmesh.injection import _fill_gaps, _Proximity

    # Only the boundary placed (as if every front had died at once): the fill covers the
    # interior at about h, keeping clear of the boundary and of each other.
    dom = Rectangle((0, 0), (2, 1))
    h = as_size_function(0.1)
    b = mesh_boundary(dom, h, np.empty((0, 2)), max_nodes=BUDGET)
    grid = _Proximity(dom, b, b.points, h(b.points), 0.1)
    filled = _fill_gaps(dom, h, grid)
    xs, ys = np.meshgrid(np.linspace(0.1, 1.9, 37), np.linspace(0.1, 0.9, 17))
    probe = np.stack([xs.ravel(), ys.ravel()], axis=1)
    assert cKDTree(np.concatenate([b.points, filled])).query(probe)[0].max() < 0.1
    _check_spacing(h, b.points, filled)
    assert len(filled) == pytest.approx(2 / (np.sqrt(3) / 2 * 0.01), rel=0.3)
    # After a full injection there is nothing left to fill.
    dom2 = Circle((0, 0), 1)
    b2 = mesh_boundary(dom2, h, np.empty((0, 2)), max_nodes=BUDGET)
    injected = inject_nodes(dom2, h, b2, b2.points, max_nodes=BUDGET)
    grid2 = _Proximity(dom2, b2, np.concatenate([b2.points, injected]),
                       h(np.concatenate([b2.points, injected])), 0.1)
    assert len(_fill_gaps(dom2, h, grid2)) == 0


def test_the_fill_skips_the_exterior_without_changing_what_it_offers() -> None:
    """For an exact distance the fill stops offering lattice cells that lie wholly outside
    (found at a coarser level); the nodes it places are those of the same domain given as a
    plain signed distance, for which nothing is skipped."""
    from injmesh.geometry import as_domain
    from injmesh.injection import _fill_gaps, _Proximity

    # A thin "C" in a large box (most of the box is outside) with h graded 8:1, so that the
    # fill runs several levels.
    ring = Circle((0, 0), 1.0) - Circle((0, 0), 0.8) - Rectangle((0.3, -0.2), (1.2, 0.2))
    size = as_size_function(lambda p: 0.02 + 0.07 * (p[:, 1] + 1.0))
    plain = as_domain(lambda p: ring.sdf(p), bbox=ring.bbox)
    assert getattr(ring, "exact_distance", False) is True
    assert getattr(plain, "exact_distance", False) is not True
    placed = []
    for dom in (ring, plain):
        h = size.restricted(dom)
        b = mesh_boundary(ring, h, np.empty((0, 2)), max_nodes=BUDGET)
        grid = _Proximity(dom, b, b.points, h(b.points), float(h(b.points).min()))
        placed.append(_fill_gaps(dom, h, grid))
    assert len(placed[0]) > 100
    assert np.array_equal(placed[0], placed[1])


@pytest.mark.parametrize("rings", [(0, 0), (3, 8)])
def test_the_fill_decides_the_same_with_or_without_the_distance_transform(
        monkeypatch: pytest.MonkeyPatch, rings: tuple[int, int]) -> None:
    """The fill asks each empty cell's nearest node by a ring search where the cells are near
    nodes and few are left over (else the whole level's distance transform): same nodes either
    way, on a fill that places nodes (a box whose fronts died at once) and one that places none
    (a graded disc the fronts filled, whose box corners are far from every node)."""
    import injmesh.injection as inj
    from injmesh.injection import _fill_gaps, _Proximity

    graded = as_size_function(lambda p: 0.01 * (1.0 + 9.0 * np.hypot(p[:, 0], p[:, 1])))
    cases = [(Rectangle((0, 0), (2, 1)), as_size_function(lambda p: 0.02 + 0.05 * p[:, 0]), False),
             (Circle((0, 0), 1), graded, True)]
    for dom, size, inject in cases:
        h = size.restricted(dom)
        b = mesh_boundary(dom, h, np.empty((0, 2)), max_nodes=BUDGET)
        nodes = b.points
        if inject:
            nodes = np.concatenate([nodes, inject_nodes(dom, h, b, b.points, max_nodes=BUDGET)])
        out = []
        for search in (True, False):
            monkeypatch.setattr(inj, "FILL_SEARCH_CELLS", 0 if search else 1 << 62)
            monkeypatch.setattr(inj, "FILL_NEAR_SHARE", -1.0)
            monkeypatch.setattr(inj, "FILL_RINGS", rings)
            grid = _Proximity(dom, b, nodes, h(nodes), float(h(b.points).min()))
            out.append(_fill_gaps(dom, h, grid))
        assert np.array_equal(out[0], out[1])
        assert (len(out[0]) > 100) != inject


def test_only_straight_outer_walls_stage_their_holes():
    """``injection._straight`` tells straight outer walls, whose fronts lay a lattice and whose
    holes alone go first, from curved ones, whose fronts are rings and which lay a strip too."""
    from injmesh.boundary import BoundaryMesh
    from injmesh.injection import _straight

    def loop(points):
        n = len(points)
        idx = np.arange(n)
        return BoundaryMesh(np.asarray(points, dtype=float), np.stack([idx, (idx + 1) % n], axis=1),
                            np.zeros(n, dtype=np.intp), np.zeros(n, dtype=bool))

    t = np.linspace(0, 1, 10, endpoint=False)
    square = np.concatenate([np.stack([t, 0 * t], 1), np.stack([1 + 0 * t, t], 1),
                             np.stack([1 - t, 1 + 0 * t], 1), np.stack([0 * t, 1 - t], 1)])
    a = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    assert _straight(loop(square))
    assert not _straight(loop(np.stack([np.cos(a), np.sin(a)], 1)))


@pytest.mark.parametrize(("domain", "h"), [
    (Rectangle((0, 0), (1, 1)) - Circle((0.3, 0.3), 0.15) - Circle((0.7, 0.65), 0.2), 0.01),
    (Circle((0, 0), 1), 0.02),
    (Circle((0, 0), 1) - Circle((0.3, 0.1), 0.3), 0.02),
], ids=["square with two holes", "disc", "off-centre annulus"])
def test_loops_lay_strips_and_a_lattice_where_h_is_uniform(domain, h):
    """With h the same on every loop, the holes (inside straight walls) or every loop (inside
    curved ones) lay a two-row strip first, then a lattice fills the rest
    (injection.INNER_LAYERS): ring fronts to the end gave q_mean 0.9913 / 0.9845 / 0.9860
    (73 / 128 / 113 steps), then 0.9961 / 0.9976 / 0.9962 (46 / 48 / 49), and with the strips'
    rings kept in step (injection.RING_WINDOW) 0.9962 / 0.9976 / 0.9962 (46 / 45 / 44)."""
    mesh = generate(domain, h)
    q = mesh.quality()
    assert mesh.stats.valid and mesh.stats.converged
    assert q.mean() > 0.995
    assert q.min() > 0.85


def test_a_graded_interior_keeps_its_fronts():
    """A disc graded 20:1 from its centre (1e5 nodes) has the same h all along its one loop, but
    no lattice suits its interior: the fronts fill it (a lattice band where h matched walled
    the centre in: 10,294 nodes, 1000 steps, not converged)."""
    disc = Circle((0, 0), 1)

    def h(p):
        return 0.00064 * (1 + 19 * np.hypot(p[:, 0], p[:, 1]))

    mesh = generate(disc, h)
    expected = estimate_nodes(disc, as_size_function(h))[1]
    assert mesh.stats.valid and mesh.stats.converged
    assert mesh.n_points == pytest.approx(expected, rel=0.15)
