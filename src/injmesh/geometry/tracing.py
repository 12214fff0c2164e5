"""Finding boundary curves from d alone: marching squares, loop ordering, corner detection.

Used for plain callables and for combinations, whose boundary topology is not known in closed
form.  A grid point is *inside* when ``d <= 0``: the boundary is where d changes sign, so a d that
is zero along an interior line (the paper's L-shape) yields no spurious curve there.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .. import _tolerances as tol
from .base import BBox, Domain, FloatArray, GeometryError

# Cell corners in counter-clockwise order and the cell edges between them:
# corner 0 (i, j), 1 (i+1, j), 2 (i+1, j+1), 3 (i, j+1); edge k joins corner k and k+1.
_CORNER_XY = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
_EDGE_MID = 0.5 * (_CORNER_XY + np.roll(_CORNER_XY, -1, axis=0))


def _segment_table() -> dict[tuple[int, bool], list[tuple[int, int]]]:
    """Oriented segments (from edge, to edge) for each marching-squares case.

    A case is the 4-bit mask of inside corners; saddles (5, 10) also depend on whether the cell
    centre is inside.  Each segment is oriented with the inside on its left.
    """
    table: dict[tuple[int, bool], list[tuple[int, int]]] = {}
    for case in range(16):
        inside = [(case >> k) & 1 == 1 for k in range(4)]
        crossing = [k for k in range(4) if inside[k] != inside[(k + 1) % 4]]
        for centre in (False, True):
            if len(crossing) == 0:
                pairs: list[tuple[int, int]] = []
            elif len(crossing) == 2:
                pairs = [(crossing[0], crossing[1])]
            else:
                # Saddle: cut off the two corners that differ from the centre.
                odd = [k for k in range(4) if inside[k] != centre]
                pairs = [((k - 1) % 4, k) for k in odd]
            oriented = []
            for e0, e1 in pairs:
                # The corner shared by edges e0 and e1 (or any inside corner) decides the side.
                a, b = _EDGE_MID[e0], _EDGE_MID[e1]
                probe = [k for k in range(4) if inside[k]]
                c = _CORNER_XY[probe].mean(axis=0) if len(crossing) == 2 else None
                if c is None:
                    shared = ({e0, (e0 + 1) % 4} & {e1, (e1 + 1) % 4}).pop()
                    c = _CORNER_XY[shared]
                    left_should_be_inside = inside[shared]
                else:
                    left_should_be_inside = True
                cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
                oriented.append((e0, e1) if (cross > 0) == left_should_be_inside else (e1, e0))
            table[(case, centre)] = oriented
    return table


_TABLE = _segment_table()


def grid_spacing(bbox: BBox, h_min: float) -> float:
    """The tracing grid's spacing for a box and the smallest target edge length."""
    x0, y0, x1, y1 = bbox
    diam = float(np.hypot(x1 - x0, y1 - y0))
    g = min(h_min / tol.TRACE_PER_H, diam / tol.TRACE_MIN_CELLS)
    return max(g, diam / tol.TRACE_MAX_CELLS)


def sample_grid(
    d: Callable[[FloatArray], FloatArray], bbox: BBox, spacing: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Evaluate d on a grid covering ``bbox`` with one cell of margin.

    Returns ``xs (nx,)``, ``ys (ny,)`` and ``values (ny, nx)``.
    """
    x0, y0, x1, y1 = bbox
    nx = int(np.ceil((x1 - x0) / spacing)) + 3
    ny = int(np.ceil((y1 - y0) / spacing)) + 3
    xs = x0 - spacing + spacing * np.arange(nx)
    ys = y0 - spacing + spacing * np.arange(ny)
    X, Y = np.meshgrid(xs, ys)
    v = np.asarray(d(np.stack([X.ravel(), Y.ravel()], axis=1)), dtype=np.float64)
    return xs.astype(np.float64), ys.astype(np.float64), v.reshape(ny, nx)


def check_box(values: FloatArray, bbox: BBox, diameter: float) -> None:
    """Raise when the domain is empty in its box or spills out of it."""
    if not np.any(values <= 0):
        raise GeometryError(f"the domain is empty inside its bounding box {bbox}: d > 0 everywhere")
    rim = np.concatenate([values[0], values[-1], values[:, 0], values[:, -1]])
    if np.any(rim < -tol.ON_BOUNDARY * diameter):
        raise GeometryError(
            f"the bounding box {bbox} does not contain the domain: d < 0 just outside it"
        )


def trace_loops(
    d: Callable[[FloatArray], FloatArray], bbox: BBox, spacing: float
) -> list[FloatArray]:
    """Closed curves where d changes sign, each with the inside on its left.

    Parameters
    ----------
    d : callable
        Signed distance (or any function negative inside), vectorised over ``(n, 2)``.
    bbox : (xmin, ymin, xmax, ymax)
        A box containing the domain.
    spacing : float
        Grid spacing; features thinner than it may be missed.

    Returns
    -------
    list of (k, 2) arrays
        Polylines, outer boundaries counter-clockwise and holes clockwise, largest first.
    """
    xs, ys, v = sample_grid(d, bbox, spacing)
    diam = float(np.hypot(bbox[2] - bbox[0], bbox[3] - bbox[1]))
    check_box(v, bbox, diam)
    return loops_from_grid(xs, ys, v)


def loops_from_grid(xs: FloatArray, ys: FloatArray, v: FloatArray) -> list[FloatArray]:
    """Marching squares on sampled values ``v (ny, nx)``; see :func:`trace_loops`."""
    ny, nx = v.shape
    inside = v <= 0
    c = [inside[:-1, :-1], inside[:-1, 1:], inside[1:, 1:], inside[1:, :-1]]
    case = (c[0] * 1 + c[1] * 2 + c[2] * 4 + c[3] * 8).ravel()
    centre = (0.25 * (v[:-1, :-1] + v[:-1, 1:] + v[1:, 1:] + v[1:, :-1]) <= 0).ravel()
    cj, ci = np.divmod(np.arange((ny - 1) * (nx - 1)), nx - 1)

    # Global ids of grid edges: horizontal edge (i, j)-(i+1, j) is j*(nx-1)+i; vertical edge
    # (i, j)-(i, j+1) is H + j*nx + i.
    H = ny * (nx - 1)

    def edge_id(k: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        if k == 0:
            return j * (nx - 1) + i
        if k == 1:
            return H + j * nx + i + 1
        if k == 2:
            return (j + 1) * (nx - 1) + i
        return H + j * nx + i

    src, dst = [], []
    for (cs, ctr), segs in _TABLE.items():
        if not segs:
            continue
        sel = np.flatnonzero((case == cs) & (centre == ctr))
        if len(sel) == 0:
            continue
        for e0, e1 in segs:
            src.append(edge_id(e0, ci[sel], cj[sel]))
            dst.append(edge_id(e1, ci[sel], cj[sel]))
    if not src:
        return []
    s = np.concatenate(src)
    t = np.concatenate(dst)

    # Crossing point on each used edge, by linear interpolation of d.
    used = np.unique(np.concatenate([s, t]))
    horiz = used < H
    hj, hi = np.divmod(used[horiz], nx - 1)
    vj, vi = np.divmod(used[~horiz] - H, nx)
    pts = np.empty((len(used), 2))
    a, b = v[hj, hi], v[hj, hi + 1]
    f = np.clip(a / np.where(a != b, a - b, 1.0), 0, 1)
    pts[horiz] = np.stack([xs[hi] + f * (xs[hi + 1] - xs[hi]), ys[hj]], axis=1)
    a, b = v[vj, vi], v[vj + 1, vi]
    f = np.clip(a / np.where(a != b, a - b, 1.0), 0, 1)
    pts[~horiz] = np.stack([xs[vi], ys[vj] + f * (ys[vj + 1] - ys[vj])], axis=1)

    s = np.searchsorted(used, s)
    t = np.searchsorted(used, t)
    succ = np.full(len(used), -1)
    succ[s] = t
    return [pts[idx] for idx in order_cycles(succ)]


def order_cycles(succ: np.ndarray) -> list[np.ndarray]:
    """Split a successor permutation into its cycles, each in traversal order.

    Vectorised list ranking (pointer doubling), so no Python loop runs over the vertices.
    Cycles come largest first.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(succ)
    ok = succ >= 0
    idx = np.arange(n)
    graph = coo_matrix((np.ones(ok.sum()), (idx[ok], succ[ok])), shape=(n, n)).tocsr()
    ncomp, label = connected_components(graph, directed=True, connection="weak")
    root = np.full(ncomp, n)
    np.minimum.at(root, label, idx)
    # Break each cycle before its root; then rank = steps to the end of the list.
    nxt = np.where(ok, succ, idx)
    tail = nxt == root[label]
    nxt = np.where(tail, idx, nxt)
    rank = np.where(nxt == idx, 0, 1)
    while True:
        jumped = nxt[nxt]
        if np.array_equal(jumped, nxt):
            break
        rank = rank + rank[nxt]
        nxt = jumped
    size = np.bincount(label, minlength=ncomp)
    pos = size[label] - 1 - rank
    order = np.lexsort((pos, label))
    starts = np.concatenate([[0], np.cumsum(size)])
    cycles = [order[starts[k] : starts[k + 1]] for k in range(ncomp)]
    cycles = [c for c in cycles if len(c) >= 3]
    cycles.sort(key=len, reverse=True)
    return cycles


def corner_brackets(loop: FloatArray, spacing: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sharp corners of a closed, projected boundary polyline (vertices of ``loop``, ``(c, 2)``)
    and the vertices on either side of each, ``(c, 2)`` twice, that bracket it along the
    boundary (for :func:`refine_corners`).

    The turning angle is measured over chords of about 3 and 6 grid spacings.  At a corner both
    chords see the same turn; on a smooth curve the longer chord sees twice the turn.  A vertex
    is a corner where the short-chord turn exceeds ``CORNER_ANGLE``, is at least 3/4 of the
    long-chord turn and is a local maximum.
    """
    n = len(loop)
    none = np.empty((0, 2))
    if n < 16:
        return none, none, none
    seg = np.hypot(*(np.roll(loop, -1, axis=0) - loop).T)
    k = max(2, int(round(3 * spacing / max(float(np.median(seg)), 1e-300))))
    if 4 * k >= n:
        return none, none, none
    idx = np.arange(n)

    def turn(m: int) -> FloatArray:
        u = loop - loop[(idx - m) % n]
        w = loop[(idx + m) % n] - loop
        return np.degrees(np.abs(np.arctan2(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0], np.sum(u * w, 1))))

    t1, t2 = turn(k), turn(2 * k)
    cand = (t1 > tol.CORNER_ANGLE) & (t1 >= 0.75 * t2)
    window = np.stack([np.roll(t1, s) for s in range(-k, k + 1)])
    peak = cand & (t1 >= window.max(axis=0))
    # Plateaus give several equal maxima: keep the first of each run.
    peak &= ~np.roll(peak, 1)
    i = np.flatnonzero(peak)
    if len(i) == 0:
        return none, none, none
    return loop[i], loop[(i - k) % n], loop[(i + k) % n]


def refine_corners(refine: Domain, a: FloatArray, b: FloatArray) -> FloatArray:
    """Corners located by bisection along the boundary of ``refine`` between boundary points
    ``a (c, 2)`` and ``b (c, 2)`` on either side of each: the half whose end has the closer
    gradient direction keeps that end, so the bracket closes on the jump of grad d.

    Every corner follows its own bisection (d is evaluated point by point), so the corners of
    all loops can be refined in one call, with the same results as one loop at a time and a
    fraction of the calls to d.
    """
    if len(a) == 0:
        return np.empty((0, 2))
    ga, gb = _unit(refine.gradient(a)), _unit(refine.gradient(b))
    for _ in range(50):
        m = refine.project(0.5 * (a + b))
        gm = _unit(refine.gradient(m))
        side_a = np.sum(gm * ga, axis=1) >= np.sum(gm * gb, axis=1)
        a = np.where(side_a[:, None], m, a)
        b = np.where(side_a[:, None], b, m)
    return refine.project(0.5 * (a + b))


def _unit(v: FloatArray) -> FloatArray:
    return v / np.maximum(np.hypot(*v.T), 1e-300)[:, None]
