"""injmesh.plot: lazy matplotlib, Axes in and out, the colours mean what they say."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import LineCollection, PolyCollection  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

import injmesh  # noqa: E402
from injmesh import Circle, Mesh, Rectangle  # noqa: E402
from injmesh import plot as P  # noqa: E402
from injmesh.quality import triangle_quality, unique_edges  # noqa: E402
from injmesh.triangulation import boundary_edges, delaunay  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def mesh() -> Mesh:
    return injmesh.generate(Circle((0, 0), 1) - Circle((0, 0), 0.4), 0.25)


def test_import_does_not_import_matplotlib():
    code = "import sys, injmesh.plot, injmesh.io, injmesh.cli; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_headless_uses_agg(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY",
                                                             "MPLBACKEND")}
    code = ("import injmesh.plot as P, matplotlib; P.plot_points([[0, 0], [1, 1]]);"
            "print(matplotlib.get_backend().lower())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=env)
    if sys.platform.startswith("linux"):
        assert out.stdout.strip() == "agg"


def test_quality_colours_are_q(mesh):
    ax = P.plot_mesh(mesh)
    faces = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(faces) == 1
    np.testing.assert_allclose(faces[0].get_array(), triangle_quality(mesh.points, mesh.triangles))
    assert faces[0].get_clim()[1] == 1.0
    assert ax.get_aspect() == 1.0
    assert len(ax.figure.axes) == 2  # the colorbar


def test_size_error_colours_are_relative_edge_errors(mesh):
    ax = P.plot_mesh(mesh, color="size-error", colorbar=False)
    lines = [c for c in ax.collections if isinstance(c, LineCollection) and c.get_array() is not None]
    assert len(lines) == 1
    e = unique_edges(mesh.triangles)
    lc = np.hypot(*(mesh.points[e[:, 0]] - mesh.points[e[:, 1]]).T)
    np.testing.assert_allclose(lines[0].get_array(), lc / 0.25 - 1)
    lo, hi = lines[0].get_clim()
    assert lo == pytest.approx(-hi)
    assert len(ax.figure.axes) == 1


def test_size_error_with_explicit_size_and_without_any():
    p = np.random.default_rng(0).random((20, 2))
    t = delaunay(p)
    e = boundary_edges(t)
    bare = Mesh(p, t, e, np.zeros(len(e), int))
    with pytest.raises(ValueError, match="size"):
        P.plot_mesh(bare, color="size-error")
    assert P.plot_mesh(bare, color="size-error", size=0.3).get_aspect() == 1.0
    with pytest.raises(ValueError, match="color"):
        P.plot_mesh(bare, color="rainbow")  # type: ignore[arg-type]


def test_plain_mesh_on_given_axes(mesh):
    fig, ax = plt.subplots()
    assert P.plot_mesh(mesh, ax, color=None, boundary=False) is ax
    assert not [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert len(fig.axes) == 1


def test_histogram_annotates_q_min(mesh):
    ax = P.plot_quality_histogram(mesh, bins=10)
    q_min = mesh.quality().min()
    texts = [t.get_text() for t in ax.texts]
    assert any(f"{q_min:.4f}" in t for t in texts)
    heights = [p.get_height() for p in ax.patches]
    assert sum(heights) == mesh.n_triangles
    assert ax.get_xlim()[1] == pytest.approx(1.0)
    explicit = P.plot_quality_histogram(mesh.quality(), bins=[0.5, 0.75, 1.0])
    assert len(explicit.patches) == 2
    assert P.plot_quality_histogram([]).get_title() == "no elements"


def test_mesh_with_histogram(mesh, tmp_path):
    fig = P.plot_mesh_with_histogram(mesh, title="ring")
    assert len(fig.axes) == 3 and fig.get_suptitle() == "ring"  # mesh, histogram, colorbar
    assert "nodes" in fig.axes[0].get_title()
    own = P.plot_mesh_with_histogram(mesh, figure=Figure(), color="size-error")
    own.savefig(tmp_path / "own.png")
    assert (tmp_path / "own.png").stat().st_size > 1000


def test_points_and_triangulation():
    p = np.random.default_rng(1).random((15, 2))
    ax = P.plot_points(p)
    np.testing.assert_allclose(np.column_stack(ax.lines[0].get_data()), p)
    ax2 = P.plot_triangulation(p, delaunay(p))
    assert ax2.get_aspect() == 1.0 and len(ax2.lines) >= 1


def test_plot_domain_domain_and_callable():
    ax = P.plot_domain(Rectangle((0, 0), (2, 1)) - Circle((1, 0.5), 0.25), resolution=50)
    assert ax.get_aspect() == 1.0
    assert len(ax.figure.axes) == 2
    ax2 = P.plot_domain(lambda p: np.hypot(p[:, 0], p[:, 1]) - 1, bbox=(-1.5, -1.5, 1.5, 1.5),
                        resolution=40, colorbar=False)
    assert len(ax2.figure.axes) == 1
    with pytest.raises(TypeError, match="bbox"):
        P.plot_domain(lambda p: p[:, 0])
    with pytest.raises(ValueError, match="resolution"):
        P.plot_domain(Circle((0, 0), 1), resolution=1)


def test_missing_matplotlib_message(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(ImportError, match=r"plotting needs matplotlib: pip install 'injmesh\[plot\]'"):
        P.plot_points([[0, 0]])


def test_mesh_methods_delegate(mesh):
    assert mesh.plot().get_aspect() == 1.0
    assert injmesh.plot_mesh(mesh, color=None).get_aspect() == 1.0


def test_points_and_triangles_coloured_by_values():
    from matplotlib.colors import Normalize

    p = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    norm = Normalize(0, 2)
    ax = P.plot_points(p, values=[0.5, 1.0, 1.5, 2.5], norm=norm, cmap="coolwarm")
    dots = ax.collections[0]
    assert np.allclose(dots.get_array(), [0.5, 1.0, 1.5, 2.5]) and dots.norm is norm
    t = np.array([[0, 1, 2], [1, 3, 2]])
    ax = P.plot_triangulation(p, t, values=[0.25, 0.75], norm=norm)
    assert np.allclose(ax.collections[0].get_array(), [0.25, 0.75])
    with pytest.raises(ValueError, match="one entry per point"):
        P.plot_points(p, values=[1.0])
    with pytest.raises(ValueError, match="one entry per triangle"):
        P.plot_triangulation(p, t, values=[1.0, 2.0, 3.0])
