"""The exceptions and warnings of injmesh, in one place every stage can import."""

from __future__ import annotations

from .geometry.base import GeometryError
from .sizing import SizeError


class NodeBudgetError(ValueError):
    """The size function asks for more nodes than ``max_nodes`` allows."""


class ConvergenceWarning(UserWarning):
    """Smoothing stopped at its iteration cap before meeting its convergence test, or the mesh
    does not follow the boundary everywhere."""


__all__ = ["ConvergenceWarning", "GeometryError", "NodeBudgetError", "SizeError"]
