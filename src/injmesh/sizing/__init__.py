"""The target edge length h(p): validation, size fields from data, feature size, gradation.

A size is a positive number (uniform mesh) or a callable ``h(p)`` that takes an ``(n, 2)`` array
of points and returns ``(n,)`` positive lengths in the units of the domain.  This package turns
what the user gives into a validated :class:`SizeFunction` and builds sizes from data and from
the geometry:

- :class:`GriddedSize` (a raster, bilinear) and :class:`ScatteredSize` (samples, linear on their
  Delaunay triangulation);
- :func:`limit_gradation`: |grad h| <= rate (Persson 2006, fast marching on a background grid);
- :func:`feature_size`: the local thickness of the domain, from its medial axis;
- :func:`effective_size`: ``min(h, feature_size / layers)``, gradation-limited;
- :func:`inside_only` / :meth:`SizeFunction.restricted`: h evaluated only inside the domain.

Every sampling of a user's h by this package is at points inside the domain or on its boundary.
"""

from ._core import SizeError, SizeFunction, SizeLike, as_size_function, inside_only
from .features import effective_size, feature_size
from .fields import GriddedSize, ScatteredSize
from .gradation import limit_gradation

__all__ = [
    "GriddedSize",
    "ScatteredSize",
    "SizeError",
    "SizeFunction",
    "SizeLike",
    "as_size_function",
    "effective_size",
    "feature_size",
    "inside_only",
    "limit_gradation",
]
