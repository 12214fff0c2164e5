"""Gradation limiting: the largest size below h whose gradient is at most a given rate.

After P.-O. Persson, "Mesh size functions for implicit geometries and PDE-based gradient
limiting", Engineering with Computers 22 (2006): h is sampled on a background grid and replaced
by the steady state of dh/dt + min(|grad h|, g) = g (Persson's eq. 9), computed exactly on the
grid by fast marching (:mod:`injmesh.kernels.fastmarch`).  The result is the largest grid
function h' <= h whose upwind gradient satisfies |grad h'| <= g at every node: a size that
changes faster than g (a jump, a point refinement, a steep user formula) is lowered around the
small sizes until neighbouring elements differ by at most a factor of about 1 + g, so they stay
well shaped.  Where h already satisfies the limit it is returned unchanged.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Domain, as_domain
from ._core import SizeError, SizeLike, as_size_function
from .background import DEFAULT_MAX_CELLS, Background, check_grid_options, sampled_grid
from .fields import GriddedSize

FloatArray = NDArray[np.float64]


def check_rate(rate: float) -> float:
    """Validate a gradation rate: a positive finite number."""
    if isinstance(rate, (bool, np.bool_)) or not isinstance(rate, (int, float, np.number)):
        raise SizeError(f"the gradation rate must be a positive number, got {rate!r}")
    if not (math.isfinite(float(rate)) and rate > 0):
        raise SizeError(f"the gradation rate must be positive and finite, got {rate!r}")
    return float(rate)


def limit_grid(values: FloatArray, grid: Background, rate: float) -> FloatArray:
    """Gradient-limit sizes on the background grid; ``inf`` nodes take the limited value."""
    from ..kernels.fastmarch import limit_gradient

    out: FloatArray = limit_gradient(np.ascontiguousarray(values), grid.spacing, grid.spacing, rate)
    return out


def limit_gradation(
    size: SizeLike,
    domain: Domain | Callable[[FloatArray], FloatArray],
    rate: float = 0.2,
    *,
    spacing: float | None = None,
    max_cells: int = DEFAULT_MAX_CELLS,
    bbox: ArrayLike | None = None,
) -> GriddedSize:
    """A size field below ``size`` whose gradient is at most ``rate`` (Persson 2006).

    Parameters
    ----------
    size : float, callable or size field
        The target size h(p); evaluated only inside the domain and on its boundary.
    domain : Domain or callable
        The domain (a plain signed distance needs ``bbox``).
    rate : float
        The gradation limit g: |grad h| <= g, so neighbouring elements differ in size by a
        factor of at most about 1 + g.  Persson recommends 0.2 to 0.3.
    spacing : float, optional
        Background grid spacing.  Default: the smallest size divided by 4 (estimated on a coarse
        probe of the domain, refined once if the grid finds smaller sizes), enlarged if needed so
        the grid has at most ``max_cells`` nodes.
    max_cells : int
        Cap on the background grid's nodes (default 1e6).
    bbox : (xmin, ymin, xmax, ymax), optional
        Required for a callable ``domain``.

    Returns
    -------
    GriddedSize
        The limited sizes on the background grid (which covers the domain's box with a margin of
        two cells), bilinear between nodes.  At every node it is at most h (and at most the
        domain's diameter, to which larger sizes are clamped) and equal to h where h already
        satisfies the limit; the differences along grid edges are at most ``rate * spacing``.
        Nodes outside the domain carry the limited extension of the inside values.

    Raises
    ------
    SizeError
        A rate that is not positive and finite, a bad grid option, or a size that is not
        positive and finite inside the domain (named with the point).

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Rectangle
    >>> jump = lambda p: np.where(p[:, 0] < 0.5, 0.02, 0.4)
    >>> h = limit_gradation(jump, Rectangle((0, 0), (1, 1)), 0.2)
    >>> h(np.array([[0.4, 0.5], [0.6, 0.5], [1.0, 0.5]])).round(2)
    array([0.02, 0.04, 0.12])
    """
    g = check_rate(rate)
    check_grid_options(spacing, max_cells)
    dom = as_domain(domain, bbox=bbox)
    h = as_size_function(size)
    grid, values = sampled_grid(h, dom, spacing, int(max_cells), g)
    return GriddedSize._trusted(grid.x, grid.y, np.minimum(limit_grid(values, grid, g), dom.diameter))
