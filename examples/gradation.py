"""Gradation limiting: a size that jumps 20:1 still gives well-shaped triangles.

The size asked for jumps from 0.02 to 0.4 across x = 0.5 on the unit square.  Followed as
given, the triangles along the jump cannot be both that small on one side and that large on
the other: slivers.  :func:`injmesh.sizing.limit_gradation` (Persson 2006: fast marching of
``h_i <= h_j + rate * |x_i - x_j|`` on a background grid) lowers h so that it grows by at
most ``rate`` per unit length.  ``injmesh.generate`` does this by default (``gradation=0.2``;
``gradation=None`` turns it off; ``--gradation RATE`` on the command line, 0 for off).

Run ``python examples/gradation.py [--out DIR]``: it prints q_min before and after and writes
``DIR/gradation.png`` (the two meshes side by side, coloured by quality).
"""

# ruff: noqa: T201  (an example prints its figures)
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

import injmesh
from injmesh.sizing import limit_gradation

SQUARE = injmesh.Rectangle((0, 0), (1, 1))


def jump(p: np.ndarray) -> np.ndarray:
    """0.02 left of x = 0.5, 0.4 right of it."""
    return np.where(p[:, 0] < 0.5, 0.02, 0.4)


def main(out: Path) -> dict[str, float]:
    with warnings.catch_warnings():
        # The raw jump: corrections off, smoothing capped (it does not settle), checks off so
        # the slivers are shown rather than refused.
        warnings.simplefilter("ignore")
        before = injmesh.generate(SQUARE, jump, gradation=None, feature_layers=None,
                                  max_iterations=300, strict=False)
    limited = limit_gradation(jump, SQUARE, rate=0.2)
    after = injmesh.generate(SQUARE, limited, gradation=None)  # the same as generate(SQUARE, jump)
    figures = {
        "q_min before": float(before.quality().min()),
        "q_min after": float(after.quality().min()),
        "nodes before": before.n_points,
        "nodes after": after.n_points,
    }
    for name, value in figures.items():
        print(f"{name:14s} {value:.4g}")

    from matplotlib.figure import Figure

    from injmesh.plot import plot_mesh

    fig = Figure(figsize=(12, 5.4), layout="constrained")
    left, right = fig.subplots(1, 2)
    plot_mesh(before, ax=left, vmin=0, vmax=1, colorbar=False)
    left.set_title(f"h as given: q_min {figures['q_min before']:.3f}")
    plot_mesh(after, ax=right, vmin=0, vmax=1)
    right.set_title(f"limit_gradation(rate=0.2): q_min {figures['q_min after']:.3f}")
    fig.savefig(out / "gradation.png", dpi=80)
    print(f"wrote {out / 'gradation.png'}")
    return figures


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="output directory")
    main(parser.parse_args().out)
