"""The paper's six test domains (Table 10) with their size functions (Section 5).

Each case carries the domain twice: as composed geometry (exact distances and corners) and as
the plain signed distance function printed in Table 10 (with the unit disc's missing ``- 1``
restored), together with the corners to pass as ``fixed_points``, the h0 the paper used for
DistMesh, and the figures the paper printed for both algorithms.

Examples
--------
>>> from injmesh.cases import CASES
>>> sorted(CASES)  # doctest: +NORMALIZE_WHITESPACE
['circle_with_hole', 'l_shape', 'square_with_four_holes', 'square_with_hole',
 'two_circles_and_square', 'unit_disc']
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .geometry import BBox, Circle, Domain, Rectangle

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PaperFigures:
    """One column of the paper's Tables 3 and 5-9 (``None`` where the paper gives nothing)."""

    N: int | None = None
    iterations: int | None = None
    q_min: float | None = None
    cpu_seconds: float | None = None
    Er: float | None = None


@dataclass(frozen=True)
class Case:
    """A test domain of the paper.

    Attributes
    ----------
    name, title : str
        Identifier (used on the command line) and the paper's caption.
    geometry : Domain
        The domain as composed primitives.
    sdf : callable
        Table 10's signed distance function as a plain function of an ``(n, 2)`` array.
    bbox : (xmin, ymin, xmax, ymax)
        A box containing the domain.
    fixed_points : (k, 2) array
        The sharp corners, for meshing ``sdf`` as a plain function.
    size : callable
        The size function h of Section 5.
    h0 : float
        The initial spacing the paper used for DistMesh on this case.
    paper_ours, paper_distmesh : PaperFigures
        What the paper printed for its algorithm and for DistMesh.
    """

    name: str
    title: str
    geometry: Domain
    sdf: Callable[[FloatArray], FloatArray]
    bbox: BBox
    fixed_points: FloatArray
    size: Callable[[FloatArray], FloatArray]
    h0: float
    paper_ours: PaperFigures = field(default_factory=PaperFigures)
    paper_distmesh: PaperFigures = field(default_factory=PaperFigures)


def _r(p: FloatArray, cx: float, cy: float) -> FloatArray:
    return np.hypot(p[:, 0] - cx, p[:, 1] - cy)


def _cones(
    centres: list[tuple[float, float]], slope: float, base: float
) -> Callable[[FloatArray], FloatArray]:
    def h(p: FloatArray) -> FloatArray:
        # min_i (slope r_i + base) is slope min_i r_i + base, to the bit (rounding is
        # monotone): one distance array kept, not a stack of them (the stages call h often).
        p = np.asarray(p, dtype=float)
        r = _r(p, *centres[0])
        for cx, cy in centres[1:]:
            np.minimum(r, _r(p, cx, cy), out=r)
        return slope * r + base

    return h


# --- Table 10 as printed (x = p[:, 0], y = p[:, 1]) --------------------------------------------


def unit_disc_sdf(p: FloatArray) -> FloatArray:
    """``sqrt(x^2 + y^2) - 1`` (Table 10 omits the ``- 1``)."""
    return _r(p, 0, 0) - 1.0


def square_with_hole_sdf(p: FloatArray) -> FloatArray:
    """``max(-min(x, 1-x, y, 1-y), min(x-0.4, 0.6-x, y-0.4, 0.6-y))``."""
    x, y = p[:, 0], p[:, 1]
    outer = -np.minimum.reduce([x, 1 - x, y, 1 - y])
    hole = np.minimum.reduce([x - 0.4, 0.6 - x, y - 0.4, 0.6 - y])
    return np.maximum(outer, hole)


def circle_with_hole_sdf(p: FloatArray) -> FloatArray:
    """``max(sqrt(x^2+y^2) - 1, -sqrt(x^2+y^2) + 0.2)``."""
    r = _r(p, 0, 0)
    return np.maximum(r - 1.0, -r + 0.2)


def square_with_four_holes_sdf(p: FloatArray) -> FloatArray:
    """The square ``[-1, 1]^2`` minus four discs of radius 0.2 at ``(+-0.5, +-0.5)``."""
    x, y = p[:, 0], p[:, 1]
    outer = -np.minimum.reduce([x + 1, 1 - x, y + 1, 1 - y])
    holes = np.minimum.reduce(
        [_r(p, 0.5, 0.5) - 0.2, _r(p, -0.5, -0.5) - 0.2, _r(p, 0.5, -0.5) - 0.2, _r(p, -0.5, 0.5) - 0.2]
    )
    return np.maximum(outer, -holes)


def two_circles_and_square_sdf(p: FloatArray) -> FloatArray:
    """``max(min(square, disc((0, 1), 0.3)), -disc((0.9, 1), 0.6))``."""
    x, y = p[:, 0], p[:, 1]
    square = -np.minimum.reduce([x + 1, 1 - x, y + 1, 1 - y])
    return np.maximum(np.minimum(square, _r(p, 0, 1) - 0.3), -(_r(p, 0.9, 1) - 0.6))


def l_shape_sdf(p: FloatArray) -> FloatArray:
    """``min(-min(x, 1-x, y, 0.4-y), -min(x-0.6, 1-x, y-0.4, 1-y))``.

    As printed it is exactly zero along the shared edge ``y = 0.4, 0.6 < x < 1``, which lies
    inside the domain; the boundary is where the sign changes.
    """
    x, y = p[:, 0], p[:, 1]
    a = -np.minimum.reduce([x, 1 - x, y, 0.4 - y])
    b = -np.minimum.reduce([x - 0.6, 1 - x, y - 0.4, 1 - y])
    return np.minimum(a, b)


def _two_circles_and_square() -> Domain:
    return (Rectangle((-1, -1), (1, 1)) | Circle((0, 1), 0.3)) - Circle((0.9, 1), 0.6)


_Y_RIGHT = 1.0 - float(np.sqrt(0.6**2 - 0.1**2))  # where the big circle meets x = 1

CASES: dict[str, Case] = {
    c.name: c
    for c in [
        Case(
            "unit_disc",
            "Unit disc",
            Circle((0, 0), 1),
            unit_disc_sdf,
            (-1.0, -1.0, 1.0, 1.0),
            np.empty((0, 2)),
            _cones([(1, 0)], 0.2, 0.04),
            0.01,
            PaperFigures(356, 638, 0.8545, None, 0.07),
            PaperFigures(1631, 4036, 0.7991, None, 0.12),
        ),
        Case(
            "square_with_hole",
            "Square with hole",
            Rectangle((0, 0), (1, 1)) - Rectangle((0.4, 0.4), (0.6, 0.6)),
            square_with_hole_sdf,
            (0.0, 0.0, 1.0, 1.0),
            np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]], float),
            _cones([(0.4, 0.4), (0.6, 0.4), (0.6, 0.6), (0.4, 0.6)], 0.2, 0.05),
            0.04,
            PaperFigures(168, 103, 0.8284, 7.5938, 0.0108),
            PaperFigures(234, 2246, 0.7292, 13.0625, 0.0214),
        ),
        Case(
            "circle_with_hole",
            "Circle with hole",
            Circle((0, 0), 1) - Circle((0, 0), 0.2),
            circle_with_hole_sdf,
            (-1.0, -1.0, 1.0, 1.0),
            np.empty((0, 2)),
            _cones([(0, 0)], 0.2, 0.05),
            0.05,
            PaperFigures(205, 105, 0.8223, 8.0313, 0.0343),
            PaperFigures(416, 1193, 0.7925, 10.6881, 0.0884),
        ),
        Case(
            "square_with_four_holes",
            "Square with four holes",
            Rectangle((-1, -1), (1, 1))
            - Circle((0.5, 0.5), 0.2)
            - Circle((-0.5, -0.5), 0.2)
            - Circle((0.5, -0.5), 0.2)
            - Circle((-0.5, 0.5), 0.2),
            square_with_four_holes_sdf,
            (-1.0, -1.0, 1.0, 1.0),
            np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float),
            _cones([(0.5, 0.5), (0.5, -0.5), (-0.5, -0.5), (-0.5, 0.5)], 0.2, 0.05),
            0.048,
            PaperFigures(420, 100, 0.7335, 7.2969, 0.022),
            PaperFigures(906, 5184, 0.7066, 20.7188, 0.0601),
        ),
        Case(
            "two_circles_and_square",
            "Domain obtained by two circles and square",
            _two_circles_and_square(),
            two_circles_and_square_sdf,
            (-1.0, -1.0, 1.0, 1.3),
            np.array([[-1, -1], [1, -1], [-1, 1], [-0.3, 1], [0.3, 1], [1, _Y_RIGHT]], float),
            _cones([(0, 1), (0.9, 1), (1.5, 1)], 0.2, 0.05),
            0.0086,
            PaperFigures(180, 158, 0.6466, 7.9219, 0.0285),
            PaperFigures(194, 8985, 0.7612, 29.7602, 0.0224),
        ),
        Case(
            "l_shape",
            "L-shaped domain",
            Rectangle((0, 0), (1, 0.4)) | Rectangle((0.6, 0.4), (1, 1)),
            l_shape_sdf,
            (0.0, 0.0, 1.0, 1.0),
            np.array([[0, 0], [1, 0], [1, 1], [0.6, 1], [0.6, 0.4], [0, 0.4]], float),
            lambda p: _r(np.asarray(p, dtype=float), 1, 0) / 7 + 0.03,
            0.061,
            PaperFigures(204, 195, 0.707, 9.7813, 0.0363),
            PaperFigures(35, 174, 0.7285, 4.8438, 0.1536),
        ),
    ]
}


def get_case(name: str) -> Case:
    """Look up a case by name, with a helpful error for unknown names."""
    try:
        return CASES[name]
    except KeyError:
        raise ValueError(f"unknown case {name!r}; choose one of {', '.join(sorted(CASES))}") from None
