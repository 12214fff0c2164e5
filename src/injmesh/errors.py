"""The exceptions and warnings of injmesh, in one place every stage can import."""

from __future__ import annotations

from .geometry.base import GeometryError
from .geometry.regions import CurveError, RegionError
from .sizing import SizeError


class NodeBudgetError(ValueError):
    """The size function asks for more nodes than ``max_nodes`` allows."""


class MeshError(ValueError):
    """The mesh failed its own checks (a duplicate or unused node, a flat or inverted triangle, a
    boundary segment that is not a boundary edge, a node off the boundary, a triangle outside).

    ``defects`` lists what and where; ``generate(..., strict=False)`` returns the mesh instead,
    flagged ``mesh.stats.valid == False`` with the same list in ``mesh.stats.defects``.
    """

    def __init__(self, message: str, defects: tuple[object, ...] = ()) -> None:
        super().__init__(message)
        self.defects = defects


class ConvergenceWarning(UserWarning):
    """Smoothing stopped at its iteration cap before meeting its convergence test, or the mesh
    does not follow the boundary everywhere."""


__all__ = ["ConvergenceWarning", "CurveError", "GeometryError", "MeshError", "NodeBudgetError", "RegionError",
           "SizeError"]
