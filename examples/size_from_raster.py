"""A size field from a raster: h read from a grid of values, as a depth or a DEM would give it.

A bay (a rectangle with a round island) is meshed with an edge length that follows a raster
of "depth": fine in the shallow water near the coast and the island, coarse offshore.  The
raster is a :class:`injmesh.sizing.GriddedSize` (bilinear between the grid nodes); from the
command line the same raster is an ``.npz`` file with arrays ``x``, ``y`` and ``values``
(``values[j, i]`` is the size at ``(x[i], y[j])``), passed as
``injmesh generate DOMAIN --size raster.npz -o mesh.msh``.

Run ``python examples/size_from_raster.py [--out DIR]``: it prints the mesh's figures and the
size error against the formula the raster samples, writes the raster as ``DIR/bay_size.npz``
and the picture ``DIR/size_from_raster.png`` (the raster, and the mesh coloured by quality).
"""

# ruff: noqa: T201  (an example prints its figures)
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import injmesh
from injmesh.sizing import GriddedSize

BAY = injmesh.Rectangle((0, 0), (3, 2)) - injmesh.Circle((2.0, 1.2), 0.3)


def depth_size(p: np.ndarray) -> np.ndarray:
    """The formula behind the raster: h grows with the distance from the coast (x = 0) and
    from the island, 0.03 near them, up to 0.2 offshore."""
    coast = p[:, 0]
    island = np.hypot(p[:, 0] - 2.0, p[:, 1] - 1.2) - 0.3
    return np.minimum(0.03 + 0.15 * np.minimum(coast, np.abs(island)), 0.2)


def make_raster(spacing: float = 0.02) -> GriddedSize:
    """The raster: ``depth_size`` sampled on a grid of this spacing covering the bay."""
    x = np.arange(-spacing, 3 + 2 * spacing, spacing)
    y = np.arange(-spacing, 2 + 2 * spacing, spacing)
    X, Y = np.meshgrid(x, y)
    values = depth_size(np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)
    return GriddedSize(x, y, values)


def main(out: Path) -> dict[str, float]:
    raster = make_raster()
    np.savez(out / "bay_size.npz", x=raster.x, y=raster.y, values=raster.values)
    mesh = injmesh.generate(BAY, raster)
    direct = injmesh.generate(BAY, depth_size)
    figures = {
        "nodes": mesh.n_points,
        "q_min": float(mesh.quality().min()),
        "size error (raster)": mesh.size_report(depth_size).relative,
        "size error (formula)": direct.size_report(depth_size).relative,
    }
    for name, value in figures.items():
        print(f"{name:22s} {value:.4g}")

    from matplotlib.figure import Figure

    from injmesh.plot import plot_mesh

    fig = Figure(figsize=(12, 4.2), layout="constrained")
    left, right = fig.subplots(1, 2)
    image = left.pcolormesh(raster.x, raster.y, raster.values, shading="auto", cmap="cividis")
    fig.colorbar(image, ax=left, label="h from the raster")
    left.set_aspect("equal")
    left.set_title(f"raster {raster.values.shape[1]} x {raster.values.shape[0]}")
    plot_mesh(mesh, ax=right)
    right.set_title(f"{mesh.n_points} nodes, q_min {figures['q_min']:.3f}")
    fig.savefig(out / "size_from_raster.png", dpi=80)
    print(f"wrote {out / 'size_from_raster.png'}")
    return figures


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="output directory")
    main(parser.parse_args().out)
