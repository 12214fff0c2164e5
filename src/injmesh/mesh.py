"""The immutable result of meshing."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .quality import (
    SizeReport,
    signed_areas,
    size_report,
    triangle_angles,
    triangle_quality,
    unique_edges,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from .validate import Defect

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


@dataclass(frozen=True)
class MeshStats:
    """What it took to make a mesh.

    Attributes
    ----------
    method : str
        ``"injection"`` (the paper's algorithm) or ``"distmesh"`` (the baseline).
    iterations : int
        Smoothing iterations performed, in steps over the whole mesh (a step over part of it
        counts the fraction of the nodes it moves).
    converged : bool
        Whether smoothing met its convergence test before the iteration cap.
    retriangulations : int
        Number of Delaunay triangulations computed.
    boundary_nodes, initial_nodes : int
        Nodes after boundary meshing (Step 1) and after node injection (Step 2).
    seconds : dict
        Wall-clock seconds per stage.
    valid : bool
        Whether the mesh passed every check of :func:`injmesh.validate.mesh_defects`; only a
        mesh made with ``generate(..., strict=False)`` can be invalid.
    defects : tuple of Defect
        What failed those checks, and where.
    unsettled : (x, y) or None
        Where smoothing was still moving most when it stopped (useful when not converged).
    cleaning : dict
        What cleaning the geometry at the scale of h changed (``merged_vertices``, ``spikes``,
        ...: counts), empty when nothing.
    """

    method: str = "injection"
    iterations: int = 0
    converged: bool = True
    retriangulations: int = 0
    boundary_nodes: int = 0
    initial_nodes: int = 0
    seconds: dict[str, float] = field(default_factory=dict)
    valid: bool = True
    defects: tuple[Defect, ...] = ()
    unsettled: tuple[float, float] | None = None
    cleaning: dict[str, int] = field(default_factory=dict)

    @property
    def total_seconds(self) -> float:
        """Sum of the per-stage seconds."""
        return float(sum(self.seconds.values()))


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangular mesh; never modified after it is made.

    Attributes
    ----------
    points : (n, 2) float64 array
        Node coordinates.
    triangles : (m, 3) int array
        Node indices of each triangle, counter-clockwise.
    boundary_edges : (k, 2) int array
        Boundary edges, oriented with the domain on their left (outer boundary counter-clockwise,
        holes clockwise).
    boundary_tags : (k,) int array
        Boundary loop of each boundary edge, numbered in a stable order that depends on the
        shape only: outer boundaries by decreasing area, each followed by its own holes by
        decreasing area (0 is the outer boundary of the largest component).  Never negative.
    size : callable or None
        The size function h the mesh was made for, used by :meth:`size_report`.
    stats : MeshStats
        Iterations, convergence and timings.
    triangle_tags : (m,) int array
        Region of each triangle: 0 is the rest of the domain, k the k-th region given to
        ``generate(..., regions=...)``.  All zero without regions.
    region_names : tuple of str
        Name of each region tag: ``region_names[0] == "domain"``, then the regions' names.
    curve_edges : (c, 2) int array
        Interior constraint edges (regions' boundaries inside the domain, user curves), each
        an edge of two triangles, oriented along its curve.
    curve_tags : (c,) int array
        Curve of each interior edge, an index into ``curve_names``.
    curve_names : tuple of str
        The user curves' names in the order given, then one name per interface between two
        regions, ``"a/b"`` for regions a and b in tag order (``"domain/inclusion"``).
    """

    points: FloatArray
    triangles: IntArray
    boundary_edges: IntArray
    boundary_tags: IntArray
    size: Callable[[FloatArray], FloatArray] | None = None
    stats: MeshStats = field(default_factory=MeshStats)
    triangle_tags: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    region_names: tuple[str, ...] = ("domain",)
    curve_edges: IntArray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.intp))
    curve_tags: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    curve_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # Without regions every triangle is in the domain (tag 0).
        if len(self.triangle_tags) == 0 and len(self.triangles):
            object.__setattr__(self, "triangle_tags", np.zeros(len(self.triangles), dtype=np.intp))
        object.__setattr__(self, "curve_edges", np.asarray(self.curve_edges, dtype=np.intp).reshape(-1, 2))
        for name in ("points", "triangles", "boundary_edges", "boundary_tags", "triangle_tags",
                     "curve_edges", "curve_tags"):
            a = np.array(getattr(self, name), copy=True)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "region_names", tuple(self.region_names))
        object.__setattr__(self, "curve_names", tuple(self.curve_names))
        if len(self.triangle_tags) != len(self.triangles):
            raise ValueError(f"triangle_tags must have one tag per triangle ({len(self.triangles)}), "
                             f"got {len(self.triangle_tags)}")
        if len(self.curve_tags) != len(self.curve_edges):
            raise ValueError(f"curve_tags must have one tag per curve edge ({len(self.curve_edges)}), "
                             f"got {len(self.curve_tags)}")

    def region_areas(self) -> FloatArray:
        """Total area of each region, indexed by tag (``len(region_names)`` entries)."""
        tags = np.asarray(self.triangle_tags, dtype=np.intp)
        n = max(len(self.region_names), int(tags.max(initial=-1)) + 1)
        return np.asarray(np.bincount(tags, weights=self.areas(), minlength=n), dtype=np.float64)

    @property
    def n_points(self) -> int:
        """Number of nodes."""
        return int(len(self.points))

    @property
    def n_triangles(self) -> int:
        """Number of triangles."""
        return int(len(self.triangles))

    @property
    def edges(self) -> IntArray:
        """All distinct edges ``(k, 2)`` with ``i < j``."""
        return unique_edges(self.triangles)

    @property
    def boundary_nodes(self) -> IntArray:
        """Sorted indices of the nodes on the boundary."""
        return np.unique(self.boundary_edges)

    @property
    def converged(self) -> bool:
        """Whether smoothing converged (see :class:`MeshStats`)."""
        return self.stats.converged

    def quality(self) -> FloatArray:
        """Quality q of every triangle, Eq. (5.1) of the paper (1 is equilateral)."""
        return triangle_quality(self.points, self.triangles)

    def angles(self) -> FloatArray:
        """Interior angles of every triangle in degrees, ``(m, 3)``."""
        return triangle_angles(self.points, self.triangles)

    def areas(self) -> FloatArray:
        """Area of every triangle (positive: triangles are counter-clockwise)."""
        return signed_areas(self.points, self.triangles)

    def size_report(self, size: Callable[[FloatArray], FloatArray] | float | None = None) -> SizeReport:
        """Edge lengths against h: the paper's Er and the mean relative error.

        Parameters
        ----------
        size : float or callable, optional
            The h to compare against; defaults to the h the mesh was made for.
        """
        from .sizing import as_size_function

        h = size if size is not None else self.size
        if h is None:
            raise ValueError("this mesh carries no size function; pass size=...")
        return size_report(self.points, self.triangles, as_size_function(h))

    def summary(self) -> dict[str, Any]:
        """Nodes, triangles, quality and size figures as a flat dict (for tables and JSON)."""
        q = self.quality()
        out: dict[str, Any] = {
            "N": self.n_points,
            "triangles": self.n_triangles,
            "iterations": self.stats.iterations,
            "converged": self.stats.converged,
            "q_min": float(q.min()) if len(q) else float("nan"),
            "q_mean": float(q.mean()) if len(q) else float("nan"),
            "seconds": self.stats.total_seconds,
        }
        if self.size is not None:
            r = self.size_report()
            out["Er"] = r.er
            out["Er_rel"] = r.relative
        return out

    def write(self, path: str | Path, **kwargs: Any) -> None:
        """Write the mesh to a file; the format follows the extension (see :mod:`injmesh.io`)."""
        from .io import write

        write(self, path, **kwargs)

    def plot(self, ax: Axes | None = None, **kwargs: Any) -> Axes:
        """Draw the mesh coloured by quality (see :func:`injmesh.plot.plot_mesh`)."""
        from .plot import plot_mesh

        return plot_mesh(self, ax=ax, **kwargs)

    def __repr__(self) -> str:
        q = self.quality()
        qmin = f"{q.min():.3f}" if len(q) else "n/a"
        return f"<Mesh: {self.n_points} points, {self.n_triangles} triangles, min q {qmin}>"
