"""The exact boundary of a set operation on boundary representations.

When every operand of a ``|``, ``&``, ``-`` expression is a :class:`~.brep.BRep` (a polygon,
rectangle, circle, or such a combination), the boundary of the result is computed once:

1. **Split.**  The operands' pieces (segments and arcs) are cut at their mutual intersections:
   crossings, tangent points, and every end point of one piece lying on another (which covers
   T-junctions, operands touching at a point, shared edges and collinear or co-circular
   overlaps).  Points closer than ``CSG_SNAP`` times the diameter are merged into one vertex.
2. **Classify.**  Each sub-piece is probed ``CSG_PROBE`` times the diameter to its left and right
   and the set operation is evaluated there from the operands' signs.  It is on the result's
   boundary when exactly one side is inside; it is turned so the inside is on its left.  Pieces
   of two operands that coincide (a shared edge kept by both) are kept once.
3. **Chain.**  The kept pieces are joined end to start into closed loops; where several leave
   one vertex (operands touching at a point) the sharpest left turn is taken, so each loop
   bounds one component.  Consecutive collinear segments (and co-circular arcs) are merged,
   except at a point the boundary passes more than once: where operands are tangent, the
   contact stays a vertex and :meth:`~.brep.BRep.cleaned` bridges the cusps there.

The result is a :class:`~.brep.BRep`, whose distance, projection and corners are exact.
"""

from __future__ import annotations

import logging
import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol
from .brep import BRep, _kernels

if TYPE_CHECKING:
    from .base import Domain, FloatArray

logger = logging.getLogger(__name__)


class EmptyResult(Exception):
    """The set operation leaves nothing: no piece of any operand bounds the result."""


def boolean_brep(expr: Domain) -> BRep | None:
    """The exact B-rep of a set operation whose leaves are all B-reps, or None when its
    boundary cannot be chained into loops (the caller keeps the min/max d).

    Raises
    ------
    EmptyResult
        No piece of any operand has the result on one side only: the result is empty (a
        bounded non-empty set has a boundary, made of pieces of its operands).  Its min/max d
        can still be zero along edges the operands share, which looked like a domain of zero
        width to the stages (found by fuzzing: a difference removing all of a rectangle with
        two sides in common).
    """
    from .csg import _Combination

    assert isinstance(expr, _Combination)
    leaves = expr.leaves()
    parts = [leaf._global_pieces() for leaf in leaves]  # type: ignore[attr-defined]
    p0 = np.concatenate([p[0] for p in parts])
    p1 = np.concatenate([p[1] for p in parts])
    cen = np.concatenate([p[2] for p in parts])
    sw = np.concatenate([p[3] for p in parts])
    owner = np.concatenate([np.full(len(p[0]), k) for k, p in enumerate(parts)])
    boxes = np.array([leaf.bbox for leaf in leaves])
    lo, hi = boxes[:, :2].min(axis=0), boxes[:, 2:].max(axis=0)
    origin = 0.5 * (lo + hi)
    scale = float(np.hypot(*(hi - lo)))
    snap = tol.CSG_SNAP * scale
    p0, p1, cen = p0 - origin, p1 - origin, cen - origin
    arc = sw != 0
    cen[~arc] = 0.0
    r = np.where(arc, np.hypot(*(p0 - cen).T), 0.0)
    a0 = np.where(arc, np.arctan2(p0[:, 1] - cen[:, 1], p0[:, 0] - cen[:, 0]), 0.0)
    p0, p1, cen = (np.ascontiguousarray(a) for a in (p0, p1, cen))

    # 1. split
    k = _kernels()
    plo, phi_ = k.piece_boxes(p0, p1, cen, r, a0, sw)
    tree = k.build_bvh(plo, phi_, k.LEAF)
    pairs = k.box_pairs(plo, phi_, *tree, snap)
    pairs = pairs[owner[pairs[:, 0]] < owner[pairs[:, 1]]]
    rec_k, rec_xy = k.split_points(np.ascontiguousarray(pairs), p0, p1, cen, r, a0, sw, snap)
    sub = _split(p0, p1, cen, r, a0, sw, rec_k, rec_xy, snap)
    s0, s1, sc, ssw, parent = sub

    # merge end points closer than snap into vertices
    v0, v1, verts = _snap_vertices(s0, s1, snap)
    keep = v0 != v1
    s0, s1, sc, ssw, parent, v0, v1 = (a[keep] for a in (s0, s1, sc, ssw, parent, v0, v1))
    s0, s1 = verts[v0], verts[v1]

    # 2. classify
    mid, normal = _midpoints(s0, s1, sc, ssw)
    probe = tol.CSG_PROBE * scale
    left = _member(expr, mid + probe * normal + origin)
    right = _member(expr, mid - probe * normal + origin)
    on = left != right
    if not on.any():
        raise EmptyResult
    flip = right & ~left
    s0, s1, sc, ssw, v0, v1, mid = (a[on] for a in (s0, s1, sc, ssw, v0, v1, mid))
    flip = flip[on]
    s0, s1 = np.where(flip[:, None], s1, s0), np.where(flip[:, None], s0, s1)
    v0, v1 = np.where(flip, v1, v0), np.where(flip, v0, v1)
    ssw = np.where(flip, -ssw, ssw)
    uniq = _dedupe(v0, v1, ssw, mid, snap)
    s0, s1, sc, ssw, v0, v1 = (a[uniq] for a in (s0, s1, sc, ssw, v0, v1))

    # 3. chain
    loops = _chain(s0, s1, sc, ssw, v0, v1)
    if loops is None:
        logger.warning("set operation %r: its boundary does not close into loops; using min/max", expr)
        return None
    order = np.concatenate(loops)
    loop_start = np.r_[0, np.cumsum([len(lp) for lp in loops])]
    # A vertex the boundary passes more than once (operands touching at a point, a circle
    # tangent to an edge) stays a vertex, so cleaning can find the cusps there
    # (BRep.cleaned): merged into a straight edge or an arc, the contact was no vertex.
    touch = np.bincount(v0, minlength=int(max(v0.max(), v1.max())) + 1) > 1
    b0, b1, bc, bsw, loop_start = _merge_straight(
        s0[order], s1[order], sc[order], ssw[order], loop_start, snap, touch[v0[order]]
    )
    out = BRep.__new__(BRep)
    out._set_local(b0, b1, bc, bsw, loop_start, origin)
    return out


def _split(p0, p1, cen, r, a0, sw, rec_k, rec_xy, snap):  # type: ignore[no-untyped-def]
    """Cut each piece at its recorded points: sub-pieces ``s0, s1, centre, sweep, parent``."""
    m = len(p0)
    arc = sw != 0
    # parameter of each record along its piece, in length units from the start
    rk = rec_k
    d = rec_xy - p0[rk]
    seg_len = np.hypot(*(p1 - p0).T)
    t_seg = np.einsum("ij,ij->i", d, p1[rk] - p0[rk]) / np.maximum(seg_len[rk], 1e-300)
    phi = np.arctan2(rec_xy[:, 1] - cen[rk, 1], rec_xy[:, 0] - cen[rk, 0])
    s = np.where(sw[rk] > 0, (phi - a0[rk]) % (2 * math.pi), (a0[rk] - phi) % (2 * math.pi))
    span = np.abs(sw[rk])
    # a point just before the start wraps to ~2 pi: bring it back to 0
    s = np.where(s > 0.5 * (span + 2 * math.pi), 0.0, np.minimum(s, span))
    t_arc = s * r[rk]
    t = np.where(arc[rk], t_arc, t_seg)
    length = np.where(arc, np.abs(sw) * r, seg_len)
    inner = (t > snap) & (t < length[rk] - snap)
    rk, t = rk[inner], t[inner]
    order = np.lexsort((t, rk))
    rk, t = rk[order], t[order]
    # drop repeats along a piece
    if len(rk):
        dup = np.r_[False, (rk[1:] == rk[:-1]) & (np.diff(t) <= snap)]
        rk, t = rk[~dup], t[~dup]
    counts = np.bincount(rk, minlength=m)
    n_sub = counts + 1
    parent = np.repeat(np.arange(m), n_sub)
    # cut parameters per sub-piece: start and end
    first = np.cumsum(n_sub) - n_sub
    tt_start = np.zeros(len(parent))
    tt_end = np.repeat(length, n_sub).astype(float)
    if len(rk):
        # index of each cut within its piece
        pos = np.arange(len(rk)) - np.repeat(np.cumsum(counts) - counts, counts)
        tt_end[first[rk] + pos] = t
        tt_start[first[rk] + pos + 1] = t
    par = parent
    a = arc[par]
    # points at parameters
    def at(tt: FloatArray) -> FloatArray:
        seg = p0[par] + (p1[par] - p0[par]) * (tt / np.maximum(seg_len[par], 1e-300))[:, None]
        ang = a0[par] + np.sign(sw[par]) * tt / np.where(a, r[par], 1.0)
        circ = cen[par] + r[par][:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        return np.where(a[:, None], circ, seg)

    s0, s1 = at(tt_start), at(tt_end)
    # exact original end points where a sub-piece starts or ends its parent
    is_first = tt_start == 0
    is_last = np.r_[par[1:] != par[:-1], True]
    s0[is_first] = p0[par[is_first]]
    s1[is_last] = p1[par[is_last]]
    ssw = np.where(a, np.sign(sw[par]) * (tt_end - tt_start) / np.where(a, r[par], 1.0), 0.0)
    return s0, s1, cen[par], ssw, par


def _snap_vertices(s0, s1, snap):  # type: ignore[no-untyped-def]
    """Vertex ids of the end points (points within ``snap`` merged, transitively) and the
    vertices' coordinates (each cluster's first point)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pts = np.concatenate([s0, s1])
    n = len(pts)
    pairs = cKDTree(pts).query_pairs(snap, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, n)
    np.minimum.at(first, label, np.arange(n))
    rep = first[label]
    # renumber to compact ids in order of first appearance
    ids, vid = np.unique(rep, return_inverse=True)
    verts = pts[ids]
    m = len(s0)
    return vid[:m], vid[m:], verts


def _midpoints(s0, s1, sc, ssw):  # type: ignore[no-untyped-def]
    """Midpoint of each sub-piece and the unit normal to its left."""
    arc = ssw != 0
    t = s1 - s0
    n_seg = np.stack([-t[:, 1], t[:, 0]], axis=1)
    m_seg = 0.5 * (s0 + s1)
    a_start = np.arctan2(s0[:, 1] - sc[:, 1], s0[:, 0] - sc[:, 0])
    rad = np.hypot(*(s0 - sc).T)
    ang = a_start + 0.5 * ssw
    u = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    m_arc = sc + rad[:, None] * u
    n_arc = -u * np.sign(ssw)[:, None]  # counter-clockwise: the centre is on the left
    mid = np.where(arc[:, None], m_arc, m_seg)
    nrm = np.where(arc[:, None], n_arc, n_seg)
    return mid, nrm / np.maximum(np.hypot(*nrm.T), 1e-300)[:, None]


def _member(expr: Domain, p: FloatArray) -> NDArray[np.bool_]:
    """Whether each point is in the set ``expr``, from the signs of its leaves."""
    from .csg import Difference, Intersection, Union, _Combination

    if not isinstance(expr, _Combination):
        return expr.sdf(p) < 0
    a, b = _member(expr.a, p), _member(expr.b, p)
    if isinstance(expr, Union):
        return a | b
    if isinstance(expr, Intersection):
        return a & b
    assert isinstance(expr, Difference)
    return a & ~b


def _dedupe(v0, v1, ssw, mid, snap):  # type: ignore[no-untyped-def]
    """Indices of the pieces to keep: one of each set of coincident pieces (same end vertices
    and same midpoint)."""
    order = np.lexsort((v1, v0))
    keep = np.ones(len(v0), dtype=bool)
    same = (v0[order][1:] == v0[order][:-1]) & (v1[order][1:] == v1[order][:-1])
    for j in np.flatnonzero(same):
        a, b = order[j], order[j + 1]
        if np.hypot(*(mid[a] - mid[b])) <= 10 * snap:
            keep[b] = False
    return np.flatnonzero(keep)


def _chain(s0, s1, sc, ssw, v0, v1):  # type: ignore[no-untyped-def]
    """Join pieces end to start into loops (lists of piece indices), or None if they do not
    close."""
    n = len(v0)
    out_of: dict[int, list[int]] = {}
    for i in range(n):
        out_of.setdefault(int(v0[i]), []).append(i)
    t_start = _tangent(s0, s1, sc, ssw, at_end=False)
    t_end = _tangent(s0, s1, sc, ssw, at_end=True)
    used = np.zeros(n, dtype=bool)
    loops = []
    for first in range(n):
        if used[first]:
            continue
        loop = [first]
        used[first] = True
        cur = first
        while True:
            v = int(v1[cur])
            cands = [j for j in out_of.get(v, []) if not used[j]]
            if v == int(v0[first]) and (not cands or _closes_here(first, cands, t_end[cur], t_start)):
                break
            if not cands:
                return None
            if len(cands) > 1:
                # The sharpest left turn: first outgoing direction clockwise from the reversed
                # incoming one (keeps components that touch at a point in separate loops).
                back = math.atan2(-t_end[cur][1], -t_end[cur][0])
                cw = [(back - math.atan2(t_start[j][1], t_start[j][0])) % (2 * math.pi) for j in cands]
                cw = [c if c > 1e-9 else 2 * math.pi for c in cw]
                nxt = cands[int(np.argmin(cw))]
            else:
                nxt = cands[0]
            used[nxt] = True
            loop.append(nxt)
            cur = nxt
            if len(loop) > n:
                return None
        loops.append(np.array(loop, dtype=np.intp))
    return loops


def _closes_here(first: int, cands: list[int], t_in: FloatArray, t_start: FloatArray) -> bool:
    """At the loop's start vertex with other pieces leaving too: close the loop when the loop's
    first piece is the sharpest left turn among them."""
    back = math.atan2(-t_in[1], -t_in[0])

    def cw(j: int) -> float:
        c = (back - math.atan2(t_start[j][1], t_start[j][0])) % (2 * math.pi)
        return c if c > 1e-9 else 2 * math.pi

    return cw(first) <= min(cw(j) for j in cands)


def _tangent(s0, s1, sc, ssw, at_end):  # type: ignore[no-untyped-def]
    q = s1 if at_end else s0
    v = q - sc
    arc_t = np.stack([-v[:, 1], v[:, 0]], axis=1) * np.sign(ssw)[:, None]
    t = np.where((ssw != 0)[:, None], arc_t, s1 - s0)
    return t / np.maximum(np.hypot(*t.T), 1e-300)[:, None]


def _merge_straight(s0, s1, sc, ssw, loop_start, snap, keep):  # type: ignore[no-untyped-def]
    """Merge consecutive collinear segments and consecutive arcs of one circle, except into a
    piece that starts at a vertex ``keep`` marks."""
    out0, out1, outc, outsw, starts = [], [], [], [], [0]
    for k in range(len(loop_start) - 1):
        idx = list(range(loop_start[k], loop_start[k + 1]))
        pieces = [[s0[i].copy(), s1[i].copy(), sc[i].copy(), float(ssw[i]), bool(keep[i])] for i in idx]
        merged = True
        while merged and len(pieces) > 2:
            merged = False
            for j in range(len(pieces)):
                a, b = pieces[j], pieces[(j + 1) % len(pieces)]
                if not b[4] and _joinable(a, b, snap):
                    a[1] = b[1]
                    a[3] = a[3] + b[3]
                    del pieces[(j + 1) % len(pieces)]
                    merged = True
                    break
        for a in pieces:
            out0.append(a[0])
            out1.append(a[1])
            outc.append(a[2])
            outsw.append(a[3])
        starts.append(starts[-1] + len(pieces))
    return np.array(out0), np.array(out1), np.array(outc), np.array(outsw), np.array(starts)


def _joinable(a: list, b: list, snap: float) -> bool:  # type: ignore[type-arg]
    if (a[3] == 0) != (b[3] == 0):
        return False
    if a[3] == 0:
        u, w = a[1] - a[0], b[1] - b[0]
        if float(np.dot(u, w)) <= 0:
            return False
        chord = b[1] - a[0]
        length = float(np.hypot(*chord))
        if length == 0:
            return False
        # the shared vertex lies on the line through the outer end points
        off = abs(float(chord[0] * (a[1][1] - a[0][1]) - chord[1] * (a[1][0] - a[0][0]))) / length
        return off <= snap
    same_circle = float(np.hypot(*(a[2] - b[2]))) <= snap
    same_way = (a[3] > 0) == (b[3] > 0)
    return same_circle and same_way and abs(a[3] + b[3]) < 2 * math.pi - 1e-9
