"""Benchmark: the corner cap of h (``boundary.corner_size``) where the mesher asks it.

Issue 8's 20,000-vertex outline (``robustness.py --real``, case "large") lowers h near its
corners with ``min(h, min_c (s_c + rate |p - c|))`` over every corner c
(:func:`injmesh.kernels.outline.corner_cones`).  Smoothing asks it at the midpoints of the bars
that moved: batches of a few points to the whole mesh, in the mesh's node order, nearly all of
them near the boundary.  This meshes that outline once, records every batch the cap is asked
(wrapping ``boundary._CornerCap.__call__``), then prints the cap's cost per point on those
batches (all of them, and those of 1,000 to 10,000 points) and on uniform random points over
the corners' box, and the time to build its search structure (``cone_index``) over the
recorded corners and over the 20,000 vertices of the raw outline.  Figures are the best of
``--repeat`` passes (median beside it).

Usage::

    python benchmarks/corner_cones.py [--vertices 20000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import injmesh
from injmesh import boundary, shapes
from injmesh.kernels.outline import cone_index, corner_cones

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import machine_note, markdown_table  # noqa: E402


def record(n_vertices: int) -> tuple[boundary._CornerCap, list[tuple[np.ndarray, np.ndarray]]]:
    """Mesh the outline; the cap with the most corners and the batches it was asked (points, h)."""
    from injmesh.inputs import read_geojson

    caps: dict[int, tuple[boundary._CornerCap, list[tuple[np.ndarray, np.ndarray]]]] = {}
    original = boundary._CornerCap.__call__

    def recording(self: boundary._CornerCap, p: np.ndarray) -> np.ndarray:
        if len(p):
            caps.setdefault(id(self), (self, []))[1].append((np.array(p, dtype=float), np.array(self.h(p))))
        return original(self, p)

    domain = read_geojson(shapes.to_geojson(shapes.large(0, n_vertices=n_vertices)))
    boundary._CornerCap.__call__ = recording  # type: ignore[method-assign]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            injmesh.generate(domain, 0.02, strict=False)
    finally:
        boundary._CornerCap.__call__ = original  # type: ignore[method-assign]
    return max(caps.values(), key=lambda c: len(c[0].corners))


def timed(fn: object, repeat: int) -> tuple[float, float]:
    """Best and median wall seconds of ``repeat`` calls of ``fn()``."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t)
    return min(times), statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--vertices", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)

    cap, batches = record(args.vertices)
    index = cap.index
    mid = [b for b in batches if 1_000 <= len(b[0]) <= 10_000]
    rng = np.random.default_rng(0)
    lo, hi = cap.corners.min(axis=0), cap.corners.max(axis=0)
    uniform = lo + rng.random((200_000, 2)) * (hi - lo)
    h_uniform = cap.h(uniform)

    def run(chosen: list[tuple[np.ndarray, np.ndarray]]) -> None:
        for p, hp in chosen:
            corner_cones(p, hp, index)

    rows = []
    for label, chosen in (("recorded batches, all", batches), ("recorded, 1k-10k points", mid),
                          ("uniform over the corners' box", [(uniform, h_uniform)])):
        n = sum(len(p) for p, _ in chosen)
        run(chosen)  # compiled, caches warm
        best, median = timed(lambda chosen=chosen: run(chosen), args.repeat)
        rows.append([label, len(chosen), n, f"{best / n * 1e9:.0f}", f"{median / n * 1e9:.0f}"])
    print(f"corner_cones on the {args.vertices}-vertex outline's cap ({len(cap.corners)} corners); "
          + machine_note())
    print(markdown_table(["points", "batches", "points", "ns/point (best)", "ns/point (median)"], rows))

    ring = np.ascontiguousarray(shapes.large(0, n_vertices=args.vertices).rings[0], dtype=float)
    spacing = np.hypot(*(np.roll(ring, -1, axis=0) - ring).T)
    rows = []
    for label, corners, s, rate, margin, h_max in (
        ("recorded corners", cap.corners, cap.spacing, cap.rate, None, None),
        (f"the {len(ring)} outline vertices", ring, spacing, 0.2, 0.1, 0.02),
    ):
        if margin is None:  # as boundary._CornerCap builds it
            h_max = float(np.max(cap.h(corners)))
            reach = (h_max - float(s.min())) / rate
            margin = min(reach, float(np.ptp(corners, axis=0).max()))
        build_args = (corners, s, float(rate), boundary.CONE_LEAF, margin,
                      boundary.CONE_CELLS * len(corners), h_max)
        cone_index(*build_args)
        best, median = timed(lambda a=build_args: cone_index(*a), args.repeat)
        rows.append([label, len(corners), f"{best * 1e3:.1f}", f"{median * 1e3:.1f}"])
    print()
    print(markdown_table(["cone_index over", "corners", "ms (best)", "ms (median)"], rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
