"""Adaptive-precision exact geometric predicates: ``orient2d`` and ``incircle``.

After J. R. Shewchuk, "Adaptive Precision Floating-Point Arithmetic and Fast Robust Geometric
Predicates", Discrete & Computational Geometry 18 (1997).  Each predicate first evaluates its
determinant in ordinary floating point and accepts the result when its magnitude exceeds
Shewchuk's a-priori error bound (the filter: almost every call ends there).  Otherwise it
recomputes the determinant *exactly* as a floating-point expansion -- a sum of non-overlapping
doubles built with error-free transformations (``two_sum``, ``two_product`` by Dekker's split)
-- whose largest component carries the exact sign.  The exact stage has two levels: when the
coordinate differences are themselves exact (the usual case: nearby points, lattices) the
expansions stay a few terms long; otherwise the differences are carried as two-term expansions.

The returned float has the exact sign of the determinant; its magnitude is only an estimate.

* ``orient2d(a, b, c) > 0``: a, b, c are counter-clockwise; ``< 0`` clockwise; ``0`` collinear.
* ``incircle(a, b, c, d) > 0``: d lies strictly inside the circle through a, b, c (which must be
  counter-clockwise); ``< 0`` outside; ``0`` cocircular.

The arithmetic is exact as long as no intermediate product overflows or underflows: coordinate
differences between about 1e-60 and 1e60 for ``incircle`` (fourth powers), 1e-140 and 1e140 for
``orient2d``.  The scalar functions are ``@njit`` and meant to be called from other kernels; the
``*_many`` functions vectorise them for NumPy callers and tests.

Examples
--------
>>> import numpy as np
>>> from injmesh.kernels.predicates import orient2d, incircle
>>> orient2d(0.0, 0.0, 1.0, 0.0, 0.0, 1.0) > 0
True
>>> incircle(0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0)  # four corners of a square: cocircular
0.0
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

# Shewchuk's epsilon is half an ulp of 1: 2^-53.  The error bounds are his (section 4 and the
# constants of predicates.c's exactinit), written out for IEEE double precision.
_EPS = 2.0**-53
_SPLITTER = 2.0**27 + 1.0
_CCW_BOUND_A = (3.0 + 16.0 * _EPS) * _EPS
_ICC_BOUND_A = (10.0 + 96.0 * _EPS) * _EPS


# ---------------------------------------------------------------------------------------------
# Error-free transformations.  Each returns (x, y) with x = fl(op) and x + y = op exactly.


@njit(cache=True, inline="always")
def _two_sum(a: float, b: float) -> tuple[float, float]:
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@njit(cache=True, inline="always")
def _two_diff(a: float, b: float) -> tuple[float, float]:
    x = a - b
    bv = a - x
    av = x + bv
    return x, (a - av) + (bv - b)


@njit(cache=True, inline="always")
def _fast_two_sum(a: float, b: float) -> tuple[float, float]:
    # Requires |a| >= |b| (or a == 0).
    x = a + b
    return x, b - (x - a)


@njit(cache=True, inline="always")
def _split(a: float) -> tuple[float, float]:
    # Dekker: a = hi + lo with hi, lo of 26 significant bits each, so products of halves are exact.
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


@njit(cache=True, inline="always")
def _two_product(a: float, b: float) -> tuple[float, float]:
    x = a * b
    ahi, alo = _split(a)
    bhi, blo = _split(b)
    err = x - ahi * bhi
    err -= alo * bhi
    err -= ahi * blo
    return x, alo * blo - err


# ---------------------------------------------------------------------------------------------
# Expansion arithmetic.  An expansion is e[0:n], components sorted by increasing magnitude,
# non-overlapping, zeros eliminated; its largest component e[n-1] has the sign of the sum.


@njit(cache=True)
def _expansion_sum(e, elen, f, flen, h):  # type: ignore[no-untyped-def]
    """h = e + f by merging the components in order of magnitude; returns len(h).

    Shewchuk's fast expansion sum with zero elimination (Theorem 13), written with ``two_sum``
    throughout: slightly slower, and free of the ``fast_two_sum`` precondition.
    """
    ei = 0
    fi = 0
    enow = e[0]
    fnow = f[0]
    # Taking the smaller of the two heads: |fnow| > |enow|  <=>  the two comparisons agree.
    if (fnow > enow) == (fnow > -enow):
        q = enow
        ei += 1
    else:
        q = fnow
        fi += 1
    hi = 0
    while ei < elen and fi < flen:
        enow = e[ei]
        fnow = f[fi]
        if (fnow > enow) == (fnow > -enow):
            q, hh = _two_sum(q, enow)
            ei += 1
        else:
            q, hh = _two_sum(q, fnow)
            fi += 1
        if hh != 0.0:
            h[hi] = hh
            hi += 1
    while ei < elen:
        q, hh = _two_sum(q, e[ei])
        ei += 1
        if hh != 0.0:
            h[hi] = hh
            hi += 1
    while fi < flen:
        q, hh = _two_sum(q, f[fi])
        fi += 1
        if hh != 0.0:
            h[hi] = hh
            hi += 1
    if q != 0.0 or hi == 0:
        h[hi] = q
        hi += 1
    return hi


@njit(cache=True)
def _scale_expansion(e, elen, b, h):  # type: ignore[no-untyped-def]
    """h = b * e, exactly (Shewchuk's scale expansion with zero elimination); returns len(h)."""
    q, hh = _two_product(e[0], b)
    hi = 0
    if hh != 0.0:
        h[hi] = hh
        hi += 1
    for i in range(1, elen):
        p1, p0 = _two_product(e[i], b)
        s, hh = _two_sum(q, p0)
        if hh != 0.0:
            h[hi] = hh
            hi += 1
        q, hh = _fast_two_sum(p1, s)
        if hh != 0.0:
            h[hi] = hh
            hi += 1
    if q != 0.0 or hi == 0:
        h[hi] = q
        hi += 1
    return hi


@njit(cache=True)
def _orient2d_exact(ax, ay, bx, by, cx, cy):  # type: ignore[no-untyped-def]
    acx, acxt = _two_diff(ax, cx)
    bcx, bcxt = _two_diff(bx, cx)
    acy, acyt = _two_diff(ay, cy)
    bcy, bcyt = _two_diff(by, cy)
    if acxt == 0.0 and bcxt == 0.0 and acyt == 0.0 and bcyt == 0.0:
        # Stage B: the differences are exact, so acx*bcy - acy*bcx, as the four-term expansion
        # of Shewchuk's two_two_diff (x3 largest), is the determinant itself.
        l1, l0 = _two_product(acx, bcy)
        r1, r0 = _two_product(acy, bcx)
        i, x0 = _two_diff(l0, r0)
        j, x1 = _two_sum(l1, i)
        i, x1b = _two_diff(x1, r1)
        x3, x2 = _two_sum(j, i)
        if x3 != 0.0:
            return x3
        if x2 != 0.0:
            return x2
        if x1b != 0.0:
            return x1b
        return x0
    # Full exact evaluation from the coordinates themselves: the determinant is
    # ax*by - ay*bx + bx*cy - by*cx + cx*ay - cy*ax, a sum of six exact products.
    acc = np.zeros(13)
    nxt = np.empty(13)
    part = np.empty(2)
    alen = 1
    for k in range(6):
        if k == 0:
            p1, p0 = _two_product(ax, by)
        elif k == 1:
            p1, p0 = _two_product(-ay, bx)
        elif k == 2:
            p1, p0 = _two_product(bx, cy)
        elif k == 3:
            p1, p0 = _two_product(-by, cx)
        elif k == 4:
            p1, p0 = _two_product(cx, ay)
        else:
            p1, p0 = _two_product(-cy, ax)
        if p0 == 0.0:
            part[0] = p1
            plen = 1
        else:
            part[0] = p0
            part[1] = p1
            plen = 2
        alen = _expansion_sum(acc, alen, part, plen, nxt)
        acc, nxt = nxt, acc
    return acc[alen - 1]


@njit(cache=True)
def orient2d(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    """Twice the signed area of triangle abc, with the exact sign.

    Positive when a, b, c turn counter-clockwise, negative when clockwise, zero when collinear.
    """
    detleft = (ax - cx) * (by - cy)
    detright = (ay - cy) * (bx - cx)
    det = detleft - detright
    if detleft > 0.0:
        if detright <= 0.0:
            return det
        detsum = detleft + detright
    elif detleft < 0.0:
        if detright >= 0.0:
            return det
        detsum = -detleft - detright
    else:
        return det
    bound = _CCW_BOUND_A * detsum
    if det >= bound or -det >= bound:
        return det
    return _orient2d_exact(ax, ay, bx, by, cx, cy)


# ---------------------------------------------------------------------------------------------
# incircle


@njit(cache=True)
def _diff_into(a, b, out):  # type: ignore[no-untyped-def]
    """a - b as an exact expansion of one or two components written to out; returns its length."""
    x, y = _two_diff(a, b)
    if y == 0.0:
        out[0] = x
        return 1
    out[0] = y
    out[1] = x
    return 2


@njit(cache=True)
def _mul_into(e, elen, f, flen, h, tmp, part):  # type: ignore[no-untyped-def]
    """h = e * f exactly, with scratch arrays tmp and part; returns len(h)."""
    h[0] = 0.0
    hlen = 1
    for j in range(flen):
        plen = _scale_expansion(e, elen, f[j], part)
        tlen = _expansion_sum(h, hlen, part, plen, tmp)
        for i in range(tlen):
            h[i] = tmp[i]
        hlen = tlen
    return hlen


@njit(cache=True)
def _incircle_exact(ax, ay, bx, by, cx, cy, dx, dy):  # type: ignore[no-untyped-def]
    # One workspace for the whole evaluation: the exact stage runs on every cocircular quad of
    # a lattice, where one allocation per expansion would dominate the cost.
    w = np.empty(8192)
    d = w[0:12]  # the six differences to d, two slots each
    n = np.empty(6, dtype=np.int64)
    n[0] = _diff_into(ax, dx, d[0:2])
    n[1] = _diff_into(ay, dy, d[2:4])
    n[2] = _diff_into(bx, dx, d[4:6])
    n[3] = _diff_into(by, dy, d[6:8])
    n[4] = _diff_into(cx, dx, d[8:10])
    n[5] = _diff_into(cy, dy, d[10:12])
    s1 = w[16:48]
    s2 = w[48:80]
    part = w[80:144]
    tmp = w[144:2192]
    cross = w[2192:2288]  # bc, ca, ab: 32 slots each
    lift = w[2288:2384]  # alift, blift, clift
    terms = w[2384:4184]  # three products of up to 512 components: 600 slots each
    acc = w[4184:5384]
    det = w[5384:7000]
    ncross = np.empty(3, dtype=np.int64)
    nlift = np.empty(3, dtype=np.int64)
    for r in range(3):
        # Rows a, b, c: x = 2r, y = 2r+1; cross of rows (r+1, r+2): x1*y2 - x2*y1.
        i1 = (r + 1) % 3
        i2 = (r + 2) % 3
        x1 = d[4 * i1 : 4 * i1 + 2]
        y1 = d[4 * i1 + 2 : 4 * i1 + 4]
        x2 = d[4 * i2 : 4 * i2 + 2]
        y2 = d[4 * i2 + 2 : 4 * i2 + 4]
        pn = _mul_into(x1, n[2 * i1], y2, n[2 * i2 + 1], s1, tmp, part)
        qn = _mul_into(x2, n[2 * i2], y1, n[2 * i1 + 1], s2, tmp, part)
        for i in range(qn):
            s2[i] = -s2[i]
        ncross[r] = _expansion_sum(s1, pn, s2, qn, cross[32 * r : 32 * r + 32])
        xr = d[4 * r : 4 * r + 2]
        yr = d[4 * r + 2 : 4 * r + 4]
        pn = _mul_into(xr, n[2 * r], xr, n[2 * r], s1, tmp, part)
        qn = _mul_into(yr, n[2 * r + 1], yr, n[2 * r + 1], s2, tmp, part)
        nlift[r] = _expansion_sum(s1, pn, s2, qn, lift[32 * r : 32 * r + 32])
    # det = alift * (b x c) + blift * (c x a) + clift * (a x b)
    nterm = np.empty(3, dtype=np.int64)
    for r in range(3):
        nterm[r] = _mul_into(
            lift[32 * r : 32 * r + 32], nlift[r], cross[32 * r : 32 * r + 32], ncross[r],
            terms[600 * r : 600 * r + 600], tmp, part,
        )
    na = _expansion_sum(terms[0:600], nterm[0], terms[600:1200], nterm[1], acc)
    nd = _expansion_sum(acc, na, terms[1200:1800], nterm[2], det)
    return det[nd - 1]


@njit(cache=True)
def incircle(
    ax: float, ay: float, bx: float, by: float, cx: float, cy: float, dx: float, dy: float
) -> float:
    """In-circle determinant with the exact sign.

    For a, b, c counter-clockwise: positive when d lies strictly inside their circumcircle,
    negative outside, zero when the four points are cocircular.
    """
    adx = ax - dx
    bdx = bx - dx
    cdx = cx - dx
    ady = ay - dy
    bdy = by - dy
    cdy = cy - dy
    bdxcdy = bdx * cdy
    cdxbdy = cdx * bdy
    alift = adx * adx + ady * ady
    cdxady = cdx * ady
    adxcdy = adx * cdy
    blift = bdx * bdx + bdy * bdy
    adxbdy = adx * bdy
    bdxady = bdx * ady
    clift = cdx * cdx + cdy * cdy
    det = alift * (bdxcdy - cdxbdy) + blift * (cdxady - adxcdy) + clift * (adxbdy - bdxady)
    permanent = (
        (abs(bdxcdy) + abs(cdxbdy)) * alift
        + (abs(cdxady) + abs(adxcdy)) * blift
        + (abs(adxbdy) + abs(bdxady)) * clift
    )
    bound = _ICC_BOUND_A * permanent
    if det > bound or -det > bound:
        return det
    return _incircle_exact(ax, ay, bx, by, cx, cy, dx, dy)


# ---------------------------------------------------------------------------------------------
# Vectorised wrappers.


@njit(cache=True)
def _orient2d_many(a, b, c):  # type: ignore[no-untyped-def]
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = orient2d(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
    return out


@njit(cache=True)
def _incircle_many(a, b, c, d):  # type: ignore[no-untyped-def]
    out = np.empty(a.shape[0])
    for i in range(a.shape[0]):
        out[i] = incircle(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1], d[i, 0], d[i, 1])
    return out


def _rows(x: NDArray[np.float64], name: str) -> NDArray[np.float64]:
    arr = np.ascontiguousarray(np.atleast_2d(np.asarray(x, dtype=np.float64)))
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{name} must be (k, 2) points, got shape {np.shape(x)}")
    return arr


def orient2d_many(
    a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``orient2d`` row by row over ``(k, 2)`` arrays; the signs are exact.

    Examples
    --------
    >>> import numpy as np
    >>> float(orient2d_many(np.zeros((1, 2)), [[1.0, 1.0]], [[2.0, 2.0]])[0])
    0.0
    """
    a, b, c = _rows(a, "a"), _rows(b, "b"), _rows(c, "c")
    if not (len(a) == len(b) == len(c)):
        raise ValueError(f"a, b, c differ in length: {len(a)}, {len(b)}, {len(c)}")
    return _orient2d_many(a, b, c)  # type: ignore[no-any-return]


def incircle_many(
    a: NDArray[np.float64], b: NDArray[np.float64], c: NDArray[np.float64], d: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``incircle`` row by row over ``(k, 2)`` arrays; the signs are exact.

    Examples
    --------
    >>> import numpy as np
    >>> float(incircle_many([[0.0, 0.0]], [[1.0, 0.0]], [[0.0, 1.0]], [[0.2, 0.2]])[0]) > 0
    True
    """
    a, b, c, d = _rows(a, "a"), _rows(b, "b"), _rows(c, "c"), _rows(d, "d")
    if not (len(a) == len(b) == len(c) == len(d)):
        raise ValueError("a, b, c, d differ in length")
    return _incircle_many(a, b, c, d)  # type: ignore[no-any-return]


__all__ = ["incircle", "incircle_many", "orient2d", "orient2d_many"]
