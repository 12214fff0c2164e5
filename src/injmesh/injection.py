"""Step 2 of Algorithm 1: Advancing Node Injection (paper Section 3.1, Algorithm 4).

Interior nodes are injected layer by layer from the boundary front inwards; no triangulation is
built.  The front is a set of *chains*: polylines of nodes with the unmeshed region on their left
(the boundary loops to begin with).  One layer does, for all chains at once:

1. **Inject.**  Every front edge e gives the apex of the equilateral triangle on its inner side:
   its midpoint moved by ``sqrt(3)/2 * h`` along the inward normal, h taken at the apex.  At a
   front vertex whose interior angle theta exceeds 180 degrees the two apexes drift apart, so
   ``m = round((theta - 120) / 60) - 1`` more points are injected on the arc of radius h around
   the vertex (the paper's "angles between e_i and the previous and the next edges").  At convex
   vertices the apexes draw together and the next step merges them.
2. **Space along the front.**  The injected points of a chain, in order, form the new chain.  It
   is re-laid at equal h-length, ``round(int ds / h)`` segments (closed chains keep at least
   three; a closed chain shorter than 2.5 h collapses to its centroid).  A straight front with
   constant h is left exactly as injected (the staggered, equilateral layout).
3. **Merge fronts.**  A new point is rejected when it is outside the domain (``d > 0``), or
   closer than ``MERGE * h`` to any existing node (earlier layers, other fronts, the boundary), or
   to a lower-numbered point of the same layer.  This is how fronts that meet — across a narrow
   part, around holes, at re-entrant corners, where h changes fast — stop without clusters;
   gaps left are below about ``(MERGE + sqrt(3)/2) h`` wide and smoothing closes them.
4. **Advance.**  The surviving runs of consecutive points are the next front.

The proximity tests of step 3 run on a background grid of about h_min cells that every
admitted node is inserted into as it is admitted (:mod:`injmesh.kernels.inject`): nothing is
rebuilt per layer, so the whole injection is linear in the number of nodes.  The wall test
measures the exact distance to the boundary segments of Step 1 listed in the nearby cells.

*Stopping condition*: a layer in which no point survives (the front is exhausted), or
``diameter / (sqrt(3)/2 * h_min) + 10`` layers.

h is asked only at points inside the domain or on its boundary: a candidate beyond the boundary
(an apex past the opposite wall, the midpoint of a chord across a notch) takes h at its
projection onto the boundary.  DistMesh users write h that is meaningless, even negative,
outside the domain.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .boundary import BoundaryMesh
from .errors import NodeBudgetError
from .geometry import Domain
from .progress import Callback, report

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]
SizeFn = Callable[[FloatArray], FloatArray]

#: Layer height as a fraction of h: the height of the equilateral triangle.
HEIGHT = np.sqrt(3.0) / 2.0
#: A new node closer than MERGE * h to an existing one is not injected.
MERGE = 0.6
#: A new node closer than CLEARANCE * h to a boundary segment is not injected.
CLEARANCE = 0.5
#: Most cells of the proximity grid (16 MiB of list heads).
MAX_CELLS = 1 << 21
#: Angle (degrees) between injected points on the arc around a reflex front vertex.
FAN_STEP = 60.0


class Front:
    """Chains of front nodes, stored contiguously.

    ``points[i]`` is followed by ``points[i + 1]`` within a chain; ``start[c]:start[c + 1]`` is
    chain c, ``closed[c]`` says whether its last node joins its first.
    """

    def __init__(self, points: FloatArray, lengths: IntArray, closed: BoolArray) -> None:
        self.points = points
        self.lengths = lengths
        self.closed = closed
        self.start = np.concatenate([[0], np.cumsum(lengths)])
        self.chain = np.repeat(np.arange(len(lengths)), lengths)

    def __len__(self) -> int:
        return len(self.points)

    def successor(self) -> IntArray:
        """Index of the next node in its chain, or -1 at the end of an open chain."""
        idx = np.arange(len(self.points))
        last = self.start[1:][self.chain] - 1
        first = self.start[:-1][self.chain]
        wrap = np.where(self.closed[self.chain], first, -1)
        return np.where(idx == last, wrap, idx + 1)


def inject_nodes(
    domain: Domain,
    h: SizeFn,
    boundary: BoundaryMesh,
    existing: FloatArray,
    *,
    max_nodes: int,
    callback: Callback | None = None,
) -> FloatArray:
    """Inject interior nodes by advancing fronts from the boundary (Algorithm 4).

    Parameters
    ----------
    domain : Domain
    h : callable
        Validated size function.
    boundary : BoundaryMesh
        Step 1's result; its loops are the initial front.
    existing : (k, 2) array
        Nodes already placed (boundary nodes and user fixed points); new nodes keep clear of them.
    max_nodes : int
        Node budget.

    Returns
    -------
    (n, 2) array
        The injected nodes only, in injection order.
    """
    counts = np.bincount(boundary.node_loop)
    front = Front(boundary.points, counts, np.ones(len(counts), dtype=bool))
    placed = [existing]
    n_placed = len(existing)
    h_bnd = h(boundary.points)
    h_min = float(h_bnd.min())
    h_existing = np.concatenate([h_bnd, h(existing[len(boundary.points):])]) if _starts_with(
        existing, boundary.points) else h(existing)
    grid = _Proximity(domain, boundary, existing, h_existing, h_min)
    max_layers = int(domain.diameter / (HEIGHT * h_min)) + 10

    for layer in range(1, max_layers + 1):
        cand = _inject(front, domain, h)
        cand = _respace(cand, domain, h)
        keep = _admissible(domain, h, cand.points, grid)
        if not keep.any():
            break
        front = _survivors(cand, keep)
        placed.append(front.points)
        n_placed += len(front.points)
        if n_placed > max_nodes:
            raise NodeBudgetError(f"node injection passed max_nodes={max_nodes} (layer {layer})")
        report(callback, "injection", layer, max_layers, nodes=n_placed, front=len(front))
        front = _drop_isolated(front)
        if len(front) == 0:
            break
    # The layer count is not known in advance: close the progress at 100 %.
    report(callback, "injection", max_layers, max_layers, nodes=n_placed, front=0)
    return np.concatenate(placed[1:]) if len(placed) > 1 else np.empty((0, 2))


def _starts_with(a: FloatArray, b: FloatArray) -> bool:
    """Whether the rows of ``b`` are the first rows of ``a`` (the boundary nodes among the seeds)."""
    return len(a) >= len(b) and np.array_equal(a[: len(b)], b)


def _h_inside(domain: Domain, h: SizeFn, q: FloatArray) -> FloatArray:
    """h at ``q``, taken at the boundary projection for points outside the domain."""
    out = domain.sdf(q) > 0
    if out.any():
        q = q.copy()
        q[out] = domain.project(q[out])
    return h(q)


def _inject(front: Front, domain: Domain, h: SizeFn) -> Front:
    """Apexes of the front edges plus arc points at reflex vertices, as new chains."""
    p = front.points
    nxt = front.successor()
    has_edge = nxt >= 0
    e0 = np.flatnonzero(has_edge)
    a, b = p[e0], p[nxt[e0]]
    t = b - a
    length = np.maximum(np.hypot(*t.T), 1e-300)
    t = t / length[:, None]
    normal = np.stack([-t[:, 1], t[:, 0]], axis=1)  # left of the edge: the unmeshed side
    mid = 0.5 * (a + b)
    hm = _h_inside(domain, h, mid)
    apex = mid + HEIGHT * hm[:, None] * normal
    # Re-evaluate h at the apex so layers thin out or thicken with h.
    ha = 0.5 * (hm + _h_inside(domain, h, apex))
    apex = mid + HEIGHT * ha[:, None] * normal

    # Reflex vertices: a node with both an incoming and an outgoing edge.
    edge_of = np.full(len(p), -1)
    edge_of[e0] = np.arange(len(e0))  # outgoing edge of node i
    incoming = np.full(len(p), -1)
    incoming[nxt[e0]] = np.arange(len(e0))
    v = np.flatnonzero((edge_of >= 0) & (incoming >= 0))
    t_in, t_out = t[incoming[v]], t[edge_of[v]]
    # Interior angle on the left: 180 minus the signed turn from t_in to t_out.
    turn = np.degrees(np.arctan2(t_in[:, 0] * t_out[:, 1] - t_in[:, 1] * t_out[:, 0],
                                 np.sum(t_in * t_out, axis=1)))
    theta = 180.0 - turn
    m = np.maximum(np.floor((theta - 120.0) / FAN_STEP + 0.5).astype(int) - 1, 0)
    fan_v = np.repeat(v, m)
    fan_k = np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m) + 1
    # Arc from the incoming apex direction (normal of e_in rotated back by 30 degrees) to the
    # outgoing one, through the interior, in m + 1 equal steps.
    n_in = normal[incoming[fan_v]]
    start_ang = np.arctan2(n_in[:, 1], n_in[:, 0]) + np.radians(30.0)
    sweep = np.radians(np.repeat(theta, m) - 120.0)
    ang = start_ang - fan_k / (np.repeat(m, m) + 1) * sweep
    hv = h(p[fan_v])
    fan = p[fan_v] + hv[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)

    # Order: for node i of a chain, its fan points (key i, then k) then its outgoing apex.
    key_apex = e0.astype(float) + 0.999
    key_fan = fan_v + fan_k / (m.max() + 2 if len(m) else 2)
    keys = np.concatenate([key_apex, key_fan])
    pts = np.concatenate([apex, fan])
    chain = front.chain[np.concatenate([e0, fan_v])]
    order = np.lexsort((keys, chain))
    pts, chain = pts[order], chain[order]
    lengths = np.bincount(chain, minlength=len(front.lengths))
    return Front(pts, lengths, front.closed.copy())


def _respace(front: Front, domain: Domain, h: SizeFn) -> Front:
    """Re-lay every chain at equal h-length, ``round(S)`` segments (Step 2 of the module doc)."""
    front = _drop_empty(front)
    if len(front) == 0:
        return front
    p = front.points
    n_chain = len(front.lengths)
    # Polyline per chain with the closing vertex repeated for closed chains.
    close = front.closed & (front.lengths > 0)
    last = front.start[1:] - 1
    rep_idx = np.concatenate([np.arange(len(p)), front.start[:-1][close]])
    rep_key = np.concatenate([np.arange(len(p), dtype=float), last[close] + 0.5])
    order = np.argsort(rep_key, kind="stable")
    poly = p[rep_idx[order]]
    pchain = np.concatenate([front.chain, np.flatnonzero(close)])[order]
    same = pchain[1:] == pchain[:-1]
    seg = poly[1:] - poly[:-1]
    ds = np.where(same, np.hypot(*seg.T) / _h_inside(domain, h, 0.5 * (poly[1:] + poly[:-1])), 0.0)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    pstart = np.flatnonzero(np.r_[True, ~same])
    pend = np.r_[pstart[1:], len(poly)] - 1
    total = s[pend] - s[pstart]

    closed = front.closed
    count = np.where(closed, np.rint(total), np.rint(total) + 1).astype(int)
    count = np.maximum(count, 1)
    collapse = closed & (total < 2.5)
    count = np.where(collapse, 1, np.where(closed, np.maximum(count, 3), count))
    count[front.lengths == 0] = 0
    # Offsets make one global, strictly increasing abscissa over all chains.
    offset = np.cumsum(np.r_[0.0, total[:-1] + 1.0])
    gs = s - s[pstart][pchain] + offset[pchain]
    piece = np.repeat(np.arange(n_chain), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    denom = np.where(closed, count, np.maximum(count - 1, 1))[piece]
    target = offset[piece] + k * total[piece] / denom
    out = np.stack([np.interp(target, gs, poly[:, 0]), np.interp(target, gs, poly[:, 1])], axis=1)
    if collapse.any():
        cen = np.zeros((n_chain, 2))
        np.add.at(cen, front.chain, p)
        cen /= np.maximum(front.lengths, 1)[:, None]
        sel = collapse[piece]
        out[sel] = cen[piece[sel]]
    closed_out = closed & ~collapse
    return Front(out, count, closed_out)


class _Proximity:
    """The nodes placed so far and the boundary segments, on a background grid (compiled).

    Cells are about the smallest boundary h wide (at most ``MAX_CELLS`` of them over the
    domain's box, so a tiny h in a large box makes cells coarser, not the grid huge).  Nodes
    are inserted layer by layer into per-cell lists, never rebuilt; see
    :mod:`injmesh.kernels.inject`.  Each node keeps the h it was admitted with, so the merge
    test needs no further evaluation of h.
    """

    def __init__(self, domain: Domain, boundary: BoundaryMesh, existing: FloatArray,
                 h_existing: FloatArray, h_min: float) -> None:
        from .kernels import inject as kern

        self.kern = kern
        x0, y0, x1, y1 = (float(v) for v in domain.bbox)
        lo = np.minimum([x0, y0], existing.min(axis=0)) if len(existing) else np.array([x0, y0])
        hi = np.maximum([x1, y1], existing.max(axis=0)) if len(existing) else np.array([x1, y1])
        w, ht = float(hi[0] - lo[0]), float(hi[1] - lo[1])
        cell = max(h_min, math.sqrt(max(w * ht, 0.0) / MAX_CELLS), 1e-12 * max(w, ht, 1e-300))
        self.cell = cell
        self.nx = int(w / cell) + 1
        self.ny = int(ht / cell) + 1
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.head = np.full(self.nx * self.ny, -1, dtype=np.int64)
        cap = max(1024, 2 * len(existing))
        self.pts = np.empty((cap, 2))
        self.hs = np.empty(cap)
        self.link = np.empty(cap, dtype=np.int64)
        self.n = len(existing)
        self.pts[: self.n] = existing
        self.hs[: self.n] = h_existing
        self.h_max = float(h_existing.max()) if len(existing) else 0.0
        kern.insert(self.pts, 0, self.n, self.head, self.link, self.x0, self.y0, 1.0 / cell,
                    self.nx, self.ny)
        e = boundary.edges
        self.seg_a = np.ascontiguousarray(boundary.points[e[:, 0]])
        self.seg_b = np.ascontiguousarray(boundary.points[e[:, 1]])
        self.rows, self.items = kern.segment_lists(self.seg_a, self.seg_b, self.x0, self.y0, cell,
                                                   self.nx, self.ny)

    def admit(self, q: FloatArray, hq: FloatArray, inside: BoolArray) -> BoolArray:
        """Which candidates survive (Step 3 of the module doc); the survivors are inserted."""
        need = self.n + len(q)
        if need > len(self.pts):
            cap = max(need, 2 * len(self.pts))
            self.pts = np.concatenate([self.pts[: self.n], np.empty((cap - self.n, 2))])
            self.hs = np.concatenate([self.hs[: self.n], np.empty(cap - self.n)])
            self.link = np.concatenate([self.link[: self.n], np.empty(cap - self.n, dtype=np.int64)])
        keep = inside.copy()
        self.n = int(self.kern.admit(
            np.ascontiguousarray(q), hq, keep, MERGE, CLEARANCE, self.pts, self.hs, self.n,
            self.h_max, self.head, self.link, self.seg_a, self.seg_b, self.rows, self.items,
            self.x0, self.y0, self.cell, self.nx, self.ny,
        ))
        if keep.any():
            self.h_max = max(self.h_max, float(hq[keep].max()))
        return keep


def _admissible(domain: Domain, h: SizeFn, q: FloatArray, grid: _Proximity) -> BoolArray:
    """Points inside, clear of the boundary, of existing nodes and of lower-numbered new points."""
    if len(q) == 0:
        return np.zeros(0, dtype=bool)
    inside = domain.sdf(q) < 0
    hq = np.ones(len(q))
    if inside.any():
        hq[inside] = h(q[inside])
    return grid.admit(q, hq, inside)


def _survivors(front: Front, keep: BoolArray) -> Front:
    """Runs of consecutive kept points become the next chains."""
    n = len(front)
    idx = np.arange(n)
    chain = front.chain
    first = front.start[:-1][chain]
    # Rotate closed chains with a gap so that no run wraps around the chain's start.
    removed_any = np.zeros(len(front.lengths), dtype=bool)
    np.logical_or.at(removed_any, chain, ~keep)
    rot = np.zeros(len(front.lengths), dtype=int)
    gap = front.closed & removed_any & (front.lengths > 0)
    if gap.any():
        # Rotate so the chain starts right after its first removed point.
        first_removed = np.full(len(front.lengths), n)
        np.minimum.at(first_removed, chain[~keep], idx[~keep])
        rot[gap] = first_removed[gap] - front.start[:-1][gap] + 1
    L = front.lengths[chain]
    pos = (idx - first - rot[chain]) % np.maximum(L, 1)
    order = np.lexsort((pos, chain))
    pts, kp, ch = front.points[order], keep[order], chain[order]
    stays_closed = front.closed & ~removed_any
    # A run starts at a kept point whose predecessor (same chain) is not kept.
    prev_kept = np.r_[False, kp[:-1] & (ch[1:] == ch[:-1])]
    run_start = kp & ~prev_kept
    run_id = np.cumsum(run_start) - 1
    pts, run_id = pts[kp], run_id[kp]
    lengths = np.bincount(run_id) if len(run_id) else np.zeros(0, dtype=int)
    run_chain = ch[kp][np.r_[0, np.cumsum(lengths)[:-1]]] if len(lengths) else np.zeros(0, int)
    closed = stays_closed[run_chain] if len(lengths) else np.zeros(0, dtype=bool)
    return Front(pts, lengths, closed)


def _drop_empty(front: Front) -> Front:
    return _keep_chains(front, front.lengths >= 1)


def _drop_isolated(front: Front) -> Front:
    """Chains of a single node have no edge to inject from."""
    return _keep_chains(front, front.lengths >= 2)


def _keep_chains(front: Front, ok: BoolArray) -> Front:
    """The front restricted to the chains flagged ``ok``."""
    if ok.all():
        return front
    sel = ok[front.chain]
    return Front(front.points[sel], front.lengths[ok], front.closed[ok])
