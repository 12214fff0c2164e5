"""Benchmark: the numba Delaunay kernel against scipy.spatial.Delaunay (Qhull), same run.

Prints, for uniform random points at each size: our time (``delaunay()``: build plus the compact
output), scipy's, and their ratio (best of ``--repeat``); then the compile cost -- import plus
the first call of every kernel with an empty numba cache (a fresh ``NUMBA_CACHE_DIR``, in a
subprocess) and the same with the cache filled -- and the time of ``flip_to_delaunay`` after a
small random move of every point (up to ``--move`` of the mean spacing in x and y) at the
largest size, on the random points (whose slivers may invert: that is detected and reported)
and on a square lattice with jittered interior nodes and straight boundary rows, the interior
nodes moving (mesh-like: no sliver, so nothing inverts, and every square's diagonal is up for
a flip).

These machines are noisy: compare the ratios measured in one run, not seconds across runs.

Usage::

    python benchmarks/delaunay_kernel.py [--sizes 1e4 1e5 1e6] [--repeat 3] [--move 0.05] [--skip-compile]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import Delaunay

from injmesh.kernels.delaunay import InvertedTriangleError, LiveTriangulation, delaunay

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import best_time as timed  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")

WARM_UP = """
import time
t0 = time.perf_counter()
import numpy as np
from injmesh.kernels.delaunay import LiveTriangulation

t1 = time.perf_counter()
p = np.random.default_rng(0).random((50, 2))
live = LiveTriangulation(p)
live.triangles
live.locate([0.5, 0.5])
v = live.insert([0.25, 0.75])
live.remove(v)
live.move(live.points + 1e-6)
live.flip_to_delaunay()
live.flip(*live.triangles[0, :2].tolist())
live.recover_edge(0, 1)
live.renumber_rows()
t2 = time.perf_counter()
timings = (t1 - t0, t2 - t1)
"""


def _report_timings() -> str:
    return WARM_UP + "print(*timings)\n"


def compile_times() -> tuple[tuple[float, float], tuple[float, float]]:
    """(import, first calls) seconds with a cold numba cache, then with that cache filled."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "PYTHONPATH": SRC}
        runs = []
        for _ in range(2):
            cmd = [sys.executable, "-c", _report_timings()]
            out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
            a, b = (float(x) for x in out.stdout.split())
            runs.append((a, b))
    return runs[0], runs[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--move", type=float, default=0.05, help="move as a fraction of the mean spacing")
    parser.add_argument("--skip-compile", action="store_true", help="skip the cold-cache compile timing")
    args = parser.parse_args(argv)

    if not args.skip_compile:
        (cold_imp, cold_call), (warm_imp, warm_call) = compile_times()
        print("compile cost (subprocess, fresh NUMBA_CACHE_DIR)")
        print(f"  cold cache : import {cold_imp:6.2f} s, first call of every kernel {cold_call:6.2f} s")
        print(f"  cached     : import {warm_imp:6.2f} s, first call of every kernel {warm_call:6.2f} s")
        print()

    exec(WARM_UP, {})  # load (or compile) every kernel in this process too, before timing
    rng = np.random.default_rng(1)
    print(f"{'N':>9} {'ours s':>9} {'scipy s':>9} {'ratio':>7} {'triangles':>10}")
    for size in args.sizes:
        n = int(size)
        p = rng.random((n, 2))
        rep = args.repeat if n <= 200_000 else 1
        ours, tri = timed(lambda p=p: delaunay(p), rep)
        theirs, simp = timed(lambda p=p: Delaunay(p).simplices, rep)
        assert len(tri) == len(simp)
        print(f"{n:>9} {ours:9.3f} {theirs:9.3f} {ours / theirs:7.3f} {len(tri):>10}")
    print()

    n = int(max(args.sizes))
    spacing = 1.0 / np.sqrt(n)
    side = int(round(np.sqrt(n)))
    g = (np.arange(side) + 0.5) / side
    x, y = np.meshgrid(g, g)
    lattice = np.column_stack([x.ravel(), y.ravel()])
    # Boundary rows stay straight, as a mesher's boundary nodes do: jittered, three of them
    # would make a sliver on the hull that the move could invert.
    inner = np.all((lattice > g[0]) & (lattice < g[-1]), axis=1)
    lattice[inner] += rng.uniform(-0.05, 0.05, (inner.sum(), 2)) / side
    print(f"flip_to_delaunay after moving every point by up to {args.move} x the mean spacing (N = {n})")
    print(f"  {'points':<28} {'rows':<10} {'build s':>8} {'renumber s':>11} {'flip pass s':>12}  result")
    cases = (("random", rng.random((n, 2)), slice(None)), ("jittered square lattice", lattice, inner))
    for name, p, free in cases:
        moved = p.copy()
        moved[free] += rng.uniform(-args.move * spacing, args.move * spacing, size=moved[free].shape)
        for rows in ("as built", "renumbered"):
            build, live = timed(lambda p=p: LiveTriangulation(p), 1)
            renumber = timed(live.renumber_rows, 1)[0] if rows == "renumbered" else 0.0
            live.move(moved)
            t = time.perf_counter()
            try:
                result = f"{live.flip_to_delaunay()} flips"
            except InvertedTriangleError as exc:
                result = f"{exc}: reported, the caller rebuilds"
            dt = time.perf_counter() - t
            print(f"  {name:<28} {rows:<10} {build:8.3f} {renumber:11.3f} {dt:12.3f}  {result}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
