"""injmesh: 2-D unstructured triangular meshes by Advancing Node Injection.

The mesher implements "Generation of 2-D unstructured mesh using a novel algorithm for node
placement" (an improved DistMesh): boundary meshing by injection-projection and 1-D balancing,
Advancing Node Injection of interior nodes, and attractive force smoothing.  The original
DistMesh is available as ``method="distmesh"``.

Examples
--------
>>> import injmesh
>>> domain = injmesh.Circle((0, 0), 1) - injmesh.Circle((0, 0), 0.2)
>>> mesh = injmesh.generate(domain, lambda p: 0.05 + 0.2 * abs(p[:, 0]))
>>> mesh.n_points > 100
True
"""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .errors import ConvergenceWarning, CurveError, MeshError, NodeBudgetError, RegionError
from .expression import size_expression
from .geometry import (
    Circle,
    Difference,
    Domain,
    GeometryError,
    Implicit,
    Intersection,
    Polygon,
    Rectangle,
    Union,
)
from .mesh import Mesh, MeshStats
from .pipeline import generate
from .progress import Progress
from .sizing import SizeError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

try:
    __version__ = version("injmesh")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0+unknown"


def __getattr__(name: str) -> Any:
    # ``injmesh.adapt`` without an explicit import, loaded on first use: it pulls in SciPy's
    # graph and optimisation modules, which ``import injmesh`` should not pay for.
    if name == "adapt":
        import importlib

        return importlib.import_module(".adapt", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def read(path: str | Path) -> Mesh:
    """Read a triangular mesh from any file meshio reads, or from injmesh's ``.npz``."""
    from .io import read as _read

    return _read(path)


def plot_mesh(mesh: Mesh, ax: Axes | None = None, **kwargs: Any) -> Axes:
    """Draw a mesh coloured by element quality; see :func:`injmesh.plot.plot_mesh`."""
    from .plot import plot_mesh as _plot_mesh

    return _plot_mesh(mesh, ax=ax, **kwargs)


__all__ = [
    "Circle",
    "ConvergenceWarning",
    "CurveError",
    "Difference",
    "Domain",
    "GeometryError",
    "Implicit",
    "Intersection",
    "Mesh",
    "MeshError",
    "MeshStats",
    "NodeBudgetError",
    "Polygon",
    "Progress",
    "Rectangle",
    "RegionError",
    "SizeError",
    "Union",
    "__version__",
    "generate",
    "plot_mesh",
    "read",
    "size_expression",
]
