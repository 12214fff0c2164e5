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
figure; the first call's time is printed beside it).  Shared, loaded machine: compare figures
within one run.

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


def stages(domain: Any, size: Any) -> tuple[dict[str, float], int]:
    """Wall seconds of each set-up stage of ``generate``, and the number of nodes placed."""
    sec: dict[str, float] = {}
    t = time.perf_counter()
    dom = as_domain(domain)
    h = as_size_function(size)
    dom, _ = _clean(dom, h)
    sec["clean"] = time.perf_counter() - t
    t = time.perf_counter()
    _, follow = _target_size(dom, h, 2.0, 0.2)
    sec["size"] = time.perf_counter() - t
    follow = _capped(follow, dom.diameter)
    t = time.perf_counter()
    bnd = mesh_boundary(dom, follow, np.empty((0, 2)), max_nodes=10**8)
    sec["boundary"] = time.perf_counter() - t
    t = time.perf_counter()
    injected = inject_nodes(dom, follow, bnd, bnd.points, max_nodes=10**8)
    sec["injection"] = time.perf_counter() - t
    return sec, len(bnd.points) + len(injected)


def best(fn: Callable[[], tuple[dict[str, float], int]], repeat: int) -> tuple[dict[str, float], float, int]:
    """Per-stage best of ``repeat`` calls after a warm-up, the warm-up's total, and N."""
    first, n = fn()
    out = {k: math.inf for k in STAGES}
    for _ in range(repeat):
        sec, n = fn()
        out = {k: min(out[k], sec[k]) for k in STAGES}
    return out, sum(first.values()), n


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
    rows = []
    for s in args.sizes.split(","):
        n = float(s)
        h = math.sqrt(2.0 / (math.sqrt(3.0) * n))
        repeat = args.repeat if n < 5e5 else 1
        sec, first, got = best(lambda h=h: stages(injmesh.Rectangle((0, 0), (1, 1)), h), repeat)
        rows.append(row(f"unit square {s}", sec, first, got, 1.0, ".3f"))
    head = ["case", "N"] + [f"{k} s" for k in STAGES] + ["total s", "first call s"]
    print(markdown_table(head, rows))
    if args.skip_cases:
        return
    rows = []
    for name, case in CASES.items():
        sec, first, got = best(lambda case=case: stages(case.geometry, case.size), max(args.repeat, 5))
        rows.append(row(name, sec, first, got, 1e3, ".2f"))
    print()
    head = ["paper case", "N"] + [f"{k} ms" for k in STAGES] + ["total ms", "first call ms"]
    print(markdown_table(head, rows))


if __name__ == "__main__":
    main()
