"""The Domain base class: a region of the plane known by its signed distance function.

Conventions
-----------
Points are ``(n, 2)`` float64 rows.  ``d(p) < 0`` inside, ``> 0`` outside; the boundary is where
d changes sign (not merely where it is zero: the paper's L-shape is zero along an interior line).
Boundary loops are closed polylines ``(k, 2)`` (last vertex not repeated) with the domain on their
left: the outer boundary runs counter-clockwise, holes clockwise.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .. import _tolerances as tol

if TYPE_CHECKING:
    from .csg import Difference, Intersection, Union

FloatArray = NDArray[np.float64]
BBox = tuple[float, float, float, float]


class GeometryError(ValueError):
    """A domain is invalid: empty, unbounded in its box, or its d is malformed."""


def as_points(p: object) -> FloatArray:
    """Return ``p`` as an ``(n, 2)`` float64 array, raising a clear error otherwise."""
    a = np.asarray(p, dtype=float)
    if a.ndim == 1 and a.shape[0] == 2:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {a.shape}")
    return a


def dedupe_points(p: FloatArray, eps: float) -> FloatArray:
    """``p (n, 2)`` without the points within ``eps`` of an earlier one (order kept)."""
    from scipy.spatial import cKDTree

    if len(p) < 2:
        return p
    pairs = cKDTree(p).query_pairs(eps, output_type="ndarray")
    drop = np.zeros(len(p), dtype=bool)
    drop[pairs.max(axis=1)] = True
    return p[~drop]


def ring_next(a: NDArray[Any]) -> NDArray[Any]:
    """``np.roll(a, -1, axis=0)``: each row's successor round a closed loop.  The ring loops of
    polygon building and cleaning and of Step 1 shift short arrays many times per mesh, where
    np.roll's general-axis handling cost more than the copy (about a third of cleaning a small
    polygon)."""
    return np.concatenate((a[1:], a[:1]))


def ring_prev(a: NDArray[Any]) -> NDArray[Any]:
    """``np.roll(a, 1, axis=0)``: each row's predecessor round a closed loop."""
    return np.concatenate((a[-1:], a[:-1]))


#: :meth:`Domain.kernel_boundary`: ``(kind, shape, origin, g)``.
KernelBoundary = tuple[int, FloatArray, FloatArray, tuple[Any, ...]]


class Domain(ABC):
    """A 2-D region given by its signed distance function.

    Subclasses implement :meth:`sdf` and :attr:`bbox`; they override :meth:`corners`,
    :meth:`project` and :meth:`boundary_loops` when they know them exactly.  Domains compose with
    ``a | b`` (union), ``a & b`` (intersection) and ``a - b`` (difference).

    Examples
    --------
    >>> from injmesh import Circle, Rectangle
    >>> ring = Circle((0, 0), 1) - Circle((0, 0), 0.2)
    >>> ring.sdf([[0.5, 0.0]]).round(3)
    array([-0.3])
    """

    @abstractmethod
    def sdf(self, p: FloatArray) -> FloatArray:
        """Signed distance of each point, ``(n,)``: negative inside."""

    @property
    @abstractmethod
    def bbox(self) -> BBox:
        """``(xmin, ymin, xmax, ymax)``, a box that contains the domain."""

    def __call__(self, p: FloatArray) -> FloatArray:
        return self.sdf(p)

    #: True when :meth:`sdf` is an exact signed distance (1-Lipschitz), which some shortcuts
    #: rely on; a plain callable makes no such promise.
    exact_distance: bool = False

    @property
    def diameter(self) -> float:
        """Length of the bounding box's diagonal: the scale of relative tolerances."""
        x0, y0, x1, y1 = self.bbox
        return float(np.hypot(x1 - x0, y1 - y0))

    def corners(self) -> FloatArray:
        """Sharp corners of the boundary, ``(k, 2)``; they stay fixed while meshing."""
        return np.empty((0, 2))

    def kernel_boundary(self) -> KernelBoundary | None:
        """The boundary in the form compiled kernels query themselves
        (:func:`injmesh.kernels.smooth.boundary_query`), giving the numbers :meth:`sdf` and
        :meth:`project` give; None (the default) when those are only known through the
        methods.

        ``(kind, shape, origin, g)``: a B-rep (kind 0, ``origin`` and ``g`` its
        :meth:`~injmesh.geometry.brep.BRep.kernel_data`), a circle (1, ``shape = (cx, cy,
        r)``) or an axis-aligned rectangle (2, ``shape = (x0, y0, x1, y1)``).
        """
        return None

    def gradient(self, p: FloatArray) -> FloatArray:
        """Gradient of d by central differences, ``(n, 2)``.

        The four offsets go to d in one call (d is evaluated point by point: the same values
        as four calls, a quarter of a plain Python d's per-call cost)."""
        p = as_points(p)
        n = len(p)
        eps = tol.GRADIENT_STEP * self.diameter
        dx = np.array([eps, 0.0])
        dy = np.array([0.0, eps])
        d = self.sdf(np.concatenate([p + dx, p - dx, p + dy, p - dy]))
        return np.stack(
            [
                (d[:n] - d[n:2 * n]) / (2 * eps),
                (d[2 * n:3 * n] - d[3 * n:]) / (2 * eps),
            ],
            axis=1,
        )

    def project(self, p: FloatArray) -> FloatArray:
        """Move points onto the boundary by Eq. (3.2), ``p - d grad d``, iterated.

        The step is divided by ``|grad d|^2`` (a Newton step), so functions that are not exact
        distances but vanish on the boundary also project correctly.  The gradient is a forward
        difference from the d already known (two evaluations of d, not four) and is kept for
        the next step wherever |d| fell at least tenfold (the chord method).

        The points of one call to d are stacked: d at the points and at their two offsets in
        the first call, both offsets in one call after that.  The values are d's at the same
        points (d is evaluated point by point), in a third of the calls: a plain Python d on a
        few hundred sliding nodes costs its call, not its points (on the paper's four-hole
        square, 5.2 calls per projection became 3.0).
        """
        p = as_points(p).copy()
        n = len(p)
        diameter = self.diameter
        stop = tol.PROJECTION_TOL * diameter
        eps = tol.GRADIENT_STEP * diameter
        ex, ey = np.array([eps, 0.0]), np.array([0.0, eps])
        active = np.arange(n)
        # d and its forward differences at every point: nearly all of them move (they are
        # a step's targets, off the boundary), so the gradient is needed anyway.
        d3 = self.sdf(np.concatenate([p, p + ex, p + ey]))
        d = d3[:n]
        g = np.stack([(d3[n:2 * n] - d) / eps, (d3[2 * n:] - d) / eps], axis=1)
        stale = np.zeros(n, dtype=bool)
        # While every point still moves (usually the first step), the same arithmetic runs on
        # the whole arrays instead of gathered and scattered copies: a projection of a few
        # dozen sliding nodes costs its NumPy calls more than its points.
        everyone = True
        for _ in range(tol.PROJECTION_ITERATIONS):
            moving = np.abs(d) > stop
            if not (everyone and moving.all()):
                everyone = False
                active, d, g, stale = active[moving], d[moving], g[moving], stale[moving]
                if len(active) == 0:
                    break
            if stale.any():
                q, dq = p[active[stale]], d[stale]
                k = len(q)
                d2 = self.sdf(np.concatenate([q + ex, q + ey]))
                g[stale] = np.stack([(d2[:k] - dq) / eps, (d2[k:] - dq) / eps], axis=1)
            g2 = np.maximum(np.einsum("ij,ij->i", g, g), 1e-30)
            if everyone:
                p -= (d / g2)[:, None] * g
                d_new = self.sdf(p)
            else:
                p[active] -= (d / g2)[:, None] * g
                d_new = self.sdf(p[active])
            stale = np.abs(d_new) > 0.1 * np.abs(d)
            d = d_new
        return p

    def on_boundary(self, p: FloatArray) -> NDArray[np.bool_]:
        """Whether each point is on the boundary: d is near zero *and* changes sign around it.

        The sign test matters for functions such as the paper's L-shape, which vanish along an
        interior line.
        """
        p = as_points(p)
        r = tol.ON_BOUNDARY * self.diameter
        ang = np.linspace(0, 2 * np.pi, 8, endpoint=False)
        ring = (p[:, None, :] + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)).reshape(-1, 2)
        d = self.sdf(ring).reshape(len(p), -1)
        return (np.abs(self.sdf(p)) < r) & (d.min(axis=1) <= 0) & (d.max(axis=1) > 0)

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        """Closed polylines of the boundary with vertices at most about ``spacing`` apart.

        The generic version traces the sign change of d on a grid (marching squares) and projects
        the vertices onto the boundary; primitives override it with exact loops.
        """
        from .tracing import trace_loops

        loops = trace_loops(self.sdf, self.bbox, spacing)
        return [self.project(loop) for loop in loops]

    def cleaned(
        self, tolerance: float, *, min_feature: float | None = None, max_area: float | None = None
    ) -> tuple[Domain, dict[str, int]]:
        """This domain with defects smaller than ``tolerance`` removed, and what was changed.

        Subclasses with an explicit boundary (polygons, exact set operations) merge vertices
        closer than ``tolerance``, drop zero-length edges and collinear spikes and fix the
        orientation, and cut the outline where it comes within ``min_feature`` of itself
        (:meth:`Polygon.cleaned <injmesh.geometry.Polygon.cleaned>`); the report counts each
        change.  The base class changes nothing.

        Returns
        -------
        (Domain, dict)
            The cleaned domain and counts of the changes (empty when nothing applies).

        Examples
        --------
        >>> from injmesh import Polygon
        >>> p = Polygon([(0, 0), (1, 0), (1.0000005, 0.0000006), (0.6, 1), (0, 1)])
        >>> p.cleaned(1e-5)[1]["merged_vertices"]
        1
        """
        return self, {}

    def __or__(self, other: Domain) -> Union:
        from .csg import Union

        return Union(self, _check(other))

    def __and__(self, other: Domain) -> Intersection:
        from .csg import Intersection

        return Intersection(self, _check(other))

    def __sub__(self, other: Domain) -> Difference:
        from .csg import Difference

        return Difference(self, _check(other))


def _check(other: object) -> Domain:
    if not isinstance(other, Domain):
        raise TypeError(f"cannot combine a Domain with {type(other).__name__}")
    return other
