"""The background grid on which sizes are sampled, gradation-limited and measured.

One uniform grid of square cells covers the domain's bounding box with a margin of
``PAD`` cells.  Its spacing follows the smallest size, ``h_min / CELLS_PER_H``, but the grid never
has more than ``max_cells`` nodes (default ``DEFAULT_MAX_CELLS``): past that the spacing grows
to ``sqrt(box area / max_cells)`` and the field is coarser than the size it samples (this is
reported in the log).

A user's h is sampled only at nodes inside the domain (d <= 0) and, for the nodes just outside
(an 8-neighbour is inside), at their projection onto the boundary (Eq. 3.2), so a size that is
meaningless outside the domain is never asked for a value there.  Other nodes impose nothing.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol
from ..geometry import BRep, Circle, Domain, GeometryError, Rectangle
from ._core import SizeError, SizeFunction

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

logger = logging.getLogger(__name__)

#: Background grid nodes per smallest size: the spacing is ``h_min / CELLS_PER_H``.
CELLS_PER_H = 4.0
#: Default cap on the number of background grid nodes (about 1000 x 1000).
DEFAULT_MAX_CELLS = 1_000_000
#: Margin of the grid around the domain's bounding box, in cells.
PAD = 2
#: Nodes per side of the coarse grid that estimates h_min before the grid is chosen.
PROBE_CELLS = 64
#: A grid resolves the domain's thickness when it has this many inside nodes per inside node
#: next to the boundary (about six nodes across); otherwise it is refined, at most
#: THIN_REFINEMENTS times.
THICK_RATIO = 3.0
THIN_REFINEMENTS = 12
#: Points per sdf call while sampling the grid (bounds the memory of sdf temporaries).
CHUNK = 1 << 18
#: With an exact boundary, d is evaluated only at nodes within NEAR spacings of it.
NEAR = 2.0


@dataclass(frozen=True)
class Background:
    """A uniform grid over a domain's box, with the signed distance sampled at its nodes.

    ``d`` is exact within ``NEAR`` spacings of the boundary (:func:`_sdf_on_grid`), unless
    ``signs_only``: then only its sign is (:func:`signs_on_grid`), for the callers that read
    nothing else (which nodes are inside, the band next to them).
    """

    x: FloatArray  # (nx,)
    y: FloatArray  # (ny,)
    d: FloatArray  # (ny, nx), d at the nodes
    spacing: float
    capped: bool  # the cell cap made the spacing coarser than asked
    signs_only: bool = False

    @property
    def inside(self) -> BoolArray:
        """Nodes inside the domain or on its boundary, ``(ny, nx)``."""
        return self.d <= 0

    @property
    def band(self) -> BoolArray:
        """Nodes outside with an inside node among their eight neighbours, ``(ny, nx)``."""
        inside = self.inside
        near = inside.copy()
        near[1:, :] |= inside[:-1, :]
        near[:-1, :] |= inside[1:, :]
        wide = near.copy()
        wide[:, 1:] |= near[:, :-1]
        wide[:, :-1] |= near[:, 1:]
        return wide & ~inside

    def nodes(self, mask: BoolArray) -> FloatArray:
        """Coordinates of the masked nodes, ``(k, 2)``, in row-major order."""
        j, i = np.nonzero(mask)
        return np.stack([self.x[i], self.y[j]], axis=1)


def cells(box: tuple[float, float, float, float], spacing: float) -> tuple[int, int]:
    """Grid nodes along x and y for a box and a spacing, margin included."""
    x0, y0, x1, y1 = box
    return (
        int(math.ceil((x1 - x0) / spacing)) + 1 + 2 * PAD,
        int(math.ceil((y1 - y0) / spacing)) + 1 + 2 * PAD,
    )


def axes(box: tuple[float, float, float, float], spacing: float) -> tuple[FloatArray, FloatArray]:
    """The node coordinates along x and y of the grid of ``spacing`` over a box (:func:`cells`
    nodes each, ``PAD`` of them outside the box on every side)."""
    nx, ny = cells(box, spacing)
    x = box[0] + spacing * (np.arange(nx, dtype=np.float64) - PAD)
    y = box[1] + spacing * (np.arange(ny, dtype=np.float64) - PAD)
    return x, y


def check_grid_options(spacing: float | None, max_cells: int) -> None:
    """Validate the public ``spacing=`` and ``max_cells=`` arguments."""
    if spacing is not None and not (isinstance(spacing, (int, float, np.number)) and math.isfinite(
            float(spacing)) and spacing > 0):
        raise SizeError(f"spacing must be a positive finite length, got {spacing!r}")
    if not (isinstance(max_cells, (int, np.integer)) and max_cells >= 16):
        raise SizeError(f"max_cells must be an integer of at least 16, got {max_cells!r}")


def fit_spacing(domain: Domain, wanted: float, max_cells: int, explicit: bool) -> tuple[float, bool]:
    """``wanted``, or the smallest spacing whose grid has at most ``max_cells`` nodes."""
    x0, y0, x1, y1 = domain.bbox
    nx, ny = cells(domain.bbox, wanted)
    if nx * ny <= max_cells:
        return wanted, False
    if explicit:
        raise SizeError(
            f"spacing={wanted:g} needs a {nx} x {ny} background grid, more than max_cells={max_cells}; "
            "raise max_cells or pass a larger spacing"
        )
    s = wanted
    # Solve (w/s + 1 + 2 PAD)(h/s + 1 + 2 PAD) <= max_cells for s, then round up until it fits.
    w, h = x1 - x0, y1 - y0
    m = 1 + 2 * PAD
    a, b, c = max_cells - m * m, -m * (w + h), -w * h
    if a > 0:
        s = max(s, (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a))
    while cells(domain.bbox, s)[0] * cells(domain.bbox, s)[1] > max_cells:
        s *= 1.01
    return s, True


def resolving_background(domain: Domain, spacing: float, max_cells: int, explicit: bool,
                         signs_only: bool = False) -> Background:
    """The background grid of about ``spacing``, refined where the domain is thin everywhere.

    A domain only a few cells thick (a long channel in a box sized by its length, or a size
    much larger than the width) would leave its medial axis unresolved: while fewer than
    THICK_RATIO inside nodes stand per inside node next to the boundary, the spacing is halved
    (at most THIN_REFINEMENTS times, within ``max_cells``).  An explicit spacing is kept.
    ``signs_only``: see :func:`make_background`.
    """
    s, capped = fit_spacing(domain, spacing, max_cells, explicit)
    grid = make_background(domain, s, capped, check=False, signs_only=signs_only)
    for _ in range(0 if explicit else THIN_REFINEMENTS):
        inside = grid.inside
        edge = inside & ~(
            np.pad(inside, 1, constant_values=False)[:-2, 1:-1]
            & np.pad(inside, 1, constant_values=False)[2:, 1:-1]
            & np.pad(inside, 1, constant_values=False)[1:-1, :-2]
            & np.pad(inside, 1, constant_values=False)[1:-1, 2:]
        )
        if inside.sum() >= THICK_RATIO * max(1, int(edge.sum())):
            break
        finer, capped = fit_spacing(domain, 0.5 * s, max_cells, explicit=False)
        if finer > 0.75 * s:
            break  # the cell cap allows no finer grid
        s = finer
        grid = make_background(domain, s, capped, check=False, signs_only=signs_only)
    return make_background(domain, s, capped, signs_only=signs_only) if not grid.inside.any() else grid


def make_background(domain: Domain, spacing: float, capped: bool = False, check: bool = True,
                    signs_only: bool = False) -> Background:
    """Sample the signed distance on a grid of the given spacing over the domain's box.

    ``signs_only``: only the signs of d are sampled (:func:`signs_on_grid`, a fraction of the
    sdf calls where the boundary is exact); the magnitudes are ``NEAR`` spacings, not to be
    read (:attr:`Background.signs_only`).
    """
    x, y = axes(domain.bbox, spacing)
    # (A circle's or a rectangle's closed formula, or a plain sdf, gives d itself as cheaply.)
    signs_only = signs_only and not isinstance(domain, (Circle, Rectangle)) \
        and exact_boundary(domain) is not None
    if signs_only:
        reach = NEAR * float(spacing)
        d = np.where(signs_on_grid(domain, x, y, float(spacing)), -reach, reach)
    else:
        d = _sdf_on_grid(domain, x, y, float(spacing))
    grid = Background(x=x, y=y, d=d, spacing=float(spacing), capped=capped, signs_only=signs_only)
    if check and not grid.inside.any():
        raise SizeError(
            f"no background grid node (spacing {spacing:g}) lies inside the domain: it is thinner "
            "than the grid; pass a smaller spacing"
        )
    return grid


def exact_boundary(domain: Domain) -> BRep | None:
    """The domain's exact boundary (segments and arcs, domain on the left), if it has one."""
    if isinstance(domain, BRep):
        return domain
    exact = getattr(domain, "exact_brep", None)
    out = exact() if callable(exact) else None
    return out if isinstance(out, BRep) else None


def _sdf_on_grid(domain: Domain, x: FloatArray, y: FloatArray, spacing: float) -> FloatArray:
    """d at the grid nodes, ``(ny, nx)``; exact within ``NEAR`` spacings of the boundary.

    With an exact boundary the sign of every node comes from scanlines over the boundary
    polylines (:mod:`injmesh.kernels.raster`) and only the nodes near the boundary are
    evaluated; the others carry ``-NEAR * spacing`` inside and ``+NEAR * spacing`` outside, a
    lower bound of ``|d|`` there (nothing reads the magnitude away from the boundary).  Other
    domains, and circles and rectangles, are evaluated at every node.
    """
    nx, ny = len(x), len(y)
    # A circle's or a rectangle's d is a closed formula, cheaper than the scan, and separable
    # on a grid: from the rows' and columns' offsets, by broadcasting (a 1e6-node grid: 10 ms
    # rather than 60 ms through the point-wise sdf).  The same formulas as their sdf.
    if type(domain) is Circle:
        return np.asarray(np.hypot((x - domain.center[0])[None, :], (y - domain.center[1])[:, None])
                          - domain.r)
    if type(domain) is Rectangle:
        half = 0.5 * (domain.hi - domain.lo)
        c = 0.5 * (domain.lo + domain.hi)
        qx, qy = np.abs(x - c[0]) - half[0], np.abs(y - c[1]) - half[1]
        outside = np.hypot(np.maximum(qx, 0.0)[None, :], np.maximum(qy, 0.0)[:, None])
        return np.asarray(outside + np.minimum(np.maximum(qx[None, :], qy[:, None]), 0.0))
    brep = None if isinstance(domain, (Circle, Rectangle)) else exact_boundary(domain)
    if brep is None:
        X, Y = np.meshgrid(x, y)
        return _sdf_chunked(domain, np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(ny, nx)
    from ..kernels.raster import scan

    reach = NEAR * spacing
    inside, near = scan(x, y, *_polylines(brep, spacing), reach)
    d = np.where(inside, -reach, reach)
    if near.any():
        jj, ii = np.nonzero(near)
        d[jj, ii] = _sdf_chunked(domain, np.stack([x[ii], y[jj]], axis=1))
    return d


def _polylines(brep: BRep, spacing: float) -> tuple[FloatArray, FloatArray]:
    """The boundary as segments ``a[s] -> b[s]``: polylines within ``spacing / 8`` of it (arcs
    are sampled finer than ``spacing`` and at 16 points per turn at least), cut so that every
    segment's box is about a cell."""
    loops = [densify(np.asarray(loop, dtype=np.float64), spacing) for loop in brep.boundary_loops(spacing)
             if len(loop) >= 2]
    a = np.concatenate(loops) if loops else np.empty((0, 2))
    b = np.concatenate([np.roll(loop, -1, axis=0) for loop in loops]) if loops else np.empty((0, 2))
    return a, b


#: :func:`signs_on_grid` evaluates the sdf at the nodes within this many spacings of a boundary
#: polyline segment (more than the polylines' ``1 / 8``, with a margin for rounding).
SIGN_REACH = 0.25


def signs_on_grid(domain: Domain, x: FloatArray, y: FloatArray, spacing: float) -> BoolArray:
    """``d <= 0`` at the grid nodes, ``(ny, nx)``: the signs of :func:`_sdf_on_grid`'s d.

    With an exact boundary (not a circle or a rectangle, whose closed formulas are cheaper)
    only the nodes within ``SIGN_REACH * spacing`` of a boundary polyline segment
    (:func:`~injmesh.kernels.raster.near_nodes`) are evaluated; the others take the
    scanlines' sign, as :func:`_sdf_on_grid` gives the nodes farther than ``NEAR`` spacings:
    the polylines are within ``spacing / 8`` of the boundary, so a node farther than that
    from them lies on the same side of both.  For a grid whose magnitudes are not read (the
    probe of :func:`probe_range`): a fraction of the sdf calls.
    """
    brep = None if isinstance(domain, (Circle, Rectangle)) else exact_boundary(domain)
    if brep is None:
        out: BoolArray = _sdf_on_grid(domain, x, y, spacing) <= 0
        return out
    from ..kernels.raster import near_nodes, scan

    a, b = _polylines(brep, spacing)
    inside = scan(x, y, a, b, 0.0)[0]
    near = near_nodes(x, y, a, b, SIGN_REACH * spacing)
    if near.any():
        jj, ii = np.nonzero(near)
        inside[jj, ii] = _sdf_chunked(domain, np.stack([x[ii], y[jj]], axis=1)) <= 0
    return inside


#: :func:`inside_test` trusts the sign of the grid nodes farther than this many spacings from
#: every polyline segment (more than ``1 / sqrt(2) + 1 / 8`` = 0.832, with a margin for
#: rounding: see there).
SURE = 0.875


def inside_test(domain: Domain, spacing: float) -> Callable[[FloatArray], BoolArray] | None:
    """A fast ``domain.sdf(p) <= 0`` for many points, or None where the plain call is as fast.

    For a domain with an exact boundary (and an sdf more costly than a closed formula), the
    nodes of a grid of ``spacing`` get their sign from scanlines over the boundary polylines
    (:func:`_polylines`, :func:`~injmesh.kernels.raster.scan`; no sdf call), and those within
    ``SURE * spacing`` of a polyline segment are flagged
    (:func:`~injmesh.kernels.raster.near_nodes`).  A node not flagged is farther than ``(SURE
    - 1/8) * spacing`` from the boundary (the polylines are within ``spacing / 8`` of it),
    more than the ``spacing / sqrt(2)`` from a cell's corner to any point of the cell: a point
    in a cell whose four corners are unflagged and of one sign has that sign too.  Only the
    other points are evaluated.  The answers are those of ``domain.sdf(p) <= 0``.  (The grid's
    own d is not needed: 0.4-1 ms of sdf calls saved per node estimate on the paper's cases.)
    """
    if isinstance(domain, (Circle, Rectangle)):
        return None
    brep = exact_boundary(domain)
    if brep is None:
        return None
    gx, gy = axes(domain.bbox, spacing)
    from ..kernels.raster import cell_signs, near_nodes, scan

    a, b = _polylines(brep, float(spacing))
    sign = scan(gx, gy, a, b, 0.0)[0]
    far = ~near_nodes(gx, gy, a, b, SURE * float(spacing))
    s00, s10, s01, s11 = sign[:-1, :-1], sign[:-1, 1:], sign[1:, :-1], sign[1:, 1:]
    neg = s00 & s10 & s01 & s11
    pos = ~(s00 | s10 | s01 | s11)
    known = (neg | pos) & far[:-1, :-1] & far[:-1, 1:] & far[1:, :-1] & far[1:, 1:]

    known = np.ascontiguousarray(known)
    neg = np.ascontiguousarray(neg)
    step = float(spacing)

    def inside(p: FloatArray) -> BoolArray:
        out, rest = cell_signs(np.ascontiguousarray(p, dtype=np.float64), float(gx[0]), float(gy[0]), step,
                               known, neg)
        if len(rest):
            out[rest] = domain.sdf(p[rest]) <= 0
        out_: BoolArray = out
        return out_

    return inside


def _sdf_chunked(domain: Domain, p: FloatArray) -> FloatArray:
    """``domain.sdf`` in chunks of ``CHUNK`` points (bounds the memory of its temporaries)."""
    out = np.empty(len(p))
    for k in range(0, len(p), CHUNK):
        out[k : k + CHUNK] = domain.sdf(p[k : k + CHUNK])
    return out


def densify(loop: FloatArray, step: float) -> FloatArray:
    """A closed polyline with extra vertices so that no segment is longer than ``step``: each
    segment cut into ``max(1, ceil(length / step))`` equal pieces (compiled,
    :func:`injmesh.kernels.raster.densify`: called for every loop by the grids, the probe and
    the thickness test, ~60 us of NumPy temporaries each)."""
    from ..kernels.raster import densify as dense

    out: FloatArray = dense(np.ascontiguousarray(loop, dtype=np.float64).reshape(-1, 2), float(step))
    return out


def probe_min(h: SizeFunction, domain: Domain) -> float:
    """The smallest size at a coarse sample of the domain: nodes inside and boundary points."""
    return probe_range(h, domain)[0]


def probe_range(h: SizeFunction, domain: Domain) -> tuple[float, float]:
    """The smallest and largest size at a coarse sample of the domain (see :func:`probe_min`),
    both clamped to the domain's diameter."""
    x0, y0, x1, y1 = domain.bbox
    step = max(x1 - x0, y1 - y0) / PROBE_CELLS
    inner, rim = np.empty((0, 2)), np.empty((0, 2))
    # Only the nodes' signs are read here (:func:`signs_on_grid`: the grid's d, fewer sdf calls).
    gx, gy = axes(domain.bbox, step)
    j, i = np.nonzero(signs_on_grid(domain, gx, gy, float(step)))
    inner = np.stack([gx[i], gy[j]], axis=1)  # empty when the domain is thinner than the grid
    try:
        loops = [densify(loop, step) for loop in domain.boundary_loops(step)]
        rim = np.concatenate(loops) if loops else rim
    except ValueError:  # a domain whose boundary cannot be traced at this scale: nodes suffice
        pass
    if not len(inner) and not len(rim):
        raise GeometryError("the domain is empty: no node of the probe grid inside, no boundary curve")
    # The grid's inside nodes are inside (d <= 0): h is asked there directly; the boundary
    # points (chords of curves may lie just outside) go through the restriction.
    vals = np.concatenate([h(inner) if len(inner) else np.empty(0),
                           h.restricted(domain)(rim) if len(rim) else np.empty(0)])
    diameter = float(domain.diameter)
    return min(float(vals.min()), diameter), min(float(vals.max()), diameter)


def sample_size(h: SizeFunction, domain: Domain, grid: Background, rate: float = 0.0) -> FloatArray:
    """h at the grid nodes inside the domain and at the boundary projections of the band nodes.

    A band node ``y`` with boundary projection ``b`` gets ``h(b) + rate |y - b|``: the size at
    the boundary, extended outward at the gradation rate, so that a size that already satisfies
    the limit is not lowered inside by its own boundary values.

    Returns ``(ny, nx)`` sizes, clamped to the domain's diameter, with ``inf`` at nodes that
    impose nothing (outside, beyond the band, or whose projection did not reach the boundary).
    """
    out = np.full(grid.d.shape, np.inf)
    inside = grid.inside
    out[inside] = h(grid.nodes(inside))
    band = grid.band
    if band.any():
        q = domain.project(grid.nodes(band))
        on = domain.sdf(q) <= tol.ON_BOUNDARY * domain.diameter
        vals = np.full(len(q), np.inf)
        if on.any():
            y = grid.nodes(band)[on]
            vals[on] = h(q[on]) + rate * np.hypot(*(y - q[on]).T)
        out[band] = vals
    # A size beyond the diameter means one element across everything: clamp it (1e300 stays sane).
    return np.where(np.isfinite(out), np.minimum(out, domain.diameter), np.inf)


def sampled_grid(
    h: SizeFunction,
    domain: Domain,
    spacing: float | None,
    max_cells: int,
    rate: float = 0.0,
    max_spacing: float = np.inf,
    h_min: float | None = None,
    signs_only: bool = False,
) -> tuple[Background, FloatArray]:
    """The background grid for ``h`` on ``domain`` and h sampled on it (see the module docstring).

    Without ``spacing`` the grid follows ``min(h_min / CELLS_PER_H, max_spacing)`` with ``h_min``
    estimated on a coarse probe; when the grid then finds sizes below half that estimate, it is
    refined once.  ``h_min`` is the probe's estimate when the caller already has it.
    ``signs_only``: see :func:`make_background` (h is sampled from the signs alone).
    """
    if spacing is not None:
        grid = resolving_background(domain, float(spacing), max_cells, explicit=True, signs_only=signs_only)
        return grid, sample_size(h, domain, grid, rate)
    if h_min is None:
        h_min = probe_min(h, domain)
    grid = resolving_background(domain, min(h_min / CELLS_PER_H, max_spacing), max_cells, explicit=False,
                                signs_only=signs_only)
    values = sample_size(h, domain, grid, rate)
    finer = float(values.min())
    if not grid.capped and finer / CELLS_PER_H < 0.5 * grid.spacing:
        grid = resolving_background(domain, finer / CELLS_PER_H, max_cells, explicit=False,
                                    signs_only=signs_only)
        values = sample_size(h, domain, grid, rate)
    if grid.capped:
        logger.info(
            "background grid capped at %d nodes: spacing %.3g for a smallest size %.3g",
            max_cells, grid.spacing, float(values.min()),
        )
    return grid, values
