"""Background grids of exact-boundary domains: signs by scanlines, d evaluated near the boundary."""

from __future__ import annotations

import numpy as np
import pytest

from injmesh import Circle, Polygon, Rectangle, shapes
from injmesh.cases import CASES
from injmesh.sizing.background import NEAR, _sdf_on_grid


def _domains():
    out = [pytest.param(c.geometry, id=name) for name, c in CASES.items()]
    for fam, seed in [("star", 0), ("holes", 1), ("neck", 2), ("airfoil", 0), ("coastline", 1), ("walk", 4)]:
        out.append(pytest.param(shapes.FAMILIES[fam](seed).domain(), id=f"{fam}{seed}"))
    # A vertex exactly on grid rows and columns, and a hole touching nothing.
    out.append(pytest.param(Polygon([(0, 0), (1, 0), (1, 1), (0.5, 0.5), (0, 1)]) - Circle((0.5, 0.2), 0.1),
                            id="on-rows"))
    out.append(pytest.param(Rectangle((0, 0), (3, 1)) - Rectangle((1, 0.25), (2, 0.75)), id="frame"))
    return out


@pytest.mark.parametrize("domain", _domains())
@pytest.mark.parametrize("cells", [64, 200])
def test_grid_signs_and_near_values_match_the_sdf(domain, cells: int) -> None:
    x0, y0, x1, y1 = domain.bbox
    s = max(x1 - x0, y1 - y0) / cells
    x = x0 + s * (np.arange(int((x1 - x0) / s) + 5) - 2)
    y = y0 + s * (np.arange(int((y1 - y0) / s) + 5) - 2)
    got = _sdf_on_grid(domain, x, y, s)
    X, Y = np.meshgrid(x, y)
    full = domain.sdf(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(got.shape)
    assert np.array_equal(got <= 0, full <= 0)
    near = np.abs(full) < NEAR * s * 0.99
    assert np.array_equal(got[near], full[near])
    # Elsewhere the magnitude is a lower bound of |d|.
    assert np.all(np.abs(got) <= np.abs(full) + 1e-12 * s)


@pytest.mark.parametrize("domain", _domains()[:8])
def test_inside_test_answers_as_the_sdf(domain) -> None:
    from injmesh.sizing.background import inside_test

    x0, y0, x1, y1 = domain.bbox
    test = inside_test(domain, max(x1 - x0, y1 - y0) / 97)
    rng = np.random.default_rng(3)
    w, h = x1 - x0, y1 - y0
    p = rng.random((5000, 2)) * [1.4 * w, 1.4 * h] + [x0 - 0.2 * w, y0 - 0.2 * h]
    # Points on the boundary itself too.
    rim = np.concatenate(domain.exact_brep().boundary_loops(0.05)) if hasattr(domain, "exact_brep") else p[:0]
    p = np.concatenate([p, rim])
    expected = domain.sdf(p) <= 0
    if isinstance(domain, Circle):
        assert test is None  # a closed formula: the plain call is as fast
        return
    assert test is not None
    assert np.array_equal(test(p), expected)


@pytest.mark.parametrize("domain", [Rectangle((0.0, 0.0), (1.0, 1.0)), Rectangle((-3.0, 2.0), (5.0, 2.5)),
                                    Circle((0.3, -0.2), 0.7)])
def test_closed_form_grids_equal_the_pointwise_sdf(domain: Circle | Rectangle) -> None:
    """A circle's or a rectangle's d on a grid comes from its rows' and columns' offsets by
    broadcasting: the very values of its point-wise sdf."""
    x0, y0, x1, y1 = domain.bbox
    x = np.linspace(x0 - 0.3, x1 + 0.2, 157)
    y = np.linspace(y0 - 0.1, y1 + 0.4, 131)
    X, Y = np.meshgrid(x, y)
    expected = domain.sdf(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(X.shape)
    assert np.array_equal(_sdf_on_grid(domain, x, y, float(x[1] - x[0])), expected)


@pytest.mark.parametrize("domain", _domains())
def test_inside_test_answers_as_the_sdf_next_to_the_boundary(domain) -> None:
    """Points within two grid spacings of the boundary, where the test decides whether a cell
    is sure of its sign (the nodes it trusts are farther from every polyline segment than a
    cell's half diagonal plus the polylines' tolerance)."""
    from injmesh.sizing.background import inside_test

    x0, y0, x1, y1 = domain.bbox
    s = max(x1 - x0, y1 - y0) / 64
    test = inside_test(domain, s)
    if test is None:
        return
    from injmesh.sizing.background import exact_boundary

    rim = np.concatenate(exact_boundary(domain).boundary_loops(s / 4))
    rng = np.random.default_rng(7)
    p = np.concatenate([rim] + [rim + rng.uniform(-w * s, w * s, rim.shape) for w in (2.0, 1.0, 0.1)
                                for _ in range(4)])
    assert np.array_equal(test(p), domain.sdf(p) <= 0)


@pytest.mark.parametrize("seed", range(5))
def test_near_nodes_are_the_nodes_within_reach(seed: int) -> None:
    """Every node within ``reach`` of a segment is flagged; no node farther than that is."""
    from injmesh.kernels.raster import near_nodes

    rng = np.random.default_rng(seed)
    a = rng.random((40, 2))
    b = a + rng.normal(scale=0.05, size=a.shape)
    b[0] = a[0]  # a point segment
    x, y = np.linspace(-0.2, 1.2, 71), np.linspace(-0.1, 1.1, 53)
    reach = 0.03
    near = near_nodes(x, y, a, b, reach)
    X, Y = np.meshgrid(x, y)
    p = np.stack([X.ravel(), Y.ravel()], axis=1)[:, None, :]
    ab = b - a
    t = np.clip(np.einsum("nkj,kj->nk", p - a, ab) / np.maximum(np.einsum("kj,kj->k", ab, ab), 1e-300), 0, 1)
    dist = np.hypot(*(p - a - t[..., None] * ab).transpose(2, 0, 1)).min(axis=1).reshape(X.shape)
    assert np.all(near[dist <= reach * (1 - 1e-9)])
    assert not np.any(near[dist > reach * (1 + 1e-9)])


def test_cell_signs_are_the_numpy_lookup() -> None:
    """The compiled cell lookup of the inside test: the cell by ``floor`` of the offsets, the
    sign where the cell is known, every other point (outside the grid, NaN) left to decide."""
    from injmesh.kernels.raster import cell_signs

    rng = np.random.default_rng(2)
    known, neg = rng.random((13, 17)) < 0.7, rng.random((13, 17)) < 0.5
    p = rng.uniform(-0.3, 2.0, (4000, 2))
    p[:5] = [[np.nan, 0.5], [0.5, np.inf], [-np.inf, 0.1], [0.1, 0.1], [1.7, 1.3]]
    x0, y0, s = 0.05, -0.02, 0.1
    out, rest = cell_signs(p, x0, y0, s, known, neg)
    with np.errstate(invalid="ignore"):
        i, j = np.floor((p[:, 0] - x0) / s), np.floor((p[:, 1] - y0) / s)
        ok = (i >= 0) & (i < 17) & (j >= 0) & (j < 13)
    ii, jj = np.where(ok, i, 0).astype(np.intp), np.where(ok, j, 0).astype(np.intp)
    sure = ok & known[jj, ii]
    assert np.array_equal(rest, np.flatnonzero(~sure))
    assert np.array_equal(out, np.where(sure, neg[jj, ii], False))


@pytest.mark.parametrize("domain", _domains())
@pytest.mark.parametrize("cells", [16, 64, 200])
def test_signs_on_grid_are_the_sdf_signs(domain, cells: int) -> None:
    """The sign-only grid (sdf next to the polylines only) has the signs of the full grid and
    of the point-wise sdf."""
    from injmesh.sizing.background import signs_on_grid

    x0, y0, x1, y1 = domain.bbox
    s = max(x1 - x0, y1 - y0) / cells
    x = x0 + s * (np.arange(int((x1 - x0) / s) + 5) - 2)
    y = y0 + s * (np.arange(int((y1 - y0) / s) + 5) - 2)
    got = signs_on_grid(domain, x, y, s)
    assert np.array_equal(got, _sdf_on_grid(domain, x, y, s) <= 0)
    X, Y = np.meshgrid(x, y)
    assert np.array_equal(got, domain.sdf(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(got.shape) <= 0)


@pytest.mark.parametrize("cells", [8, 16, 40])
def test_signs_on_grid_between_a_chord_and_its_arc(cells: int) -> None:
    """A node between a polyline's chord and the arc it stands for is inside the domain but
    outside the polygon: the sign-only grid asks the sdf there."""
    from injmesh.sizing.background import _polylines, exact_boundary, signs_on_grid

    domain = Circle((0.1, -0.2), 1.0) - Circle((0.3, 0.1), 0.3)
    x0, y0, x1, y1 = domain.bbox
    s = max(x1 - x0, y1 - y0) / cells
    a, b = _polylines(exact_boundary(domain), s)
    hits = 0
    for k in range(0, len(a), max(1, len(a) // 7)):
        mid = 0.5 * (a[k] + b[k])
        nrm = np.array([b[k, 1] - a[k, 1], a[k, 0] - b[k, 0]])  # outward for the outer loop
        sag = abs(float(domain.sdf(mid[None])[0]))
        for side in (1.0, -1.0):
            p = mid + side * 0.5 * sag * nrm / np.hypot(*nrm)
            x = p[0] + s * np.arange(-int((p[0] - x0) / s) - 2, int((x1 - p[0]) / s) + 3)
            y = p[1] + s * np.arange(-int((p[1] - y0) / s) - 2, int((y1 - p[1]) / s) + 3)
            X, Y = np.meshgrid(x, y)
            full = domain.sdf(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(X.shape) <= 0
            assert np.array_equal(signs_on_grid(domain, x, y, s), full)
            hits += 1
    assert hits > 0


@pytest.mark.parametrize("domain", _domains())
def test_sign_only_backgrounds_have_the_full_grids_signs(domain) -> None:
    """A background sampled for its signs alone has the inside nodes and the band of the full
    one, and the loops traced from it (which sample d again) are the full grid's."""
    from injmesh.sizing.background import make_background
    from injmesh.sizing.features import _loops

    x0, y0, x1, y1 = domain.bbox
    s = max(x1 - x0, y1 - y0) / 150
    full = make_background(domain, s, check=False)
    signs = make_background(domain, s, check=False, signs_only=True)
    assert np.array_equal(signs.inside, full.inside) and np.array_equal(signs.band, full.band)
    a, b = _loops(domain, signs), _loops(domain, full)
    assert len(a) == len(b) and all(np.array_equal(p, q) for p, q in zip(a, b, strict=True))


@pytest.mark.parametrize("seed", range(4))
def test_quarter_samples_are_the_numpy_form(seed: int) -> None:
    """The node estimate's jittered samples, compiled: the NumPy form's numbers bit for bit."""
    from injmesh.kernels.raster import quarter_samples

    quarter = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
    r2 = np.array([0.7548776662466927, 0.5698402909980532])
    rng = np.random.default_rng(seed)
    for _ in range(20):
        k = int(rng.integers(0, 3000))
        side = float(rng.random() * 10 ** rng.uniform(-6, 3))
        centres = rng.normal(size=(k, 2)) * 10 ** rng.uniform(-3, 3)
        c = np.arange(k)
        jitter = np.stack([(c * r2[0]) % 1.0, (c * r2[1]) % 1.0], axis=1) - 0.5
        ref = (centres[None, :, :] + side * (quarter[:, None, :] + 0.5 * jitter[None, :, :])).reshape(-1, 2)
        assert np.array_equal(quarter_samples(centres, side, quarter, r2).view(np.int64), ref.view(np.int64))


@pytest.mark.parametrize("seed", range(4))
def test_densify_is_the_numpy_form(seed: int) -> None:
    """Closed polylines cut into pieces no longer than the step, compiled: the NumPy form's
    vertices bit for bit (repeated vertices, a single vertex and an empty loop included)."""
    from injmesh.sizing.background import densify

    def numpy_form(loop: np.ndarray, step: float) -> np.ndarray:
        nxt = np.roll(loop, -1, axis=0)
        pieces = np.maximum(1, np.ceil(np.hypot(*(nxt - loop).T) / step)).astype(np.intp)
        start = np.repeat(loop, pieces, axis=0)
        delta = np.repeat(nxt - loop, pieces, axis=0)
        t = np.arange(int(pieces.sum())) - np.repeat(np.cumsum(pieces) - pieces, pieces)
        return start + (t / np.repeat(pieces, pieces))[:, None] * delta

    rng = np.random.default_rng(seed)
    for trial in range(100):
        n = int(rng.integers(0, 200))
        scale = 10 ** rng.uniform(-3, 3)
        loop = rng.normal(size=(n, 2)) * scale
        if trial % 3 == 0:
            loop = np.round(loop, 1)
        if trial % 5 == 0 and n > 2:
            loop[1] = loop[0]
        step = scale * float(10 ** rng.uniform(-2, 1))
        got, ref = densify(loop, step), numpy_form(loop, step)
        assert got.shape == ref.shape and np.array_equal(got.view(np.int64), ref.view(np.int64))


def test_ring_cell_walks_the_rings_row_by_row():
    from injmesh.kernels.raster import ring_cell

    def rows(cx, cy, ring, nx, ny):  # the searches' former walk, written out
        out = []
        for gy in range(cy - ring, cy + ring + 1):
            for gx in range(cx - ring, cx + ring + 1):
                on_ring = max(abs(gx - cx), abs(gy - cy)) == ring
                if on_ring and 0 <= gx < nx and 0 <= gy < ny:
                    out.append(gy * nx + gx)
        return out

    for nx, ny in [(1, 1), (5, 3), (7, 9)]:
        for cx in range(-2, nx + 2):
            for cy in range(-2, ny + 2):
                for ring in range(0, 6):
                    got = [ring_cell(cx, cy, ring, t, nx, ny) for t in range(8 * ring if ring else 1)]
                    assert [c for c in got if c >= 0] == rows(cx, cy, ring, nx, ny)
