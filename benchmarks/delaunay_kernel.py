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

Then the public functions of ``injmesh.triangulation`` and ``injmesh.quality`` that Step 3 calls
over and over, each timed (best of ``--repeat``; one call at 1e6) in a fresh subprocess on a
mesh-like input of each size: a square lattice with jittered interior nodes and straight outer
rows; ``flip_to_delaunay`` after moving the interior nodes by up to ``--move`` of the spacing;
``classify_by_walls`` and ``inside_triangles`` with the outer rows as walls; ``recover_segments``
for a circle of segments three spacings long laid through the lattice (Delaunay drops many of
them).  With ``--before REV`` the same subprocess also runs on the source of git revision REV
(``git archive`` into a temporary directory): the before/after table of the compiled stage.

These machines are noisy: compare the ratios measured in one run, not seconds across runs.

Usage::

    python benchmarks/delaunay_kernel.py [--sizes 1e4 1e5 1e6] [--repeat 3] [--move 0.05] [--skip-compile]
                                         [--before REV] [--skip-kernel]
"""

from __future__ import annotations

import argparse
import json
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
from injmesh import quality, triangulation as tr
t = tr.delaunay(p)
tr.flip_to_delaunay(p, t)
tr.recover_segments(p, t, np.array([[0, 1]]))
tr.inside_triangles(p, t, lambda q: q[:, 0] - 2.0, tr.boundary_edges(t))
tr.neighbours(t)
quality.unique_edges(t)
quality.signed_areas(p, t)
quality.edge_lengths(p, t)
quality.triangle_quality(p, t)
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


FUNCTIONS = (
    "delaunay", "flip_to_delaunay", "unique_edges", "neighbours", "boundary_edges", "signed_areas",
    "edge_lengths", "triangle_quality", "classify_by_walls", "inside_triangles", "recover_segments",
)


def function_times(sizes: list[float], repeat: int, move: float) -> dict[str, dict[str, float]]:
    """Seconds of each public function at each size, in this process (see the module docstring)."""
    exec(WARM_UP, {})
    out: dict[str, dict[str, float]] = {name: {} for name in FUNCTIONS}
    for size in sizes:
        _time_size(out, size, repeat if size <= 2e5 else 1, move)
    return out


def _time_size(out: dict[str, dict[str, float]], size: float, rep: int, move: float) -> None:
    from injmesh import quality
    from injmesh import triangulation as tr

    rng = np.random.default_rng(2)
    side = int(round(np.sqrt(size)))
    g = np.arange(side, dtype=float)
    x, y = np.meshgrid(g, g)
    p = np.column_stack([x.ravel(), y.ravel()])
    inner = np.all((p > 0) & (p < side - 1), axis=1)
    p[inner] += rng.uniform(-0.2, 0.2, (inner.sum(), 2))
    moved = p.copy()
    moved[inner] += rng.uniform(-move, move, (inner.sum(), 2))
    # The outer rows, counter-clockwise: walls with the domain on their left.
    ring = np.concatenate([np.arange(side - 1), side - 1 + side * np.arange(side - 1),
                           side * side - 1 - np.arange(side - 1), side * (side - 1 - np.arange(side - 1))])
    walls = np.column_stack([ring, np.roll(ring, -1)])
    # A circle of segments three spacings long, lattice nodes closer than 0.3 removed.
    c, r = (side - 1) / 2, 0.35 * side
    k = int(2 * np.pi * r / 3.0)
    a = 2 * np.pi * np.arange(k) / k
    circle = np.concatenate([c + r * np.column_stack([np.cos(a), np.sin(a)]),
                             p[np.abs(np.hypot(*(p - c).T) - r) > 0.3]])
    segments = np.column_stack([np.arange(k), np.roll(np.arange(k), -1)])
    key = f"{size:.0e}"
    out["delaunay"][key], tri = timed(lambda: tr.delaunay(p), rep)
    out["flip_to_delaunay"][key], flipped = timed(lambda: tr.flip_to_delaunay(moved, tri), rep)
    if flipped is None:  # declined: the figure would not be a flip pass
        out["flip_to_delaunay"][key] = float("nan")
    out["unique_edges"][key], _ = timed(lambda: quality.unique_edges(tri), rep)
    out["neighbours"][key], _ = timed(lambda: tr.neighbours(tri), rep)
    out["boundary_edges"][key], _ = timed(lambda: tr.boundary_edges(tri), rep)
    out["signed_areas"][key], _ = timed(lambda: quality.signed_areas(p, tri), rep)
    out["edge_lengths"][key], _ = timed(lambda: quality.edge_lengths(p, tri), rep)
    out["triangle_quality"][key], _ = timed(lambda: quality.triangle_quality(p, tri), rep)
    out["classify_by_walls"][key], _ = timed(lambda: tr.classify_by_walls(tri, walls), rep)
    lo, hi = 0.5, side - 1.5  # sdf of a square just inside the outer rows

    def sdf(q: np.ndarray) -> np.ndarray:
        return np.max(np.abs(q - 0.5 * (lo + hi)), axis=1) - 0.5 * (hi - lo)

    out["inside_triangles"][key], _ = timed(lambda: tr.inside_triangles(p, tri, sdf, walls), rep)
    tri_c = tr.delaunay(circle)
    out["recover_segments"][key], (_, failed) = timed(
        lambda: tr.recover_segments(circle, tri_c, segments), rep)
    out["recover_segments failed"] = {**out.get("recover_segments failed", {}), key: float(len(failed))}


def before_and_after(sizes: list[float], repeat: int, move: float, before: str | None) -> None:
    """Print the table of :func:`function_times` for REV (if given) and this tree, each in a
    subprocess of its own."""
    code = (
        "import json, sys\n"
        f"sys.path.insert(0, {str(Path(__file__).resolve().parent)!r})\n"
        "from delaunay_kernel import function_times\n"
        f"print('FUNCTIONS-JSON', json.dumps(function_times({sizes!r}, {repeat}, {move})))\n"
    )

    def run(src: str) -> dict[str, dict[str, float]]:
        env = {**os.environ, "PYTHONPATH": src}
        proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(proc.stderr)
        line = next(ln for ln in proc.stdout.splitlines() if ln.startswith("FUNCTIONS-JSON "))
        return json.loads(line.split(" ", 1)[1])  # type: ignore[no-any-return]

    with tempfile.TemporaryDirectory() as tmp:
        old = None
        if before:
            root = Path(__file__).resolve().parents[1]
            archive = subprocess.run(["git", "-C", str(root), "archive", before, "src"],
                                     capture_output=True, check=True).stdout
            subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
            old = run(str(Path(tmp) / "src"))
        new = run(SRC)
    keys = [f"{s:.0e}" for s in sizes]
    title = f"public functions, seconds (best of {repeat}; 1 call above 2e5)"
    print(title + (f": before = {before}, after = this tree" if before else ""))
    cols = " | ".join(f"{k} before | {k} after | x" if old else f"{k}" for k in keys)
    print(f"| function | {cols} |")
    print("|---|" + "---|" * (len(keys) * (3 if old else 1)))
    for name in FUNCTIONS:
        cells = []
        for k in keys:
            if old:
                cells.append(f"{old[name][k]:.4f} | {new[name][k]:.4f} | {old[name][k] / new[name][k]:.1f}")
            else:
                cells.append(f"{new[name][k]:.4f}")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e4, 1e5, 1e6])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--move", type=float, default=0.05, help="move as a fraction of the mean spacing")
    parser.add_argument("--skip-compile", action="store_true", help="skip the cold-cache compile timing")
    parser.add_argument("--before", metavar="REV", help="also time the public functions at git revision REV")
    parser.add_argument("--skip-kernel", action="store_true",
                        help="only the public functions' table (no kernel-vs-scipy and flip tables)")
    args = parser.parse_args(argv)

    if not args.skip_compile:
        (cold_imp, cold_call), (warm_imp, warm_call) = compile_times()
        print("compile cost (subprocess, fresh NUMBA_CACHE_DIR)")
        print(f"  cold cache : import {cold_imp:6.2f} s, first call of every kernel {cold_call:6.2f} s")
        print(f"  cached     : import {warm_imp:6.2f} s, first call of every kernel {warm_call:6.2f} s")
        print()

    before_and_after(args.sizes, args.repeat, args.move, args.before)
    if args.skip_kernel:
        return 0
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
