"""A size field from scattered samples: h known at measurement points only.

A plate with a hole is meshed with sizes measured at 150 scattered points (say, an error
indicator from a previous simulation, or sensor data): fine around the hole and along the
lower edge, coarse elsewhere.  :class:`injmesh.sizing.ScatteredSize` is linear on the
samples' Delaunay triangulation and takes the nearest sample's size outside their hull.  From
the command line the samples are an ``.npz`` file with arrays ``points`` (n, 2) and
``values`` (n,): ``injmesh generate DOMAIN --size samples.npz -o mesh.msh``.

Run ``python examples/size_scattered.py [--out DIR]``: it prints the mesh's figures and
writes ``DIR/size_scattered.png`` (the mesh, the samples coloured by their size).
"""

# ruff: noqa: T201  (an example prints its figures)
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import injmesh
from injmesh.sizing import ScatteredSize

PLATE = injmesh.Rectangle((0, 0), (2, 1)) - injmesh.Circle((0.6, 0.5), 0.2)


def measured(p: np.ndarray) -> np.ndarray:
    """What the samples measure: small near the hole and the lower edge."""
    hole = np.abs(np.hypot(p[:, 0] - 0.6, p[:, 1] - 0.5) - 0.2)
    return 0.02 + 0.12 * np.minimum(hole, 0.8 * p[:, 1])


def samples(count: int = 150, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random sample points over the plate's box (seeded) and their sizes."""
    points = np.random.default_rng(seed).uniform((-0.05, -0.05), (2.05, 1.05), (count, 2))
    return points, measured(points)


def main(out: Path) -> dict[str, float]:
    points, values = samples()
    size = ScatteredSize(points, values)
    mesh = injmesh.generate(PLATE, size)
    figures = {
        "samples": len(points),
        "nodes": mesh.n_points,
        "q_min": float(mesh.quality().min()),
        "size error (samples)": mesh.size_report(size).relative,
    }
    for name, value in figures.items():
        print(f"{name:22s} {value:.4g}")

    from matplotlib.figure import Figure

    from injmesh.plot import plot_mesh

    fig = Figure(figsize=(9, 4.6), layout="constrained")
    ax = fig.subplots()
    plot_mesh(mesh, ax=ax, color=None, linewidth=0.4, edgecolor="0.45")
    dots = ax.scatter(points[:, 0], points[:, 1], c=values, s=28, cmap="plasma", zorder=3,
                      edgecolors="k", linewidths=0.4)
    fig.colorbar(dots, ax=ax, label="sampled h")
    ax.set_title(f"{len(points)} samples -> {mesh.n_points} nodes, q_min {figures['q_min']:.3f}")
    fig.savefig(out / "size_scattered.png", dpi=80)
    print(f"wrote {out / 'size_scattered.png'}")
    return figures


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="output directory")
    main(parser.parse_args().out)
