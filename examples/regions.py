"""Material regions and a crack: the square of issue 9, meshed, written and solved.

The unit square holds two circular inclusions (regions "a" and "b") and a polyline crack.
Every triangle knows its region (``mesh.triangle_tags``), every interface and crack segment is
a mesh edge (``mesh.curve_edges``, tagged by ``mesh.curve_tags``), and the ``.msh`` file carries
one named physical group per region and per curve.  With scikit-fem installed, the script also
solves a two-material conduction problem (conductivity 1 outside, 100 in the inclusions).

Run ``python examples/regions.py [--out DIR] [--size H]``: it prints the region areas and
writes ``DIR/regions.msh`` and the picture ``DIR/regions.png`` (matplotlib).
"""

# ruff: noqa: T201  (an example prints its figures)
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import injmesh

SQUARE = injmesh.Rectangle((0, 0), (1, 1))
REGIONS = {"a": injmesh.Circle((0.3, 0.3), 0.15), "b": injmesh.Circle((0.7, 0.65), 0.2)}
CURVES = {"crack": [(0.1, 0.8), (0.3, 0.75), (0.5, 0.9)]}


def conduction(mesh: injmesh.Mesh, kappa: np.ndarray) -> np.ndarray | None:
    """u with div(k grad u) = 0, u = 0 at x = 0 and 1 at x = 1 (None without scikit-fem)."""
    try:
        from skfem import Basis, BilinearForm, ElementTriP0, ElementTriP1, MeshTri, condense, solve
        from skfem.helpers import dot, grad
    except ImportError:
        return None
    m = MeshTri(mesh.points.T.copy(), mesh.triangles.T.copy())
    basis = Basis(m, ElementTriP1())
    k = Basis(m, ElementTriP0()).interpolate(kappa[mesh.triangle_tags])

    @BilinearForm
    def form(u, v, w):  # type: ignore[no-untyped-def]
        return w["k"] * dot(grad(u), grad(v))

    x = mesh.points[:, 0]
    fixed = np.flatnonzero((np.abs(x) < 1e-12) | (np.abs(x - 1) < 1e-12))
    u = np.where(np.abs(x - 1) < 1e-12, 1.0, 0.0)
    return np.asarray(solve(*condense(form.assemble(basis, k=k), np.zeros(len(x)), x=u, D=fixed)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=".", help="directory for regions.msh and regions.png")
    ap.add_argument("--size", type=float, default=0.03, help="target edge length h")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    mesh = injmesh.generate(SQUARE, args.size, regions=REGIONS, curves=CURVES)
    print(mesh)
    exact = [1 - np.pi * (0.15**2 + 0.2**2), np.pi * 0.15**2, np.pi * 0.2**2]
    for name, area, ref in zip(mesh.region_names, mesh.region_areas(), exact, strict=True):
        print(f"  region {name!r}: area {area:.5f} (circle {ref:.5f})")
    for c, name in enumerate(mesh.curve_names):
        print(f"  curve {name!r}: {np.count_nonzero(mesh.curve_tags == c)} edges")
    mesh.write(out / "regions.msh")
    u = conduction(mesh, np.array([1.0, 100.0, 100.0]))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2 if u is not None else 1, figsize=(12 if u is not None else 6, 6))
    axes = np.atleast_1d(axes)
    p, t = mesh.points, mesh.triangles
    colours = np.array(["#f2e6d0", "#9ecae1", "#a1d99b"])
    for k in range(len(mesh.region_names)):
        sel = t[mesh.triangle_tags == k]
        axes[0].tripcolor(p[:, 0], p[:, 1], sel, facecolors=np.zeros(len(sel)), edgecolors="0.35",
                          linewidth=0.3, cmap=matplotlib.colors.ListedColormap([colours[k]]))
    for c in range(len(mesh.curve_names)):
        e = mesh.curve_edges[mesh.curve_tags == c]
        segments = p[e]
        axes[0].plot(segments[:, :, 0].T, segments[:, :, 1].T, color="crimson" if c == 0 else "navy",
                     linewidth=1.6)
    axes[0].set_title(f"regions {', '.join(mesh.region_names)}; crack in red "
                      f"({mesh.n_points} nodes, q_min {mesh.quality().min():.3f})", fontsize=9)
    if u is not None:
        im = axes[1].tricontourf(p[:, 0], p[:, 1], t, u, levels=20, cmap="viridis")
        fig.colorbar(im, ax=axes[1], shrink=0.8)
        axes[1].set_title("u, conductivity 1 outside and 100 in the inclusions", fontsize=9)
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(out / "regions.png", dpi=110)
    print(f"wrote {out / 'regions.msh'} and {out / 'regions.png'}")


if __name__ == "__main__":
    main()
