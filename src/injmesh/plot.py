"""Pictures of meshes, qualities and domains with matplotlib (the paper's Figures 1-13).

matplotlib is imported inside each function, never when this module is imported, so the mesher
works without it; ``pip install 'injmesh[plot]'`` adds it.  On a Linux machine without a display
the non-interactive Agg backend is selected before pyplot is first imported.

Every function takes ``ax=None`` (a new figure is made through pyplot when it is ``None``) and
returns the Axes it drew on; nothing is shown unless the caller asks for it.  Figures made here
are managed by pyplot: close them with ``matplotlib.pyplot.close(fig)`` when done.

Examples
--------
>>> import numpy as np
>>> from scipy.spatial import Delaunay
>>> from injmesh.plot import plot_triangulation
>>> p = np.random.default_rng(0).random((20, 2))
>>> ax = plot_triangulation(p, Delaunay(p).simplices)
>>> ax.get_aspect()
1.0
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .quality import triangle_quality, unique_edges

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .geometry import Domain
    from .mesh import Mesh

FloatArray = NDArray[np.float64]

MISSING_MATPLOTLIB = "plotting needs matplotlib: pip install 'injmesh[plot]'"


def _pyplot() -> Any:
    """Import pyplot, choosing Agg when there is no display; a clear ImportError if missing."""
    try:
        import matplotlib
    except ImportError as exc:
        raise ImportError(MISSING_MATPLOTLIB) from exc
    headless = sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )
    if headless and "MPLBACKEND" not in os.environ and "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _axes(ax: Axes | None) -> Axes:
    if ax is not None:
        return ax
    _, new = _pyplot().subplots()
    return new


def _few_ticks(ax: Axes, n: int = 6) -> None:
    """At most about ``n`` ticks per axis, so labels such as -0.75 never run together."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(nbins=n, steps=[1, 2, 2.5, 5, 10]))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=n, steps=[1, 2, 2.5, 5, 10]))


def _equal(ax: Axes) -> None:
    ax.set_aspect("equal")
    ax.autoscale_view()


def plot_mesh(
    mesh: Mesh,
    ax: Axes | None = None,
    *,
    color: Literal["quality", "size-error"] | None = "quality",
    size: float | Callable[[FloatArray], FloatArray] | None = None,
    cmap: str | None = None,
    edgecolor: str = "k",
    linewidth: float = 0.3,
    boundary: bool = True,
    vmin: float | None = None,
    vmax: float | None = None,
    colorbar: bool = True,
) -> Axes:
    """Draw a triangular mesh.

    Parameters
    ----------
    mesh : Mesh
        The mesh.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    color : {"quality", "size-error", None}
        ``"quality"`` fills each triangle by its q of Eq. (5.1) (1 is equilateral);
        ``"size-error"`` colours each edge by ``lc / h(midpoint) - 1`` (0 is exactly the size
        asked for, negative too short, positive too long); ``None`` draws plain edges.
    size : float or callable, optional
        The h for ``"size-error"``; defaults to the size the mesh was made for.
    cmap : str, optional
        Colormap; ``"viridis"`` for quality and ``"coolwarm"`` for size error by default.
    edgecolor : str
        Colour of the triangle edges (quality and plain modes).
    linewidth : float
        Width of the triangle edges, in points.
    boundary : bool
        Draw the boundary edges in black at three times ``linewidth``.
    vmin, vmax : float, optional
        Colour limits: default ``[min q, 1]`` for quality and a range symmetric about 0 for size
        error.
    colorbar : bool
        Add a colorbar (when ``color`` is not ``None``).

    Returns
    -------
    matplotlib Axes

    Raises
    ------
    ValueError
        Unknown ``color``, or ``"size-error"`` without a size function.
    ImportError
        matplotlib is not installed.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.spatial import Delaunay
    >>> from injmesh import Mesh
    >>> from injmesh.triangulation import boundary_edges, delaunay
    >>> p = np.random.default_rng(1).random((30, 2))
    >>> t = delaunay(p)
    >>> e = boundary_edges(t)
    >>> mesh = Mesh(p, t, e, np.zeros(len(e), int))
    >>> ax = plot_mesh(mesh, color="size-error", size=0.2)
    >>> ax.get_aspect()
    1.0
    """
    if color not in ("quality", "size-error", None):
        raise ValueError(f"color must be 'quality', 'size-error' or None, got {color!r}")
    h = None
    if color == "size-error":
        from .sizing import as_size_function

        given = size if size is not None else mesh.size
        if given is None:
            raise ValueError("color='size-error' needs a size function: pass size=...")
        h = as_size_function(given)
    ax = _axes(ax)
    from matplotlib.collections import LineCollection

    pts = np.asarray(mesh.points, dtype=float)
    tri = np.asarray(mesh.triangles)
    x, y = pts[:, 0], pts[:, 1]
    mappable: Any = None
    label = ""
    if color == "quality":
        q = triangle_quality(pts, tri)
        lo = vmin if vmin is not None else (float(q.min()) if len(q) else 0.0)
        mappable = ax.tripcolor(
            x, y, tri, facecolors=q, cmap=cmap or "viridis", vmin=lo,
            vmax=1.0 if vmax is None else vmax, edgecolors=edgecolor, linewidth=linewidth,
        )
        label = "element quality q (Eq. 5.1)"
    elif h is not None:  # color == "size-error"
        e = unique_edges(tri)
        a, b = pts[e[:, 0]], pts[e[:, 1]]
        err = np.hypot(*(a - b).T) / h(0.5 * (a + b)) - 1.0
        span = float(np.abs(err).max()) if len(err) else 1.0
        lines = LineCollection(
            list(np.stack([a, b], axis=1)), cmap=cmap or "coolwarm", linewidths=max(linewidth, 0.8),
        )
        lines.set_array(err)
        lines.set_clim(-span if vmin is None else vmin, span if vmax is None else vmax)
        ax.add_collection(lines)
        mappable = lines
        label = "relative edge-length error lc / h - 1"
    else:
        ax.triplot(x, y, tri, color=edgecolor, linewidth=linewidth)
    if boundary and len(mesh.boundary_edges):
        be = np.asarray(mesh.boundary_edges)
        width = 3 * linewidth if linewidth > 0 else 1.0
        ax.add_collection(LineCollection(list(pts[be]), colors="k", linewidths=width))
    ax.update_datalim(pts)
    _equal(ax)
    if colorbar and mappable is not None:
        ax.figure.colorbar(mappable, ax=ax, label=label)
    return ax


def plot_quality_histogram(
    mesh: Mesh | ArrayLike,
    ax: Axes | None = None,
    *,
    bins: int | ArrayLike = 20,
    color: str = "tab:blue",
) -> Axes:
    """Histogram of element qualities q (Eq. 5.1), as in the paper's Figures 4-13.

    Parameters
    ----------
    mesh : Mesh or (m,) array_like
        A mesh, or its qualities already computed.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    bins : int or sequence
        Number of bins between ``min q`` (rounded down to 0.05) and 1, or explicit bin edges.
    color : str
        Bar colour.

    Returns
    -------
    matplotlib Axes
        With a dashed line at ``q_min`` and its value written beside it.

    Examples
    --------
    >>> ax = plot_quality_histogram([0.8, 0.9, 0.95, 0.99])
    >>> bool(ax.get_xlim()[1] <= 1.01)
    True
    """
    q = np.asarray(mesh.quality() if hasattr(mesh, "quality") else mesh, dtype=float).reshape(-1)
    ax = _axes(ax)
    if len(q) == 0:
        ax.set_title("no elements")
        return ax
    q_min = float(q.min())
    lo = min(np.floor(q_min * 20) / 20, 0.95)
    if isinstance(bins, (int, np.integer)):
        edges = np.linspace(lo, 1.0, int(bins) + 1)
    else:
        edges = np.asarray(bins, dtype=float).reshape(-1)
    ax.hist(q, bins=edges.tolist(), color=color, edgecolor="white")
    ax.axvline(q_min, color="tab:red", linestyle="--", linewidth=1)
    # The label goes on the side of the line with room for it (q_min is often close to 1).
    right_half = q_min > 0.5 * (edges[0] + edges[-1])
    ax.annotate(
        f"$q_{{min}}$ = {q_min:.4f}", xy=(q_min, 1), xycoords=("data", "axes fraction"),
        xytext=(-4 if right_half else 4, -14), textcoords="offset points", color="tab:red",
        ha="right" if right_half else "left",
    )
    ax.set_xlim(edges[0], edges[-1])
    ax.set_xlabel("element quality q")
    ax.set_ylabel("number of elements")
    return ax


def plot_mesh_with_histogram(
    mesh: Mesh, title: str | None = None, *, figure: Figure | None = None, **kwargs: Any
) -> Figure:
    """The mesh (left) beside the histogram of its qualities (right), like Figures 4-13.

    Parameters
    ----------
    mesh : Mesh
        The mesh.
    title : str, optional
        Figure title.
    figure : matplotlib Figure, optional
        An empty figure to draw in (for instance a ``matplotlib.figure.Figure()`` made without
        pyplot); by default a new pyplot figure.
    **kwargs
        Passed to :func:`plot_mesh` (``color``, ``cmap``, ``linewidth``, ...).

    Returns
    -------
    matplotlib Figure
        Close it with ``matplotlib.pyplot.close(fig)`` when done.

    Examples
    --------
    >>> import numpy as np
    >>> from injmesh import Mesh
    >>> from injmesh.triangulation import boundary_edges, delaunay
    >>> p = np.random.default_rng(2).random((25, 2))
    >>> t = delaunay(p)
    >>> e = boundary_edges(t)
    >>> fig = plot_mesh_with_histogram(Mesh(p, t, e, np.zeros(len(e), int)), title="random")
    >>> len(fig.axes) >= 2
    True
    """
    if figure is None:
        fig = _pyplot().figure(figsize=(11, 4.8), layout="constrained")
    else:
        fig = figure
    left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.35, 1]})
    plot_mesh(mesh, ax=left, **kwargs)
    _few_ticks(left)
    left.set_title(f"{mesh.n_points} nodes, {mesh.n_triangles} triangles")
    plot_quality_histogram(mesh, ax=right)
    if title:
        fig.suptitle(title)
    return fig


def plot_points(
    points: ArrayLike,
    ax: Axes | None = None,
    *,
    color: str = "k",
    markersize: float = 2.0,
    values: ArrayLike | None = None,
    cmap: str = "viridis",
    norm: Any = None,
) -> Axes:
    """Draw nodes as dots (the paper's Figure 1: initial node placement).

    Parameters
    ----------
    points : (n, 2) array_like
        The nodes.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    color : str
        Dot colour (when ``values`` is not given).
    markersize : float
        Dot diameter in points.
    values : (n,) array_like, optional
        Colour each dot by its value through ``cmap`` and ``norm`` (a matplotlib Normalize;
        by default the values' range).
    cmap : str
        Colormap for ``values``.
    norm : matplotlib Normalize, optional
        Colour scale for ``values``; pass the same one to several plots to share it.

    Returns
    -------
    matplotlib Axes

    Examples
    --------
    >>> ax = plot_points([[0, 0], [1, 0], [0, 1]])
    >>> len(ax.lines)
    1
    >>> ax = plot_points([[0, 0], [1, 0], [0, 1]], values=[0.5, 1.0, 1.5])
    >>> len(ax.collections)
    1
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    ax = _axes(ax)
    if values is None:
        ax.plot(p[:, 0], p[:, 1], "o", color=color, markersize=markersize, linestyle="none")
    else:
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.shape != (len(p),):
            raise ValueError(f"values must have one entry per point ({len(p)}), got {v.shape}")
        ax.scatter(p[:, 0], p[:, 1], c=v, s=(1.6 * markersize) ** 2, cmap=cmap, norm=norm,
                   linewidths=0)
    _equal(ax)
    return ax


def plot_triangulation(
    points: ArrayLike,
    triangles: ArrayLike,
    ax: Axes | None = None,
    *,
    edgecolor: str = "k",
    linewidth: float = 0.4,
    values: ArrayLike | None = None,
    cmap: str = "viridis",
    norm: Any = None,
) -> Axes:
    """Draw the edges of a triangulation (the paper's Figure 2: initial triangulation).

    Parameters
    ----------
    points : (n, 2) array_like
        Node coordinates.
    triangles : (m, 3) array_like of int
        Node indices of each triangle.
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    edgecolor : str
        Edge colour.
    linewidth : float
        Edge width in points.
    values : (m,) array_like, optional
        Fill each triangle by its value (for instance its quality q) through ``cmap``.
    cmap : str
        Colormap for ``values``.
    norm : matplotlib Normalize, optional
        Colour scale for ``values``; pass the same one to several plots to share it.

    Returns
    -------
    matplotlib Axes

    Examples
    --------
    >>> ax = plot_triangulation([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])
    >>> ax.get_aspect()
    1.0
    """
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    t = np.asarray(triangles, dtype=int).reshape(-1, 3)
    ax = _axes(ax)
    if values is None:
        ax.triplot(p[:, 0], p[:, 1], t, color=edgecolor, linewidth=linewidth)
    else:
        v = np.asarray(values, dtype=float).reshape(-1)
        if v.shape != (len(t),):
            raise ValueError(f"values must have one entry per triangle ({len(t)}), got {v.shape}")
        ax.tripcolor(p[:, 0], p[:, 1], t, facecolors=v, cmap=cmap, norm=norm,
                     edgecolors=edgecolor, linewidth=linewidth)
    _equal(ax)
    return ax


def plot_domain(
    domain: Domain | Callable[[FloatArray], FloatArray],
    ax: Axes | None = None,
    *,
    bbox: ArrayLike | None = None,
    resolution: int = 200,
    cmap: str = "RdBu_r",
    colorbar: bool = True,
) -> Axes:
    """Draw a domain's signed distance d and its zero contour, for debugging a geometry.

    Inside (``d < 0``) is blue, outside red; the boundary is the black zero contour.

    Parameters
    ----------
    domain : Domain or callable
        A domain, or a plain ``d(p)`` (then ``bbox`` is required).
    ax : matplotlib Axes, optional
        Where to draw; a new figure by default.
    bbox : (xmin, ymin, xmax, ymax), optional
        The region to sample; the domain's box grown by 10 % by default.
    resolution : int
        Samples along the longer side of the box.
    cmap : str
        A diverging colormap, centred on ``d = 0``.
    colorbar : bool
        Add a colorbar.

    Returns
    -------
    matplotlib Axes

    Examples
    --------
    >>> from injmesh import Circle, Rectangle
    >>> ax = plot_domain(Rectangle((0, 0), (2, 1)) - Circle((1, 0.5), 0.25), resolution=60)
    >>> ax.get_aspect()
    1.0
    """
    from .geometry import as_domain

    dom = as_domain(domain, bbox=bbox)
    if bbox is None:
        x0, y0, x1, y1 = dom.bbox
        pad = 0.1 * max(x1 - x0, y1 - y0)
        x0, y0, x1, y1 = x0 - pad, y0 - pad, x1 + pad, y1 + pad
    else:
        x0, y0, x1, y1 = (float(v) for v in np.asarray(bbox, dtype=float).reshape(4))
    if resolution < 2:
        raise ValueError(f"resolution must be at least 2, got {resolution!r}")
    step = max(x1 - x0, y1 - y0) / resolution
    xs = np.linspace(x0, x1, max(2, round((x1 - x0) / step) + 1))
    ys = np.linspace(y0, y1, max(2, round((y1 - y0) / step) + 1))
    gx, gy = np.meshgrid(xs, ys)
    d = dom.sdf(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)

    ax = _axes(ax)
    from matplotlib.colors import TwoSlopeNorm

    lo, hi = float(d.min()), float(d.max())
    span = max(abs(lo), abs(hi), np.finfo(float).tiny)
    norm = TwoSlopeNorm(0.0, vmin=min(lo, -1e-12 * span), vmax=max(hi, 1e-12 * span))
    filled = ax.contourf(gx, gy, d, levels=21, cmap=cmap, norm=norm)
    if lo < 0 < hi:
        ax.contour(gx, gy, d, levels=[0.0], colors="k", linewidths=1.5)
    _equal(ax)
    if colorbar:
        ax.figure.colorbar(filled, ax=ax, label="signed distance d")
    return ax
