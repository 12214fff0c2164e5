"""Benchmark: the compiled boundary representation.

Prints, for a fractal-like closed outline of ``--vertices`` vertices (default 20 000, in UTM-like
coordinates): construction (validation sweep included), 1e5 signed distances and 1e5
projections at random points of its box, and the same near the boundary; then the CSG L-shape
``Rectangle - Rectangle`` against the Polygon L-shape (nodes, q_min, seconds at h = 0.1); and,
with ``--compile``, the first-call compile cost of the kernels in a fresh cache.

Usage::

    python benchmarks/geometry.py [--vertices 20000] [--queries 100000] [--compile]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

import injmesh
from injmesh import Polygon, Rectangle


def outline(n: int, seed: int = 0) -> np.ndarray:
    """A star-like outline with detail at six scales (a coastline stand-in), metres at x ~ 5e5."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = 1 + 0.3 * np.sin(7 * ang)
    for k in (13, 31, 77, 190, 500, 1300):
        r += (0.6 / k) * np.sin(k * ang + rng.uniform(0, 2 * np.pi))
    return np.stack([r * np.cos(ang), r * np.sin(ang)], axis=1) * 1000 + [5e5, 4e6]


def best(fn, repeat: int = 3) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Best wall and best CPU seconds of ``repeat`` calls (CPU time is the fairer figure on a
    shared machine)."""
    wall = cpu = np.inf
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - t)
        cpu = min(cpu, time.process_time() - c)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=20000)
    ap.add_argument("--queries", type=int, default=100000)
    ap.add_argument("--compile", action="store_true", help="measure the compile cost in a fresh cache")
    args = ap.parse_args()
    warnings.simplefilter("ignore", injmesh.ConvergenceWarning)

    v = outline(args.vertices)
    Polygon([(0, 0), (1, 0), (0, 1)]).sdf(v[:3])  # load the compiled kernels once
    t_build = best(lambda: Polygon(v))
    poly = Polygon(v)
    rng = np.random.default_rng(1)
    x0, y0, x1, y1 = poly.bbox
    q = rng.uniform([x0, y0], [x1, y1], (args.queries, 2))
    near = poly.project(q) + rng.normal(scale=0.005 * poly.diameter, size=q.shape)

    def fresh_index() -> None:
        Polygon(v).sdf(q[:1])

    t_index = best(fresh_index)
    rows = [
        ("construction (validation sweep)", t_build),
        ("construction + index + 1 query", t_index),
        (f"{args.queries:.0e} sdf, random in box", best(lambda: poly.sdf(q))),
        (f"{args.queries:.0e} project, random in box", best(lambda: poly.project(q))),
        (f"{args.queries:.0e} sdf, near the boundary", best(lambda: poly.sdf(near))),
        (f"{args.queries:.0e} project, near the boundary", best(lambda: poly.project(near))),
    ]
    print(f"| {args.vertices}-vertex outline | wall s | CPU s |\n|---|---|---|")
    for name, (wall, cpu) in rows:
        print(f"| {name} | {wall:.3f} | {cpu:.3f} |")
    wall = t_index[0] + rows[2][1][0] + rows[3][1][0]
    cpu = t_index[1] + rows[2][1][1] + rows[3][1][1]
    print(f"| construction + {args.queries:.0e} sdf + {args.queries:.0e} project | {wall:.3f} | {cpu:.3f} |")

    print("\n| L-shape, h = 0.1 | nodes | q_min | q_mean | seconds |\n|---|---|---|---|---|")
    for name, dom in (
        ("Rectangle - Rectangle (CSG)", Rectangle((-1, -1), (1, 1)) - Rectangle((0, -1), (1, 0))),
        ("Polygon", Polygon([(-1, -1), (0, -1), (0, 0), (1, 0), (1, 1), (-1, 1)])),
    ):
        t = time.perf_counter()
        mesh = injmesh.generate(dom, 0.1)
        t = time.perf_counter() - t
        qual = mesh.quality()
        print(f"| {name} | {mesh.n_points} | {qual.min():.4f} | {qual.mean():.4f} | {t:.3f} |")

    if args.compile:
        code = (
            "import time; t = time.perf_counter(); from injmesh import Polygon, Rectangle, Circle; "
            "import numpy as np; p = Polygon([(0, 0), (1, 0), (1, 1), (0, 1)]); p.sdf(np.zeros((1, 2))); "
            "c = Rectangle((0, 0), (2, 2)) - Circle((1, 1), 0.5); c.sdf(np.zeros((1, 2))); "
            "print(f'{time.perf_counter() - t:.1f}')"
        )
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            cold = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
            warm = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        print(f"\nfirst use of the kernels: {cold.stdout.strip()} s with an empty cache, "
              f"{warm.stdout.strip()} s from the cache")


if __name__ == "__main__":
    main()
