"""Seeded random families of simple polygons with holes, for tests, benchmarks and batches.

Every generator takes an integer ``seed`` and returns a :class:`Shape`: plain float64 arrays,
the shell ``(k, 2)`` counter-clockwise, holes ``(k, 2)`` clockwise, and for coastlines further
components (``islands``, counter-clockwise).  The same seed gives the same arrays bit for bit
(``numpy.random.default_rng``; no global state).  Each shape is verified before it is returned:
no two non-adjacent edges of any ring closer than ``1e-9`` times the diameter (so no crossing,
touching or overlap), no edge folding back onto its neighbour, holes strictly inside the shell
and outside each other, islands outside the shell and each other.  A candidate that fails is
discarded and the generator retries with the next sub-seed ``(seed, attempt)``; an invalid
shape is never returned.

Shapes are scaled to about ``[-1, 1]^2`` (diameter about 2) unless a family says otherwise.
Each shape carries ``size``, a suggested uniform edge length for meshing it.

Families (see each function for its parameters):

==============  =================================================================================
``star``        star-shaped polygon (radius noise around the origin), 0-3 holes
``walk``        random-walk outline: the boundary of a random walk of grid cells, jittered; not
                star-shaped, with one-cell corridors; 0-3 holes
``holes``       a star or walk shell with 1-3 holes
``sharp``       convex spikes down to ``min_angle`` degrees and reflex notches
``neck``        two lobes joined by a channel narrower than ``width``
``duplicates``  star or walk outline with vertices doubled ``gap`` (1e-7 relative) apart
``coastline``   fractal (midpoint-displacement) mainland with islands whose straits to the
                mainland are narrower than ``strait``
``large``       a fractal outline of exactly ``n_vertices`` (20,000) vertices
``plates``      perforated plate: a rectangle with circular and polygonal holes
``airfoil``     a NACA 4-digit profile as a hole in a box (sharp or thin blunt trailing edge)
==============  =================================================================================

:func:`family` iterates over ``count`` shapes of one family with seeds ``seed, seed + 1, ...``;
:func:`to_geojson` and :func:`to_wkt` write a shape for the readers of :mod:`injmesh.inputs`.

Examples
--------
>>> from injmesh import shapes
>>> s = shapes.star(3, n_holes=2)
>>> s.shell.shape[1], len(s.holes)
(2, 2)
>>> bool((shapes.star(3, n_holes=2).shell == s.shell).all())
True
>>> shapes.to_geojson(s)["type"]
'Polygon'
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from .geometry import Domain

FloatArray = NDArray[np.float64]

#: Two non-adjacent edges must be farther apart than this fraction of the diameter.
CLEARANCE = 1e-9
#: Attempts (sub-seeds) before a generator gives up (it never returns an invalid shape).
MAX_ATTEMPTS = 200


class ShapeError(ValueError):
    """A generator could not build a valid shape with the requested parameters."""


@dataclass(frozen=True, eq=False)
class Shape:
    """A polygonal domain: one shell, its holes, and optional further components.

    Attributes
    ----------
    shell : (k, 2) float64 array
        Outer boundary, counter-clockwise, not closed (last vertex != first).
    holes : list of (k, 2) float64 arrays
        Holes, clockwise, strictly inside the shell and disjoint.
    islands : list of (k, 2) float64 arrays
        Further components (counter-clockwise, no holes), outside the shell and each other.
    family : str
        Name of the generating family.
    seed : int
        Seed that reproduces this shape with the family's generator.
    size : float
        Suggested uniform edge length h.
    params : dict
        The parameters the generator used, and measured properties (e.g. ``min_angle``,
        ``neck_width``, ``strait_width``).
    """

    shell: FloatArray
    holes: list[FloatArray]
    islands: list[FloatArray] = field(default_factory=list)
    family: str = ""
    seed: int = 0
    size: float = 0.1
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def rings(self) -> list[FloatArray]:
        """Every ring: shell, holes, islands (each oriented with the domain on its left)."""
        return [self.shell, *self.holes, *self.islands]

    @property
    def n_vertices(self) -> int:
        """Total number of vertices of all rings."""
        return int(sum(len(r) for r in self.rings))

    @property
    def area(self) -> float:
        """Area of the domain (shell minus holes plus islands)."""
        return float(sum(signed_area(r) for r in self.rings))

    @property
    def perimeter(self) -> float:
        """Total boundary length."""
        return float(sum(np.linalg.norm(np.roll(r, -1, axis=0) - r, axis=1).sum() for r in self.rings))

    @property
    def min_angle(self) -> float:
        """Smallest interior angle of the domain at any vertex, in degrees."""
        return float(min(interior_angles(r).min() for r in self.rings))

    def to_geojson(self) -> dict[str, Any]:
        """GeoJSON geometry; see :func:`to_geojson`."""
        return to_geojson(self)

    def to_wkt(self) -> str:
        """WKT text; see :func:`to_wkt`."""
        return to_wkt(self)

    def domain(self) -> Domain:
        """The injmesh domain: ``Polygon(shell) - Polygon(hole) ... | Polygon(island) ...``."""
        from .geometry import Polygon

        dom: Domain = Polygon(self.shell)
        for hole in self.holes:
            dom = dom - Polygon(hole)
        for island in self.islands:
            dom = dom | Polygon(island)
        return dom

    def __repr__(self) -> str:
        return (
            f"<Shape {self.family} seed={self.seed}: {self.n_vertices} vertices, "
            f"{len(self.holes)} holes, {len(self.islands)} islands>"
        )


# --------------------------------------------------------------------------------------------
# Ring geometry and the validity check
# --------------------------------------------------------------------------------------------


def signed_area(ring: ArrayLike) -> float:
    """Shoelace area of a ring (positive when counter-clockwise), in local coordinates."""
    v = np.asarray(ring, dtype=float)
    v = v - v.mean(axis=0)
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def interior_angles(ring: ArrayLike) -> FloatArray:
    """Angle of the domain at each vertex of a ring oriented with the domain on its left, degrees.

    Between 0 and 360: below 180 at convex corners, above 180 at reflex ones.  For a hole
    (clockwise) this is the angle of the surrounding domain.

    Examples
    --------
    >>> interior_angles([(0, 0), (1, 0), (1, 1), (0, 1)]).tolist()
    [90.0, 90.0, 90.0, 90.0]
    """
    v = np.asarray(ring, dtype=float)
    to_next = np.roll(v, -1, axis=0) - v
    to_prev = np.roll(v, 1, axis=0) - v
    cross = to_next[:, 0] * to_prev[:, 1] - to_next[:, 1] * to_prev[:, 0]
    dot = np.einsum("ij,ij->i", to_next, to_prev)
    return np.degrees(np.arctan2(cross, dot)) % 360.0


def _orient(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])


def _point_segment_distance(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance of each point p[i] to the segment a[i] b[i] (rows paired)."""
    ab = b - a
    ab2 = np.einsum("ij,ij->i", ab, ab)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.einsum("ij,ij->i", p - a, ab) / ab2
    t = np.clip(np.nan_to_num(t, nan=0.0), 0.0, 1.0)
    return np.hypot(*(p - a - t[:, None] * ab).T)


def segment_distances(p1: FloatArray, p2: FloatArray, q1: FloatArray, q2: FloatArray) -> FloatArray:
    """Distance between segments p1[i] p2[i] and q1[i] q2[i] (0 where they cross)."""
    d1, d2 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    d3, d4 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    dist = np.minimum(
        np.minimum(_point_segment_distance(q1, p1, p2), _point_segment_distance(q2, p1, p2)),
        np.minimum(_point_segment_distance(p1, q1, q2), _point_segment_distance(p2, q1, q2)),
    )
    # A proper crossing: a float sign error here needs an endpoint within ~1e-15 of the other
    # segment's line, and then the endpoint distances above are already below any clearance.
    dist[(d1 * d2 < 0) & (d3 * d4 < 0)] = 0.0
    return dist


def _close_pairs(a: FloatArray, b: FloatArray, tol: float) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Index pairs (i < j) of segments whose bounding boxes come within ``tol``: a sweep in x."""
    xmin = np.minimum(a[:, 0], b[:, 0])
    xmax = np.maximum(a[:, 0], b[:, 0])
    order = np.argsort(xmin, kind="stable")
    xs = xmin[order]
    hi = np.searchsorted(xs, xmax[order] + tol, side="right")
    n = len(order)
    counts = np.maximum(hi - np.arange(n) - 1, 0)
    total = int(counts.sum())
    if total == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    first = np.repeat(np.arange(n), counts)
    offset = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    i, j = order[first], order[first + 1 + offset]
    ymin = np.minimum(a[:, 1], b[:, 1])
    ymax = np.maximum(a[:, 1], b[:, 1])
    keep = (ymin[i] <= ymax[j] + tol) & (ymin[j] <= ymax[i] + tol)
    return np.minimum(i[keep], j[keep]), np.maximum(i[keep], j[keep])


def _inside(point: FloatArray, ring: FloatArray) -> bool:
    """Even-odd point-in-ring test (the point is known not to be on the ring)."""
    a, b = ring, np.roll(ring, -1, axis=0)
    x, y = point
    straddle = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(invalid="ignore", divide="ignore"):
        xc = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return bool(np.count_nonzero(straddle & (xc > x)) % 2)


def _diameter(rings: Sequence[FloatArray]) -> float:
    allp = np.concatenate(rings)
    return float(np.hypot(*np.ptp(allp, axis=0)))


def bad_segments(rings: Sequence[FloatArray], clearance: float = CLEARANCE) -> list[NDArray[np.intp]]:
    """Per ring, the indices of edges (edge k joins vertex k and k + 1) that break simplicity.

    An edge is bad when a non-adjacent edge (of any ring) comes within ``clearance`` times the
    diameter of the rings, or when it folds back onto its neighbouring edge (zero angle).
    """
    rings = [np.asarray(r, dtype=float) for r in rings]
    center = np.concatenate(rings).mean(axis=0)
    rings = [r - center for r in rings]  # local coordinates: exact-enough orientation signs
    tol = clearance * _diameter(rings)
    sizes = np.array([len(r) for r in rings])
    start = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    ring_id = np.repeat(np.arange(len(rings)), sizes)
    local = np.arange(int(sizes.sum())) - np.repeat(start, sizes)
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    bad = np.zeros(len(a), dtype=bool)

    # Edges folding back on their successor: the angle at the shared vertex is zero or 360.
    for r, (s, n) in enumerate(zip(start, sizes, strict=True)):
        ang = interior_angles(rings[r])
        fold = (ang < 1e-7) | (ang > 360 - 1e-7)
        k = np.flatnonzero(fold)  # vertex k joins edges k - 1 and k
        bad[s + k] = True
        bad[s + (k - 1) % n] = True

    i, j = _close_pairs(a, b, tol)
    same = ring_id[i] == ring_id[j]
    n_ring = sizes[ring_id[i]]
    diff = (local[j] - local[i]) % np.maximum(n_ring, 1)
    adjacent = same & ((diff == 1) | (diff == n_ring - 1))
    i, j = i[~adjacent], j[~adjacent]
    step = 1_000_000
    for s in range(0, len(i), step):
        ii, jj = i[s : s + step], j[s : s + step]
        near = segment_distances(a[ii], b[ii], a[jj], b[jj]) <= tol
        bad[ii[near]] = True
        bad[jj[near]] = True
    return [np.flatnonzero(bad[s : s + n]) for s, n in zip(start, sizes, strict=True)]


def shape_problems(
    shell: ArrayLike,
    holes: Sequence[ArrayLike] = (),
    islands: Sequence[ArrayLike] = (),
    clearance: float = CLEARANCE,
) -> list[str]:
    """Everything that keeps (shell, holes, islands) from being a valid simple domain.

    Returns an empty list for a valid shape: every ring has at least 3 finite vertices, the
    shell and islands are counter-clockwise and holes clockwise, no two non-adjacent edges come
    within ``clearance`` times the diameter, holes lie strictly inside the shell and outside each
    other, islands outside the shell and each other.

    Examples
    --------
    >>> shape_problems([(0, 0), (1, 0), (1, 1), (0, 1)], [[(0.2, 0.2), (0.2, 0.8), (0.8, 0.2)]])
    []
    >>> shape_problems([(0, 0), (1, 1), (1, 0), (0, 1)])
    ['shell: edges [0, 2] cross or touch another edge', 'shell: not counter-clockwise']
    """
    rings = [np.asarray(shell, dtype=float)]
    rings += [np.asarray(h, dtype=float) for h in holes]
    rings += [np.asarray(s, dtype=float) for s in islands]
    names = ["shell"] + [f"hole {k}" for k in range(len(holes))]
    names += [f"island {k}" for k in range(len(islands))]
    out = []
    for name, r in zip(names, rings, strict=True):
        if r.ndim != 2 or r.shape[1] != 2 or len(r) < 3:
            out.append(f"{name}: needs shape (k >= 3, 2), got {r.shape}")
        elif not np.all(np.isfinite(r)):
            out.append(f"{name}: non-finite coordinates")
    if out:
        return out
    for name, idx in zip(names, bad_segments(rings, clearance), strict=True):
        if len(idx):
            out.append(f"{name}: edges {idx[:5].tolist()} cross or touch another edge")
    for k, (name, r) in enumerate(zip(names, rings, strict=True)):
        area = signed_area(r)
        if (area <= 0) if (k == 0 or k > len(holes)) else (area >= 0):
            out.append(f"{name}: not {'clockwise' if 0 < k <= len(holes) else 'counter-clockwise'}")
    if out:
        return out
    shell_r, hole_r, island_r = rings[0], rings[1 : 1 + len(holes)], rings[1 + len(holes) :]
    for k, h in enumerate(hole_r):
        if not _inside(h[0], shell_r):
            out.append(f"hole {k}: not inside the shell")
        for m, g in enumerate(hole_r):
            if m != k and _inside(h[0], g):
                out.append(f"hole {k}: inside hole {m}")
    for k, s in enumerate(island_r):
        if _inside(s[0], shell_r) or _inside(shell_r[0], s):
            out.append(f"island {k}: overlaps the shell")
        for m, g in enumerate(island_r):
            if m != k and _inside(s[0], g):
                out.append(f"island {k}: inside island {m}")
    return out


def _valid(shell: FloatArray, holes: Sequence[FloatArray] = (), islands: Sequence[FloatArray] = ()) -> bool:
    return not shape_problems(shell, holes, islands)


def _retry(name: str, seed: int, build: Callable[[np.random.Generator], Shape | None]) -> Shape:
    """Call ``build`` with generators of sub-seeds (seed, 0), (seed, 1), ... until it succeeds."""
    if not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ShapeError(f"{name}: seed must be a non-negative integer, got {seed!r}")
    for attempt in range(MAX_ATTEMPTS):
        shape = build(np.random.default_rng([int(seed), attempt]))
        if shape is not None and _valid(shape.shell, shape.holes, shape.islands):
            shape.params["attempts"] = attempt + 1
            return shape
    raise ShapeError(f"{name}: no valid shape in {MAX_ATTEMPTS} attempts for seed {seed}; "
                     "the parameters may be infeasible")


def _normalise(shell: FloatArray, extent: float = 2.0) -> tuple[FloatArray, float, FloatArray]:
    """Scale and centre so the bounding box's larger side is ``extent`` and its centre is 0."""
    lo, hi = shell.min(axis=0), shell.max(axis=0)
    scale = extent / float((hi - lo).max())
    centre = 0.5 * (lo + hi)
    return (shell - centre) * scale, scale, centre


# --------------------------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------------------------


def _star_ring(
    rng: np.random.Generator, n: int, radius: float, irregularity: float, spikiness: float
) -> FloatArray:
    """A star-shaped ring (counter-clockwise) around the origin with ``n`` vertices."""
    gaps = 1.0 + irregularity * rng.uniform(-1, 1, n)
    theta = 2 * np.pi * np.concatenate([[0.0], np.cumsum(gaps)[:-1]]) / gaps.sum()
    theta = theta + rng.uniform(0, 2 * np.pi)
    # Smooth radius noise (a few Fourier modes) plus per-vertex noise.
    modes = np.arange(1, 5)
    amp = spikiness * rng.normal(0, 1, (2, 4)) / modes
    smooth = amp[0] @ np.cos(np.outer(modes, theta)) + amp[1] @ np.sin(np.outer(modes, theta))
    r = radius * np.clip(1.0 + 0.5 * smooth + spikiness * rng.uniform(-0.5, 0.5, n), 0.25, 1.6)
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


def _distance_to_rings(p: FloatArray, rings: Sequence[FloatArray]) -> FloatArray:
    """Distance of each point to the nearest edge of any closed ring."""
    a = np.concatenate(rings)
    b = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    return _distance_to_segments(p, a, b)


def _distance_to_segments(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance of each point to the nearest of the segments a[k] b[k] (chunked brute force)."""
    out = np.empty(len(p))
    step = max(1, 2_000_000 // len(a))
    ab = b - a
    ab2 = np.einsum("ij,ij->i", ab, ab)
    for s in range(0, len(p), step):
        q = p[s : s + step, None, :]
        t = np.clip(np.einsum("nmk,mk->nm", q - a, ab) / ab2, 0.0, 1.0)
        d2 = np.sum((q - a - t[..., None] * ab) ** 2, axis=2)
        out[s : s + step] = np.sqrt(d2.min(axis=1))
    return out


def _place_holes(
    rng: np.random.Generator,
    shell: FloatArray,
    n_holes: int,
    radius: tuple[float, float],
    clearance: float,
    kinds: Sequence[str] = ("star",),
) -> list[FloatArray]:
    """Up to ``n_holes`` clockwise holes inside ``shell``, each within a disc of the given radius
    range kept ``clearance`` away from the shell and from the other holes' discs."""
    lo, hi = shell.min(axis=0), shell.max(axis=0)
    discs: list[tuple[FloatArray, float]] = []
    holes: list[FloatArray] = []
    for _ in range(50 * max(n_holes, 1)):
        if len(holes) == n_holes:
            break
        c = rng.uniform(lo, hi)
        r = rng.uniform(*radius)
        if not _inside(c, shell):
            continue
        if _distance_to_rings(c[None], [shell])[0] < r + clearance:
            continue
        if any(np.hypot(*(c - c2)) < r + r2 + clearance for c2, r2 in discs):
            continue
        kind = kinds[int(rng.integers(len(kinds)))]
        if kind == "circle":
            n = max(12, int(round(2 * np.pi * r / (0.25 * radius[1]))))
            t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(0, 2 * np.pi)
            ring = np.column_stack([np.cos(t), np.sin(t)]) * r
        elif kind == "polygon":
            n = int(rng.integers(3, 7))
            t = np.linspace(0, 2 * np.pi, n, endpoint=False) + rng.uniform(0, 2 * np.pi)
            ring = np.column_stack([np.cos(t), np.sin(t)]) * r
        else:
            ring = _star_ring(rng, int(rng.integers(5, 13)), r / 1.6, 0.3, 0.4)
        discs.append((c, r))
        holes.append((c + ring)[::-1].copy())
    return holes


def _grid_outline(cells: NDArray[np.bool_]) -> FloatArray:
    """Counter-clockwise outline of a 4-connected, hole-free, pinch-free set of grid cells."""
    g = np.pad(cells, 1)
    nxt: dict[tuple[int, int], tuple[int, int]] = {}
    for i, j in zip(*np.nonzero(g), strict=True):
        i, j = int(i), int(j)
        if not g[i, j - 1]:
            nxt[(i, j)] = (i + 1, j)
        if not g[i + 1, j]:
            nxt[(i + 1, j)] = (i + 1, j + 1)
        if not g[i, j + 1]:
            nxt[(i + 1, j + 1)] = (i, j + 1)
        if not g[i - 1, j]:
            nxt[(i, j + 1)] = (i, j)
    start = min(nxt)
    loop = [start]
    while (q := nxt[loop[-1]]) != start:
        loop.append(q)
    if len(loop) != len(nxt):
        raise ShapeError("grid outline is not a single loop")
    v = np.array(loop, dtype=float)
    turn = _orient(np.roll(v, 1, axis=0), v, np.roll(v, -1, axis=0)) != 0
    return v[turn]


def _walk_cells(rng: np.random.Generator, grid: int, steps: int) -> NDArray[np.bool_]:
    """Cells visited by a random walk, made hole-free and pinch-free (no diagonal-only contact)."""
    from scipy.ndimage import binary_fill_holes

    cells = np.zeros((grid, grid), dtype=bool)
    moves = np.array([(1, 0), (-1, 0), (0, 1), (0, -1)])
    pos = np.array([grid // 2, grid // 2])
    cells[tuple(pos)] = True
    for m in rng.integers(0, 4, steps):
        pos = np.clip(pos + moves[m], 1, grid - 2)
        cells[tuple(pos)] = True
    while True:
        cells = binary_fill_holes(cells)
        a, b, c, d = cells[:-1, :-1], cells[1:, :-1], cells[:-1, 1:], cells[1:, 1:]
        pinch = (a & d & ~b & ~c) | (b & c & ~a & ~d)
        if not pinch.any():
            return cells
        i, j = np.nonzero(pinch)
        cells[i + 1, j] = True  # fill one of the two empty cells of each pinched 2x2 block
        cells[i, j] = True


def _walk_ring(rng: np.random.Generator, steps: int, jitter: float) -> FloatArray:
    grid = int(2 * math.sqrt(steps)) + 6
    outline = _grid_outline(_walk_cells(rng, grid, steps))
    # Subdivide long straight runs into unit pieces, then jitter every vertex: the outline stays
    # simple for jitter < 0.25 cell (non-adjacent edges of a pinch-free outline are >= 1 apart).
    pts = []
    for p, q in zip(outline, np.roll(outline, -1, axis=0), strict=True):
        n = int(round(np.hypot(*(q - p))))
        pts.append(p + np.outer(np.arange(n) / n, q - p))
    v = np.concatenate(pts)
    v = v + rng.uniform(-jitter, jitter, v.shape)
    return _normalise(v)[0]


# --------------------------------------------------------------------------------------------
# Families
# --------------------------------------------------------------------------------------------


def star(
    seed: int,
    *,
    n_vertices: int | None = None,
    irregularity: float = 0.5,
    spikiness: float = 0.4,
    n_holes: int = 0,
    hole_radius: tuple[float, float] = (0.08, 0.2),
    size: float = 0.08,
) -> Shape:
    """A star-shaped polygon around the origin, with holes.

    Parameters
    ----------
    seed : int
        Seed (non-negative).
    n_vertices : int, optional
        Number of shell vertices (default: random in 8-40).
    irregularity : float
        Spread of the angular gaps between vertices (0 = equal gaps, < 1).
    spikiness : float
        Amplitude of the radius noise, relative to the radius (0 = regular polygon).
    n_holes : int
        Holes (0-3 typical): star-shaped, each inside a disc of radius in ``hole_radius`` that
        keeps ``size`` away from the shell and the other holes.
    hole_radius : (float, float)
        Range of the holes' enclosing radii.
    size : float
        Suggested edge length (also the holes' clearance).
    """

    def build(rng: np.random.Generator) -> Shape | None:
        n = int(n_vertices) if n_vertices is not None else int(rng.integers(8, 41))
        shell = _normalise(_star_ring(rng, n, 1.0, irregularity, spikiness))[0]
        holes = _place_holes(rng, shell, n_holes, hole_radius, size)
        if len(holes) < n_holes:
            return None
        return Shape(shell, holes, family="star", seed=seed, size=size,
                     params={"n_vertices": n, "n_holes": n_holes, "spikiness": spikiness})

    return _retry("star", seed, build)


def walk(
    seed: int,
    *,
    steps: int | None = None,
    jitter: float = 0.2,
    n_holes: int = 0,
    hole_radius: tuple[float, float] = (0.06, 0.15),
    size: float = 0.06,
) -> Shape:
    """A random-walk outline: the boundary of the grid cells a random walk visits (not star-shaped).

    The walk's enclosed gaps are filled and diagonal-only contacts closed, so the outline is one
    simple loop with one-cell corridors and dead ends; each vertex is then jittered.

    Parameters
    ----------
    seed : int
        Seed.
    steps : int, optional
        Steps of the walk (default: random in 40-160); more steps, more detail.
    jitter : float
        Vertex jitter in cells (< 0.25 keeps the outline simple by construction).
    n_holes : int
        Holes, as in :func:`star`.
    hole_radius : (float, float)
        Range of the holes' enclosing radii.
    size : float
        Suggested edge length (also the holes' clearance).
    """

    def build(rng: np.random.Generator) -> Shape | None:
        k = int(steps) if steps is not None else int(rng.integers(40, 161))
        shell = _walk_ring(rng, k, jitter)
        holes = _place_holes(rng, shell, n_holes, hole_radius, size)
        if len(holes) < n_holes:
            return None
        return Shape(shell, holes, family="walk", seed=seed, size=size,
                     params={"steps": k, "n_holes": n_holes})

    return _retry("walk", seed, build)


def holes(seed: int, *, n_holes: int | None = None, size: float = 0.06) -> Shape:
    """A star or random-walk shell (chosen by the seed) with 1-3 holes (or ``n_holes``)."""
    rng = np.random.default_rng([seed, 10**6])
    k = int(n_holes) if n_holes is not None else int(rng.integers(1, 4))
    make = star if rng.random() < 0.5 else walk
    s = make(seed, n_holes=k, size=size)
    return Shape(s.shell, s.holes, family="holes", seed=seed, size=size, params=s.params)


def sharp(
    seed: int,
    *,
    min_angle: float = 5.0,
    max_angle: float = 30.0,
    n_spikes: int | None = None,
    n_notches: int | None = None,
    size: float = 0.06,
) -> Shape:
    """A rounded polygon with convex spikes and reflex notches of sharp angles.

    The first spike's tip is exactly ``min_angle`` degrees; the other spikes' tips and the
    notches' openings are uniform in ``[min_angle, max_angle]``.  Every other vertex angle is
    above ``min_angle``, so ``shape.min_angle == min_angle``.

    Parameters
    ----------
    seed : int
        Seed.
    min_angle, max_angle : float
        Range of the sharp angles, degrees (``0 < min_angle <= max_angle < 90``).
    n_spikes : int, optional
        Convex spikes (default: random 1-3).
    n_notches : int, optional
        Reflex notches, i.e. narrow cuts into the domain (default: random 0-2).
    size : float
        Suggested edge length.
    """
    if not 0 < min_angle <= max_angle < 90:
        raise ShapeError(f"sharp: need 0 < min_angle <= max_angle < 90, got {min_angle}, {max_angle}")

    def build(rng: np.random.Generator) -> Shape | None:
        ns = int(n_spikes) if n_spikes is not None else int(rng.integers(1, 4))
        nn = int(n_notches) if n_notches is not None else int(rng.integers(0, 3))
        n = int(rng.integers(max(8, ns + nn + 3), 16))
        base = _star_ring(rng, n, 0.6, 0.2, 0.15)
        edges = rng.choice(n, ns + nn, replace=False)
        angles = np.concatenate([[min_angle], rng.uniform(min_angle, max_angle, ns + nn - 1)])
        inserts: dict[int, FloatArray] = {}
        for k, (e, ang) in enumerate(zip(edges, angles, strict=True)):
            p, q = base[e], base[(e + 1) % n]
            t = (q - p) / np.hypot(*(q - p))
            normal = np.array([t[1], -t[0]])  # outward for a counter-clockwise ring
            length = rng.uniform(0.25, 0.6) if k < ns else -rng.uniform(0.15, 0.35)
            half = abs(length) * math.tan(math.radians(ang) / 2)
            if 2 * half > 0.8 * np.hypot(*(q - p)):
                return None
            mid = 0.5 * (p + q)
            inserts[int(e)] = np.array([mid - half * t, mid + length * normal, mid + half * t])
        ring = np.concatenate([np.vstack([base[i], inserts[i]]) if i in inserts else base[i : i + 1]
                               for i in range(n)])
        ring, scale, _ = _normalise(ring)
        if interior_angles(ring).min() < min_angle * (1 - 1e-9):
            return None
        return Shape(ring, [], family="sharp", seed=seed, size=size,
                     params={"min_angle": min_angle, "n_spikes": ns, "n_notches": nn})

    return _retry("sharp", seed, build)


def neck(
    seed: int,
    *,
    width: float = 0.06,
    fraction: tuple[float, float] = (0.3, 0.95),
    n_holes: int = 0,
    size: float | None = None,
) -> Shape:
    """Two lobes joined by a smoothly bent channel narrower than ``width``.

    The channel's two sides are parallel offsets of one centre line; their perpendicular
    distance is ``2 * half_width * cos(slope) <= 2 * half_width`` with the full width
    ``2 * half_width`` drawn uniformly in ``fraction * width``.

    Parameters
    ----------
    seed : int
        Seed.
    width : float
        Upper bound on the neck's width (the channel is strictly narrower).
    fraction : (float, float)
        Range of the channel width as a fraction of ``width`` (both < 1).
    n_holes : int
        Holes, placed in the lobes as in :func:`star`.
    size : float, optional
        Suggested edge length (default ``width``: the neck is narrower than h).
    """
    if not 0 < fraction[0] <= fraction[1] < 1:
        raise ShapeError(f"neck: fraction must satisfy 0 < lo <= hi < 1, got {fraction}")
    h = float(width if size is None else size)

    def build(rng: np.random.Generator) -> Shape | None:
        hw = 0.5 * width * rng.uniform(*fraction)
        r1, r2 = rng.uniform(0.3, 0.45, 2)
        c1, c2 = -0.55, 0.55
        x0, x1 = c1 + math.sqrt(r1**2 - hw**2), c2 - math.sqrt(r2**2 - hw**2)
        m = int(rng.integers(4, 12))
        xs = np.linspace(x0, x1, m + 2)
        # A smooth bend (zero at both ends) so the channel is a neck, not a row of sharp turns.
        amp = rng.uniform(-1, 1) * min(0.04, 0.05 * (x1 - x0))  # slope <= 0.1 pi
        bend = amp * np.sin(np.pi * int(rng.integers(1, 3)) * (xs - x0) / (x1 - x0))
        bottom = np.column_stack([xs, bend - hw])
        top = np.column_stack([xs[::-1], bend[::-1] + hw])

        def lobe(c: float, r: float, t0: float, t1: float) -> FloatArray:
            k = int(rng.integers(10, 25))
            t = np.linspace(t0, t1, k + 2)[1:-1]
            rr = r * (1 + 0.15 * rng.uniform(-1, 1, k))
            return np.column_stack([c + rr * np.cos(t), rr * np.sin(t)])

        a1, a2 = math.asin(hw / r1), math.asin(hw / r2)
        right = lobe(c2, r2, math.pi + a2, 3 * math.pi - a2)
        left = lobe(c1, r1, a1, 2 * math.pi - a1)
        shell = np.concatenate([bottom, right, top, left])
        hl = _place_holes(rng, shell, n_holes, (0.05, 0.12), max(h, 0.05))
        if len(hl) < n_holes:
            return None
        neck_width = float(_distance_to_segments(top, bottom[:-1], bottom[1:]).min())
        return Shape(shell, hl, family="neck", seed=seed, size=h,
                     params={"width": width, "neck_width": min(neck_width, 2 * hw),
                             "n_holes": n_holes})

    return _retry("neck", seed, build)


def duplicates(
    seed: int,
    *,
    gap: float = 1e-7,
    count: int | None = None,
    n_holes: int = 0,
    size: float = 0.08,
) -> Shape:
    """A star or random-walk outline with some vertices doubled ``gap * diameter`` apart.

    Each doubled vertex ``v`` gets a twin ``v + gap * diameter * u`` where ``u`` points along the
    next edge turned by at most 40 degrees (as GIS data do: no zero-length spike).

    Parameters
    ----------
    seed : int
        Seed.
    gap : float
        Distance of each twin, relative to the shell's bounding-box diagonal.
    count : int, optional
        Number of doubled vertices (default: random 1-3).
    n_holes : int
        Holes, as in :func:`star`.
    size : float
        Suggested edge length.
    """

    def build(rng: np.random.Generator) -> Shape | None:
        k = int(count) if count is not None else int(rng.integers(1, 4))
        base_seed = int(rng.integers(2**31))
        base = star(base_seed, n_holes=n_holes) if rng.random() < 0.5 else walk(base_seed, n_holes=n_holes)
        v = base.shell
        n = len(v)
        diam = float(np.hypot(*np.ptp(v, axis=0)))
        chosen = np.sort(rng.choice(n, min(k, n), replace=False))
        ang = interior_angles(v)
        out = []
        for i in range(n):
            out.append(v[i])
            if i in chosen:
                d = v[(i + 1) % n] - v[i]
                lim = min(40.0, ang[i] / 3, (360 - ang[i]) / 3)
                phi = math.radians(rng.uniform(-lim, lim))
                c, s = math.cos(phi), math.sin(phi)
                u = np.array([c * d[0] - s * d[1], s * d[0] + c * d[1]]) / np.hypot(*d)
                out.append(v[i] + gap * diam * u)
        return Shape(np.array(out), base.holes, family="duplicates", seed=seed, size=size,
                     params={"gap": gap, "count": len(chosen)})

    return _retry("duplicates", seed, build)


def _fractal_ring(rng: np.random.Generator, n_vertices: int, roughness: float, radius: float,
                  others: Sequence[FloatArray] = ()) -> FloatArray:
    """Midpoint displacement from a star polygon to exactly ``n_vertices`` vertices.

    Each level splits edges at their midpoint moved along the normal by ``roughness`` times the
    edge length times a standard normal draw; displacements that would make the ring (or it and
    ``others``) non-simple are halved, then dropped, so every level stays simple.
    """
    counts = [int(n_vertices)]
    while counts[-1] > 16:
        counts.append((counts[-1] + 1) // 2)
    counts.reverse()
    v = _star_ring(rng, counts[0], radius, 0.3, 0.3)
    if not _valid(v, islands=others):
        v = _star_ring(rng, counts[0], radius, 0.0, 0.0)
    for target in counts[1:]:
        n = len(v)
        a, b = v, np.roll(v, -1, axis=0)
        length = np.hypot(*(b - a).T)
        split = np.sort(np.argsort(-length, kind="stable")[: target - n])
        normal = np.column_stack([(b - a)[:, 1], -(b - a)[:, 0]])[split]
        disp = roughness * np.clip(rng.normal(0, 1, len(split)), -2.0, 2.0)
        mids = 0.5 * (a + b)[split]
        pos = split + np.arange(1, len(split) + 1)  # index of each new vertex in the new ring
        for _ in range(12):
            new = np.insert(v, split + 1, mids + disp[:, None] * normal, axis=0)
            bad = bad_segments([new, *others])[0]
            if not len(bad):
                break
            touched = np.isin(pos, bad) | np.isin(pos - 1, bad)
            if not touched.any():
                return v  # the old ring meets ``others``: give up on this level
            disp[touched] *= 0.5 if _ < 8 else 0.0
        else:
            new = np.insert(v, split + 1, mids, axis=0)
        v = new
    return v


def coastline(
    seed: int,
    *,
    n_vertices: int = 2000,
    roughness: float = 0.2,
    n_islands: int = 3,
    island_vertices: int = 120,
    strait: float = 0.05,
    fraction: tuple[float, float] = (0.3, 0.9),
    water: bool = False,
    size: float | None = None,
) -> Shape:
    """A fractal coastline: a mainland, and islands separated from it by straits.

    The mainland (about 1.8 across) is a midpoint-displacement ring of exactly ``n_vertices``
    vertices; each island is a smaller fractal ring placed off the coast so that its distance to
    the mainland (the strait) is ``strait * uniform(fraction)``, narrower than ``strait``.

    Parameters
    ----------
    seed : int
        Seed.
    n_vertices : int
        Vertices of the mainland.
    roughness : float
        Midpoint displacement relative to the edge length (0.1 smooth, 0.3 very rough).
    n_islands : int
        Number of islands.
    island_vertices : int
        Vertices of each island.
    strait : float
        Upper bound of every strait's width (use the mesh size h to get straits narrower than h).
    fraction : (float, float)
        Range of the strait widths relative to ``strait`` (< 1).
    water : bool
        False: the land (shell = mainland, islands as further components).  True: the sea, a
        rectangle around everything with the mainland and islands as holes, so the straits are
        narrow channels of the domain.
    size : float, optional
        Suggested edge length (default ``strait``).
    """
    h = float(strait if size is None else size)

    def build(rng: np.random.Generator) -> Shape | None:
        main = _normalise(_fractal_ring(rng, n_vertices, roughness, 1.0), 1.8)[0]
        islands: list[FloatArray] = []
        widths: list[float] = []
        for _ in range(20 * n_islands):
            if len(islands) == n_islands:
                break
            k = int(rng.integers(len(main)))
            p, q = main[k], main[(k + 1) % len(main)]
            out = np.array([(q - p)[1], -(q - p)[0]]) / np.hypot(*(q - p))
            r = rng.uniform(0.06, 0.15)
            isl = _fractal_ring(rng, island_vertices, roughness, 1.0)
            isl = isl / np.abs(isl).max() * r
            target = strait * rng.uniform(*fraction)
            anchor = 0.5 * (p + q)
            c = anchor + out * (r + target)
            for _ in range(8):  # slide the island along ``out`` until the strait is ``target``
                gap = _signed_gap(isl + c, main)
                if abs(gap - target) < 1e-3 * target:
                    break
                c = c - out * (gap - target)
            cand = isl + c
            gap = _signed_gap(cand, main)
            if not (0.5 * fraction[0] * strait <= gap < strait):
                continue
            if islands and _distance_to_rings(cand, islands).min() < strait:
                continue
            if not _valid(main, islands=[*islands, cand]):
                continue
            islands.append(cand)
            widths.append(gap)
        if len(islands) < n_islands:
            return None
        params = {"n_vertices": n_vertices, "roughness": roughness, "strait": strait,
                  "strait_widths": widths, "water": water}
        if water:
            lo = np.concatenate([main, *islands]).min(axis=0) - 0.2
            hi = np.concatenate([main, *islands]).max(axis=0) + 0.2
            box = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])
            return Shape(box, [r[::-1].copy() for r in [main, *islands]], family="coastline",
                         seed=seed, size=h, params=params)
        return Shape(main, [], islands, family="coastline", seed=seed, size=h, params=params)

    return _retry("coastline", seed, build)


def _signed_gap(ring: FloatArray, main: FloatArray) -> float:
    """Distance between ``ring`` and ``main``; negative if a vertex of ``ring`` is inside ``main``."""
    d = _distance_to_rings(ring, [main])
    k = int(np.argmin(d))
    return -float(d[k]) if _inside(ring[k], main) else float(d[k])


def large(seed: int, *, n_vertices: int = 20_000, roughness: float = 0.2, size: float = 0.02) -> Shape:
    """A fractal outline with exactly ``n_vertices`` vertices and no islands (speed tests).

    Parameters
    ----------
    seed : int
        Seed.
    n_vertices : int
        Number of vertices.
    roughness : float
        As in :func:`coastline`.
    size : float
        Suggested edge length.
    """

    def build(rng: np.random.Generator) -> Shape | None:
        ring = _normalise(_fractal_ring(rng, n_vertices, roughness, 1.0))[0]
        return Shape(ring, [], family="large", seed=seed, size=size,
                     params={"n_vertices": n_vertices, "roughness": roughness})

    return _retry("large", seed, build)


def plates(
    seed: int,
    *,
    width: float = 2.0,
    height: float = 1.0,
    n_holes: int | None = None,
    radius: tuple[float, float] = (0.05, 0.2),
    clearance: float = 0.05,
    size: float = 0.05,
) -> Shape:
    """A perforated plate: the rectangle [0, width] x [0, height] with circular and polygonal holes.

    Parameters
    ----------
    seed : int
        Seed.
    width, height : float
        The plate.
    n_holes : int, optional
        Number of holes (default: random 2-8).  Each is a polygonal circle (at least 12
        segments) or a regular 3-6-gon, inscribed in a disc of radius in ``radius``.
    radius : (float, float)
        Range of the holes' enclosing radii.
    clearance : float
        Minimum distance between the discs and from a disc to the plate's edges.
    size : float
        Suggested edge length.
    """

    def build(rng: np.random.Generator) -> Shape | None:
        k = int(n_holes) if n_holes is not None else int(rng.integers(2, 9))
        shell = np.array([[0.0, 0.0], [width, 0.0], [width, height], [0.0, height]])
        hl = _place_holes(rng, shell, k, radius, clearance, kinds=("circle", "circle", "polygon"))
        if len(hl) < k:
            return None
        return Shape(shell, hl, family="plates", seed=seed, size=size,
                     params={"n_holes": k, "width": width, "height": height})

    return _retry("plates", seed, build)


def naca4(code: str, n_points: int = 100, closed: bool = True) -> FloatArray:
    """A NACA 4-digit profile of unit chord, counter-clockwise, leading edge at the origin.

    Parameters
    ----------
    code : str
        Four digits ``MPTT``: camber M %, its position P tenths of chord, thickness TT %.
    n_points : int
        Points per side (cosine spacing, fine at both edges).
    closed : bool
        True: sharp trailing edge (coefficient -0.1036).  False: the original thin blunt
        trailing edge (-0.1015; thickness about 0.2 % of the chord per 10 % of thickness).

    Examples
    --------
    >>> naca4("0012", 50).shape
    (98, 2)
    """
    if len(code) != 4 or not code.isdigit():
        raise ShapeError(f"a NACA 4-digit code has four digits, got {code!r}")
    m, p, t = int(code[0]) / 100, int(code[1]) / 10, int(code[2:]) / 100
    if t <= 0 or (m > 0 and not 0 < p < 1):
        raise ShapeError(f"NACA {code}: thickness must be > 0 and camber position in 1-9")
    beta = np.linspace(0.0, np.pi, n_points)
    x = 0.5 * (1 - np.cos(beta))
    last = -0.1036 if closed else -0.1015
    yt = 5 * t * (0.2969 * np.sqrt(x) - 0.1260 * x - 0.3516 * x**2 + 0.2843 * x**3 + last * x**4)
    if m > 0:
        yc = np.where(x < p, m / p**2 * (2 * p * x - x**2), m / (1 - p) ** 2 * (1 - 2 * p + 2 * p * x - x**2))
        dyc = np.where(x < p, 2 * m / p**2 * (p - x), 2 * m / (1 - p) ** 2 * (p - x))
    else:
        yc = dyc = np.zeros_like(x)
    th = np.arctan(dyc)
    upper = np.column_stack([x - yt * np.sin(th), yc + yt * np.cos(th)])
    lower = np.column_stack([x + yt * np.sin(th), yc - yt * np.cos(th)])
    if closed:
        # Upper surface from the trailing edge to the leading edge, lower surface back.
        return np.concatenate([upper[::-1], lower[1:-1]])
    return np.concatenate([upper[::-1], lower[1:]])


def airfoil(
    seed: int,
    *,
    code: str | None = None,
    n_points: int = 80,
    closed: bool | None = None,
    angle: float | None = None,
    box: tuple[float, float, float, float] = (-1.0, -1.0, 2.0, 1.0),
    size: float = 0.05,
) -> Shape:
    """A NACA 4-digit airfoil of unit chord as a hole in a box.

    Parameters
    ----------
    seed : int
        Seed (draws what is not given).
    code : str, optional
        NACA code (default: camber 0-6 %, position 2-6, thickness 6-18 %).
    n_points : int
        Points per side of the profile.
    closed : bool, optional
        Sharp (True) or thin blunt (False) trailing edge (default: random, sharp 2 times in 3).
    angle : float, optional
        Angle of attack in degrees, about the quarter chord (default: uniform in -10-15).
    box : (xmin, ymin, xmax, ymax)
        The outer boundary; the leading edge is at the origin.
    size : float
        Suggested edge length.
    """

    def build(rng: np.random.Generator) -> Shape | None:
        c = code or f"{rng.integers(0, 7)}{rng.integers(2, 7)}{rng.integers(6, 19):02d}"
        cl = bool(closed) if closed is not None else bool(rng.random() < 2 / 3)
        aoa = float(angle) if angle is not None else float(rng.uniform(-10, 15))
        prof = naca4(c, n_points, cl) - [0.25, 0.0]
        ca, sa = math.cos(math.radians(-aoa)), math.sin(math.radians(-aoa))
        prof = prof @ np.array([[ca, sa], [-sa, ca]]) + [0.25, 0.0]
        x0, y0, x1, y1 = box
        shell = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)
        return Shape(shell, [prof[::-1].copy()], family="airfoil", seed=seed, size=size,
                     params={"code": c, "closed": cl, "angle": aoa})

    return _retry("airfoil", seed, build)


#: Every family by name: ``FAMILIES[name](seed, **params) -> Shape``.
FAMILIES: dict[str, Callable[..., Shape]] = {
    "star": star,
    "walk": walk,
    "holes": holes,
    "sharp": sharp,
    "neck": neck,
    "duplicates": duplicates,
    "coastline": coastline,
    "large": large,
    "plates": plates,
    "airfoil": airfoil,
}


def family(name: str, count: int, seed: int = 0, **params: Any) -> Iterator[Shape]:
    """``count`` shapes of one family, with seeds ``seed, seed + 1, ..., seed + count - 1``.

    Shape ``k`` is ``FAMILIES[name](seed + k, **params)``, so any one of them is reproducible
    from its ``shape.seed``.

    Examples
    --------
    >>> [s.seed for s in family("plates", 3, seed=10)]
    [10, 11, 12]
    """
    if name not in FAMILIES:
        raise ShapeError(f"unknown shape family {name!r}; choose from {', '.join(FAMILIES)}")
    if not isinstance(count, (int, np.integer)) or count < 0:
        raise ShapeError(f"count must be a non-negative integer, got {count!r}")
    make = FAMILIES[name]
    for k in range(int(count)):
        yield make(int(seed) + k, **params)


# --------------------------------------------------------------------------------------------
# Export
# --------------------------------------------------------------------------------------------


def _rings_of(shape: Shape | ArrayLike, holes: Sequence[ArrayLike]) -> list[list[FloatArray]]:
    if isinstance(shape, Shape):
        return [[shape.shell, *shape.holes]] + [[s] for s in shape.islands]
    return [[np.asarray(shape, dtype=float), *(np.asarray(h, dtype=float) for h in holes)]]


def _closed(ring: FloatArray) -> list[list[float]]:
    r = ring.tolist()
    return [*r, r[0]]


def to_geojson(shape: Shape | ArrayLike, holes: Sequence[ArrayLike] = ()) -> dict[str, Any]:
    """A GeoJSON geometry (nested lists, rings closed): Polygon, or MultiPolygon with islands.

    Accepts a :class:`Shape`, or a shell and its holes.

    Examples
    --------
    >>> to_geojson([(0, 0), (1, 0), (0, 1)])
    {'type': 'Polygon', 'coordinates': [[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]]}
    """
    parts = [[_closed(r) for r in part] for part in _rings_of(shape, holes)]
    if len(parts) == 1:
        return {"type": "Polygon", "coordinates": parts[0]}
    return {"type": "MultiPolygon", "coordinates": parts}


def to_wkt(shape: Shape | ArrayLike, holes: Sequence[ArrayLike] = ()) -> str:
    """WKT text (POLYGON, or MULTIPOLYGON with islands) with round-trip exact coordinates.

    Examples
    --------
    >>> to_wkt([(0, 0), (1, 0), (0, 1)])
    'POLYGON ((0.0 0.0, 1.0 0.0, 0.0 1.0, 0.0 0.0))'
    """

    def ring(r: FloatArray) -> str:
        return "(" + ", ".join(f"{x!r} {y!r}" for x, y in _closed(r)) + ")"

    def poly(part: list[FloatArray]) -> str:
        return "(" + ", ".join(ring(r) for r in part) + ")"

    parts = _rings_of(shape, holes)
    if len(parts) == 1:
        return "POLYGON " + poly(parts[0])
    return "MULTIPOLYGON (" + ", ".join(poly(p) for p in parts) + ")"


__all__ = [
    "FAMILIES",
    "Shape",
    "ShapeError",
    "airfoil",
    "bad_segments",
    "coastline",
    "duplicates",
    "family",
    "holes",
    "interior_angles",
    "large",
    "naca4",
    "neck",
    "plates",
    "segment_distances",
    "shape_problems",
    "sharp",
    "signed_area",
    "star",
    "to_geojson",
    "to_wkt",
    "walk",
]
