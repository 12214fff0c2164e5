"""Domains: primitives with exact distances, set operations, and plain callables d(p)."""

from .base import BBox, Domain, GeometryError
from .brep import BRep
from .csg import Difference, Intersection, Union
from .implicit import Implicit, as_domain
from .primitives import Circle, Polygon, Rectangle

__all__ = [
    "BBox",
    "BRep",
    "Circle",
    "Difference",
    "Domain",
    "GeometryError",
    "Implicit",
    "Intersection",
    "Polygon",
    "Rectangle",
    "Union",
    "as_domain",
]
