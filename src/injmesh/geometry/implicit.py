"""Any plain callable d(p) as a domain."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike

from .base import BBox, Domain, FloatArray, GeometryError, as_points
from .tracing import corner_brackets, grid_spacing, refine_corners, trace_loops

#: Tracings an :class:`Implicit` keeps (by spacing; the oldest is dropped first).
TRACINGS_KEPT = 4


class Implicit(Domain):
    """A domain given only by a signed distance function ``d(p)``.

    Its boundary curves (outer boundary and every hole) are traced from the sign changes of d;
    sharp corners are detected from the traced curves and snapped to ``fixed_points`` when one is
    near.  Projection is Eq. (3.2) with a finite-difference gradient.

    Parameters
    ----------
    d : callable
        ``d(p) -> (n,)`` for ``p`` of shape ``(n, 2)``, negative inside.
    bbox : (xmin, ymin, xmax, ymax)
        A box that contains the domain.
    fixed_points : (k, 2) array_like, optional
        Points that must be nodes of the mesh; those on the boundary are treated as corners.

    Examples
    --------
    >>> import numpy as np
    >>> disc = Implicit(lambda p: np.hypot(p[:, 0], p[:, 1]) - 1, bbox=(-1, -1, 1, 1))
    >>> disc.sdf(np.array([[0.0, 0.0]]))
    array([-1.])
    """

    def __init__(
        self,
        d: Callable[[FloatArray], FloatArray],
        bbox: ArrayLike,
        fixed_points: ArrayLike | None = None,
    ) -> None:
        if not callable(d):
            raise TypeError(f"a domain must be a Domain or a callable d(p), got {type(d).__name__}")
        box = np.asarray(bbox, dtype=float).reshape(-1)
        if box.shape != (4,) or not np.all(np.isfinite(box)):
            raise GeometryError(f"bbox must be four finite numbers (xmin, ymin, xmax, ymax), got {bbox!r}")
        if not (box[2] > box[0] and box[3] > box[1]):
            raise GeometryError(f"bbox must have xmin < xmax and ymin < ymax, got {tuple(box.tolist())}")
        self._d = d
        self._bbox: BBox = (float(box[0]), float(box[1]), float(box[2]), float(box[3]))
        self.fixed_points = (
            np.empty((0, 2)) if fixed_points is None else as_points(fixed_points).copy()
        )
        self._corners: FloatArray | None = None
        self._traced: dict[float, list[FloatArray]] = {}
        self._probe()

    def __repr__(self) -> str:
        name = getattr(self._d, "__name__", type(self._d).__name__)
        return f"Implicit({name}, bbox={self._bbox})"

    def _probe(self) -> None:
        x0, y0, x1, y1 = self._bbox
        p = np.array([[x0, y0], [x1, y1], [0.5 * (x0 + x1), 0.5 * (y0 + y1)]])
        self.sdf(p)

    @property
    def bbox(self) -> BBox:
        return self._bbox

    def sdf(self, p: FloatArray) -> FloatArray:
        p = as_points(p)
        try:
            d = np.asarray(self._d(p), dtype=float)
        except (TypeError, ValueError, IndexError) as exc:
            raise TypeError(f"the distance function failed on an (n, 2) array of points: {exc}") from exc
        if d.shape != (len(p),):
            raise GeometryError(
                f"the distance function must return shape ({len(p)},) for {len(p)} points, "
                f"got shape {d.shape}"
            )
        if not np.all(np.isfinite(d)):
            i = int(np.argmax(~np.isfinite(d)))
            raise GeometryError(
                f"the distance function is not finite at {tuple(p[i].tolist())}: {float(d[i])}"
            )
        return d

    def corners(self) -> FloatArray:
        """The boundary fixed points, plus the sharp corners found on the traced boundary (refined)
        that are not within 2 tracing spacings of one."""
        if self._corners is None:
            spacing = grid_spacing(self._bbox, np.inf)
            brackets = [corner_brackets(loop, spacing) for loop in self.boundary_loops(spacing)]
            found, a, b = (np.concatenate([br[k] for br in brackets]) if brackets else np.empty((0, 2))
                           for k in range(3))
            fixed = self.fixed_points[self.on_boundary(self.fixed_points)] if len(
                self.fixed_points) else self.fixed_points
            if len(found) and len(fixed):
                # A user's point near a detected corner is the exact corner: the corner found
                # within 2 spacings of it (before the bisection, which costs about 50
                # projections, or after it) is dropped.  Where the user gives every corner (the
                # paper's cases) nothing is left to refine.
                far = _distance_to(found, fixed) > 2 * spacing
                a, b = a[far], b[far]
            # The brackets of all loops are refined together: one bisection, not one per loop.
            c = refine_corners(self, a, b)
            if len(c) and len(fixed):
                c = c[_distance_to(c, fixed) > 2 * spacing]
            self._corners = np.concatenate([fixed, c])
        return self._corners.copy()

    def boundary_loops(self, spacing: float) -> list[FloatArray]:
        # corners() traces at grid_spacing(bbox, inf) and Step 1 at grid_spacing(bbox, h_min):
        # the same spacing whenever h_min / TRACE_PER_H is above diameter / TRACE_MIN_CELLS (all
        # six paper cases), where the second tracing (grid, marching squares, projection:
        # ~4 ms of a 100-node mesh) would repeat the first.  d is a function of the point
        # alone, so the last few tracings (the size probe asks another spacing in between) are
        # kept by spacing and handed out as copies: the same loops.
        loops = self._traced.get(spacing)
        if loops is None:
            loops = [self.project(loop) for loop in trace_loops(self.sdf, self._bbox, spacing)]
            # A new dict, assigned at once: threads meshing the same domain see one or the other.
            kept = dict(list(self._traced.items())[1 - TRACINGS_KEPT:])
            kept[spacing] = loops
            self._traced = kept
        return [loop.copy() for loop in loops]


def _distance_to(p: FloatArray, q: FloatArray) -> FloatArray:
    """Distance from each point of ``p (n, 2)`` to the nearest point of ``q (m, 2)``."""
    return np.asarray(np.hypot(*(p[:, None, :] - q[None, :, :]).transpose(2, 0, 1)).min(axis=1))


def _check_extent(domain: Domain) -> None:
    """Raise when a domain's box has no area: an intersection of shapes whose boxes do not
    overlap is empty, and every grid over such a box has no cell (or a negative count)."""
    x0, y0, x1, y1 = (float(v) for v in domain.bbox)
    if not (x1 > x0 and y1 > y0):
        raise GeometryError(
            f"the domain is empty: its bounding box ({x0:.6g}, {y0:.6g}, {x1:.6g}, {y1:.6g}) has "
            "no area (an intersection of shapes that do not overlap?)")
    if getattr(domain, "is_empty", False) is True:
        raise GeometryError(
            f"the domain is empty: {domain!r} leaves nothing (shapes that do not overlap, or a "
            "difference that removes all of a shape)")


def as_domain(
    domain: Domain | Callable[[FloatArray], FloatArray] | object,
    bbox: ArrayLike | None = None,
    fixed_points: ArrayLike | None = None,
) -> Domain:
    """Return ``domain`` as a :class:`Domain`, wrapping a plain callable in :class:`Implicit`.

    Anything else is converted by :func:`injmesh.geometry.convert.to_domain`: shapely and other
    ``__geo_interface__`` geometries, GeoJSON dicts or text, WKT text, ``(n, 2)`` vertices.

    Raises
    ------
    TypeError
        ``domain`` is none of these, or is a callable given without ``bbox``.
    """
    if isinstance(domain, Domain):
        _check_extent(domain)
        return domain
    if not callable(domain):
        from .convert import to_domain

        return to_domain(domain)
    if bbox is None:
        raise TypeError("a callable domain needs bbox=(xmin, ymin, xmax, ymax)")
    return Implicit(domain, bbox, fixed_points)
