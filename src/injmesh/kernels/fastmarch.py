"""Fast marching for the gradient limiter of Persson (2006).

Solves, on a uniform grid, the steady Hamilton-Jacobi problem of "Mesh size functions for
implicit geometries and PDE-based gradient limiting" (P.-O. Persson, Eng. Comput. 22, 2006),

    dh/dt + min(|grad h|, g) - g = 0,   h(t=0) = h0,                        (Persson, eq. 9)

whose steady state is the largest h <= h0 with |grad h| <= g.  It is the eikonal equation
|grad h| = g wherever h < h0, solved here exactly on the grid by Sethian's fast marching with the
first-order Godunov upwind stencil (Persson, eq. 11): nodes are accepted in increasing order of
h, and each accepted node lowers its neighbours to the eikonal update when that is below their
h0.  Every node is a potential source (its value starts at h0); only the nodes that get lowered
pass through the heap, so the cost is one O(N) pass plus O(M log M) for the M lowered nodes.

On the output every node satisfies the discrete limit

    (max(h - h_W, h - h_E, 0) / dx)^2 + (max(h - h_S, h - h_N, 0) / dy)^2 <= g^2,

hence |h_E - h| <= g dx along every grid edge; and h == h0 wherever h0 already satisfies it.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _less(key_a: float, node_a: int, key_b: float, node_b: int) -> bool:
    # Ties broken by node number: the acceptance order, hence the output, is deterministic.
    return key_a < key_b or (key_a == key_b and node_a < node_b)


#: Children per node of the heap.  The order in which nodes are accepted is the order of
#: (key, node number), whatever the heap's shape: a wider heap only makes fewer, more local
#: moves (the keys are kept in the heap itself, beside the nodes, for the same reason).
ARITY = 4


@numba.njit(cache=True)
def _sift_up(hkey: np.ndarray, hnode: np.ndarray, pos: np.ndarray, k: int) -> None:
    key = hkey[k]
    node = hnode[k]
    while k > 0:
        parent = (k - 1) // ARITY
        if not _less(key, node, hkey[parent], hnode[parent]):
            break
        hkey[k] = hkey[parent]
        hnode[k] = hnode[parent]
        pos[hnode[k]] = k
        k = parent
    hkey[k] = key
    hnode[k] = node
    pos[node] = k


@numba.njit(cache=True)
def _sift_down(hkey: np.ndarray, hnode: np.ndarray, pos: np.ndarray, k: int, size: int) -> None:
    key = hkey[k]
    node = hnode[k]
    while True:
        first = ARITY * k + 1
        if first >= size:
            break
        child = first
        ckey = hkey[first]
        cnode = hnode[first]
        for c in range(first + 1, min(first + ARITY, size)):
            if _less(hkey[c], hnode[c], ckey, cnode):
                child = c
                ckey = hkey[c]
                cnode = hnode[c]
        if not _less(ckey, cnode, key, node):
            break
        hkey[k] = ckey
        hnode[k] = cnode
        pos[cnode] = k
        k = child
    hkey[k] = key
    hnode[k] = node
    pos[node] = k


@numba.njit(cache=True, inline="always")
def _update(a: float, b: float, gx: float, gy: float) -> float:
    """The eikonal update from the smallest accepted x-neighbour ``a`` and y-neighbour ``b``.

    Solves ((u - a) / gx)^2 + ((u - b) / gy)^2 = 1 for u >= max(a, b) with gx = g dx and
    gy = g dy, or the one-sided update min(a + gx, b + gy) when only one neighbour is upwind.
    Infinite neighbours (not accepted yet) drop out.
    """
    u = min(a + gx, b + gy)
    hi = max(a, b)
    if u <= hi:
        return u
    # Both upwind.  Solve in coordinates relative to the lower neighbour (no cancellation).
    lo = min(a, b)
    da = (a - lo) / gx
    db = (b - lo) / gy
    ax = 1.0 / gx
    by = 1.0 / gy
    # (ax v - da)^2 + (by v - db)^2 = 1 for v = u - lo.
    qa = ax * ax + by * by
    qb = -2.0 * (ax * da + by * db)
    qc = da * da + db * db - 1.0
    disc = qb * qb - 4.0 * qa * qc
    if disc < 0.0:
        return u
    v = (-qb + np.sqrt(disc)) / (2.0 * qa)
    return min(lo + v, u)


@numba.njit(cache=True, inline="always")
def _known_pair(key: np.ndarray, pos: np.ndarray, nb: int, nx: int, ny: int) -> tuple[float, float]:
    """The smallest x-neighbour and y-neighbour of node ``nb`` that are not tentative (in the
    heap); ``inf`` where there is none."""
    bj = nb // nx
    bi = nb - bj * nx
    a = np.inf
    if bi > 0 and pos[nb - 1] < 0:
        a = key[nb - 1]
    if bi < nx - 1 and pos[nb + 1] < 0:
        a = min(a, key[nb + 1])
    b = np.inf
    if bj > 0 and pos[nb - nx] < 0:
        b = key[nb - nx]
    if bj < ny - 1 and pos[nb + nx] < 0:
        b = min(b, key[nb + nx])
    return a, b


@numba.njit(cache=True, inline="always")
def _known_update(key: np.ndarray, pos: np.ndarray, nb: int, nx: int, ny: int, gx: float, gy: float) -> float:
    """The eikonal update of node ``nb`` from its neighbours that are not tentative (in the heap)."""
    a, b = _known_pair(key, pos, nb, nx, ny)
    return _update(a, b, gx, gy)


#: :func:`_not_below` trusts its test when ``F(c) <= g^2 (1 - NOT_BELOW)`` and ``g > NOT_BELOW_G * c``.
NOT_BELOW = 1e-9
NOT_BELOW_G = 1e-4


@numba.njit(cache=True, inline="always")
def _not_below(a: float, b: float, c: float, gx: float, gy: float) -> bool:
    """True only if ``_update(a, b, gx, gy) >= c`` (computed as it computes it): a test with no
    division or square root, for the first pass of :func:`limit_gradient`, where nearly every
    node of a size that needs no limiting keeps its value.  False means "compute it".

    With ``u1 = min(a + gx, b + gy)`` (the one-sided update, computed as ``_update`` does):
    if ``u1 < c`` nothing is claimed.  If ``u1 <= max(a, b)``, ``_update`` returns u1 itself.
    Otherwise it returns ``min(lo + v, u1)`` with ``lo + v`` the computed root U >= max(a, b)
    of ``F(u) = (u - a)^2 + (u - b)^2 = g^2`` (here ``gx == gy == g``; the test is left out
    otherwise).  For ``c >= max(a, b)``, F is convex and increasing on ``[c, U]`` with
    ``F'(U) = 2 ((U - a) + (U - b)) <= 2 sqrt(2) g``, so ``F(c) <= g^2 (1 - eps)`` gives
    ``U - c >= eps g / (2 sqrt 2)``: 3.5e-10 g with eps = NOT_BELOW (less the few ulps of the
    computed F).  In this branch ``0 <= |a - b| < g``, the discriminant is at least ``4 / g^2``
    and ``v = (g / 2) (d + sqrt(2 - d^2))``, d in [0, 1), is computed within about 12 ulps of
    g; ``lo + v`` adds an ulp of c.  With ``g > NOT_BELOW_G * c`` these errors (below
    3e-15 g + 3e-16 c < 1e-11 g) are far inside the margin, so the computed ``lo + v`` is
    above c too.
    """
    if not (gx == gy and c < np.inf):
        return False
    u1 = min(a + gx, b + gy)
    if not u1 >= c:
        return False
    hi = max(a, b)
    if u1 <= hi:
        return True
    if not (c >= hi and gx > NOT_BELOW_G * c):
        return False
    f = (c - a) * (c - a) + (c - b) * (c - b)
    return f <= gx * gx * (1.0 - NOT_BELOW)


@numba.njit(cache=True)
def limit_gradient(h0: np.ndarray, dx: float, dy: float, rate: float) -> np.ndarray:
    """The largest ``h <= h0`` on the grid with upwind |grad h| <= ``rate`` (see module docstring).

    Only nodes that get lowered ever enter the heap: a first pass finds the nodes whose h0
    exceeds the update from their neighbours' h0 (most nodes are settled by :func:`_not_below`,
    without the update's divisions and square root), and marching spreads from them.  A node never
    lowered keeps its h0, which is final; updates read every neighbour that is not tentative
    (accepted, or untouched at its h0, an upper bound until it is lowered and accepted itself,
    which triggers a new update).  A smooth h0 that nearly satisfies the limit costs one pass.

    Parameters
    ----------
    h0 : (ny, nx) float64
        Target sizes; ``inf`` at nodes that impose nothing (they take the limited value).
    dx, dy : float
        Grid spacings along x (axis 1) and y (axis 0).
    rate : float
        The limit g on |grad h|.
    """
    ny, nx = h0.shape
    n = ny * nx
    flat0 = np.ascontiguousarray(h0).ravel()
    key = flat0.copy()
    # The heap of tentative nodes, with their keys beside them.
    hnode = np.empty(n, dtype=np.int64)
    hkey = np.empty(n)
    pos = np.full(n, -1, dtype=np.int64)  # place in the heap, -1 when not tentative
    gx = rate * dx
    gy = rate * dy
    size = 0
    for node in range(n):
        # Most nodes of a size that needs no limiting keep it: a cheap test first.
        a, b = _known_pair(flat0, pos, node, nx, ny)
        if _not_below(a, b, key[node], gx, gy):
            continue
        u = _update(a, b, gx, gy)
        if u < key[node]:
            key[node] = u
            hnode[size] = node
            hkey[size] = u
            pos[node] = size
            size += 1
    for k in range((size - 2) // ARITY, -1, -1):
        _sift_down(hkey, hnode, pos, k, size)
    while size > 0:
        node = hnode[0]
        size -= 1
        pos[node] = -1
        if size > 0:
            hnode[0] = hnode[size]
            hkey[0] = hkey[size]
            pos[hnode[0]] = 0
            _sift_down(hkey, hnode, pos, 0, size)
        j = node // nx
        i = node - j * nx
        for m in range(4):
            if m == 0:
                if i == 0:
                    continue
                nb = node - 1
            elif m == 1:
                if i == nx - 1:
                    continue
                nb = node + 1
            elif m == 2:
                if j == 0:
                    continue
                nb = node - nx
            else:
                if j == ny - 1:
                    continue
                nb = node + nx
            if key[nb] <= key[node]:
                continue  # accepted already, or never lowered below this level
            u = _known_update(key, pos, nb, nx, ny, gx, gy)
            if u < key[nb]:
                key[nb] = u
                if pos[nb] < 0:
                    hnode[size] = nb
                    pos[nb] = size
                    size += 1
                hkey[pos[nb]] = u
                _sift_up(hkey, hnode, pos, pos[nb])
    return key.reshape(ny, nx)
