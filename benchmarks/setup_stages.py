"""Benchmark: the stages before smoothing, per stage, from 1e3 to 1e6 nodes and on the paper's cases.

Issue 7 asks everything before smoothing to cost a small fraction of the whole: at most about
1 s at 1e5 nodes, 10 s at 1e6, 20 ms on the paper's cases (all stages).  This prints, for the
uniform unit square (``h = sqrt(2 / (sqrt(3) N))``, as ``benchmarks/scale.py``) and for the six
paper cases, the wall seconds of each set-up stage as ``generate`` runs them:

- ``clean``: the node estimate (``boundary.estimate_nodes``) and geometry cleaning;
- ``size``: the effective size (``pipeline._target_size``: feature size and gradation);
- ``boundary``: Step 1 (``mesh_boundary``);
- ``injection``: Step 2 (``inject_nodes``).

Every figure is the best of ``--repeat`` calls after one warm-up call (compilation out of the
figure; the first call's wall time is printed beside it), as CPU seconds of this process
(``time.process_time``: the stages are single-threaded, and CPU time is what a loaded shared
machine distorts least) and, in a second table, wall seconds.  Compare figures within one run.

Usage::

    python benchmarks/setup_stages.py [--sizes 1e3,1e4,1e5,1e6] [--repeat 3] [--skip-cases]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import injmesh
from injmesh.boundary import mesh_boundary
from injmesh.cases import CASES
from injmesh.geometry import as_domain
from injmesh.injection import inject_nodes
from injmesh.pipeline import _capped, _clean, _target_size
from injmesh.sizing import as_size_function

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import machine_note, markdown_table  # noqa: E402

STAGES = ("clean", "size", "boundary", "injection")


class _Clock:
    """Wall and CPU seconds of successive stages."""

    def __init__(self) -> None:
        self.wall: dict[str, float] = {}
        self.cpu: dict[str, float] = {}
        self.t, self.c = time.perf_counter(), time.process_time()

    def lap(self, stage: str) -> None:
        t, c = time.perf_counter(), time.process_time()
        self.wall[stage], self.cpu[stage] = t - self.t, c - self.c
        self.t, self.c = t, c


def stages(domain: Any, size: Any) -> tuple[dict[str, float], dict[str, float], int]:
    """Wall and CPU seconds of each set-up stage of ``generate``, and the number of nodes placed."""
    clock = _Clock()
    dom = as_domain(domain)
    h = as_size_function(size)
    dom, _, _, _ = _clean(dom, h)
    clock.lap("clean")
    _, follow = _target_size(dom, h, 2.0, 0.2)
    clock.lap("size")
    follow = _capped(follow, dom.diameter)
    bnd = mesh_boundary(dom, follow, np.empty((0, 2)), max_nodes=10**8)
    clock.lap("boundary")
    injected = inject_nodes(dom, follow, bnd, bnd.points, max_nodes=10**8)
    clock.lap("injection")
    return clock.wall, clock.cpu, len(bnd.points) + len(injected)


Timing = tuple[dict[str, float], dict[str, float], float, int]


def best(fn: Callable[[], tuple[dict[str, float], dict[str, float], int]], repeat: int) -> Timing:
    """Per-stage best wall and CPU seconds of ``repeat`` calls after a warm-up, the warm-up's
    wall total, and N."""
    first, _, n = fn()
    wall = {k: math.inf for k in STAGES}
    cpu = {k: math.inf for k in STAGES}
    for _ in range(repeat):
        w, c, n = fn()
        wall = {k: min(wall[k], w[k]) for k in STAGES}
        cpu = {k: min(cpu[k], c[k]) for k in STAGES}
    return wall, cpu, sum(first.values()), n


def row(label: str, sec: dict[str, float], first: float, n: int, unit: float, fmt: str) -> list[str]:
    total = sum(sec.values())
    return [label, str(n)] + [format(sec[k] * unit, fmt) for k in STAGES] + [
        format(total * unit, fmt), format(first * unit, fmt)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1e3,1e4,1e5,1e6", help="comma-separated node counts")
    ap.add_argument("--repeat", type=int, default=3, help="timed calls after the warm-up (best kept)")
    ap.add_argument("--skip-cases", action="store_true", help="leave out the paper's six cases")
    args = ap.parse_args()
    print(f"_{machine_note()}_\n")
    results: list[tuple[str, Timing]] = []
    for s in args.sizes.split(","):
        n = float(s)
        h = math.sqrt(2.0 / (math.sqrt(3.0) * n))
        repeat = args.repeat if n < 5e5 else 1
        square = injmesh.Rectangle((0, 0), (1, 1))
        results.append((f"unit square {s}", best(lambda h=h, sq=square: stages(sq, h), repeat)))
    if not args.skip_cases:
        for name, case in CASES.items():
            timing = best(lambda case=case: stages(case.geometry, case.size), max(args.repeat, 5))
            results.append((name, timing))
    for kind, pick in (("CPU", 1), ("wall", 0)):
        for paper in (False, True):
            rows = []
            for label, timing in results:
                if label.startswith("unit square") == paper:
                    continue
                unit, fmt = (1e3, ".2f") if paper else (1.0, ".3f")
                rows.append(row(label, timing[pick], timing[2], timing[3], unit, fmt))
            if not rows:
                continue
            u = "ms" if paper else "s"
            head = ["paper case" if paper else "case", "N"] + [f"{k} {kind} {u}" for k in STAGES]
            print(markdown_table(head + [f"total {kind} {u}", f"first call wall {u}"], rows))
            print()


if __name__ == "__main__":
    main()
