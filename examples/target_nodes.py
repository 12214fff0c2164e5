"""Ask for a node count: ``generate(domain, h, target_nodes=N)``.

The size function gives the *shape* of h (where the mesh is fine, where it is coarse); with
``target_nodes`` injmesh finds the constant that scales it to about N nodes (within 3 % on
the paper's cases, usually 1 %), keeping the feature-size and gradation corrections.  From the
command line: ``injmesh generate DOMAIN --size "0.01 + 0.3*hypot(x - 1, y)" --nodes 2000``,
or ``--nodes 2000`` alone for a uniform mesh.

Run ``python examples/target_nodes.py [--out DIR]``: it prints target against obtained and
writes ``DIR/target_nodes.png`` (the same graded h at three node counts).
"""

# ruff: noqa: T201  (an example prints its table)
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import injmesh

# A quarter annulus with a notch in its lower edge: finer towards the notch's inner corner.
DOMAIN = (injmesh.Circle((0, 0), 2) & injmesh.Rectangle((0, 0), (2, 2))) - injmesh.Circle((0, 0), 0.5) \
    - injmesh.Rectangle((0.9, -0.1), (1.6, 0.08))
TARGETS = (250, 1000, 4000)


def shape(p: np.ndarray) -> np.ndarray:
    """The shape of h: seven times finer at the notch's corner (0.9, 0.08) than 1.2 away."""
    return 0.2 + np.hypot(p[:, 0] - 0.9, p[:, 1] - 0.08)


def main(out: Path, targets: tuple[int, ...] = TARGETS) -> list[tuple[int, int]]:
    meshes = [injmesh.generate(DOMAIN, shape, target_nodes=n) for n in targets]
    print("| target | nodes | error % | q_min |")
    print("|---|---|---|---|")
    for n, mesh in zip(targets, meshes, strict=True):
        print(f"| {n} | {mesh.n_points} | {100 * (mesh.n_points / n - 1):+.2f} | "
              f"{mesh.quality().min():.3f} |")

    from matplotlib.figure import Figure

    from injmesh.plot import plot_mesh

    fig = Figure(figsize=(4.2 * len(targets), 4.4), layout="constrained")
    for ax, n, mesh in zip(np.atleast_1d(fig.subplots(1, len(targets))), targets, meshes, strict=True):
        plot_mesh(mesh, ax=ax, color=None, linewidth=0.3)
        ax.set_title(f"target_nodes={n}: {mesh.n_points} nodes")
    fig.savefig(out / "target_nodes.png", dpi=80)
    print(f"wrote {out / 'target_nodes.png'}")
    return [(n, mesh.n_points) for n, mesh in zip(targets, meshes, strict=True)]


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="output directory")
    main(parser.parse_args().out)
