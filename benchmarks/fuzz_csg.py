"""Benchmark: random set operations, regions, curves and sizes, as a careless user writes them.

Each seed draws a domain of one to three operands (circles, rectangles, star polygons) joined by
``|``, ``-`` or ``&``, half of them with coordinates snapped to a 1/8 grid (so operands share
edges, touch at points and are tangent, as hand-written geometry is); zero to two regions (half
in four clipped to the domain with ``&``, the rest as drawn, possibly overlapping it or each
other); zero or one polyline through random inside points; and a size: uniform, a cone about a
random point, or a jump from h0/4 to h0 across x = 0.5.  ``--seed S --count 1`` reproduces case
S.

Each case runs ``injmesh.generate`` in a worker process with a time limit and is classified:

- **valid**: a mesh (``generate`` checks its own output and raises ``MeshError`` otherwise),
  whose triangles cover the domain's exact area (the B-rep's, arcs included) within
  ``AREA_TOL``, plus the segments its longest boundary edge cuts off the arcs, plus a few per
  cent of a sliver per bridged cusp, and whose region areas add up to it;
- **invalid**: a ``MeshError`` (a mesh that failed injmesh's own checks), or an area check
  failed;
- **refused**: another ``ValueError``/``TypeError`` subclass of injmesh's (the input was bad:
  a region outside the domain, an empty intersection, a self-crossing curve);
- **crashed**: any other exception, or the worker died;
- **timeout**: no answer within ``--timeout`` seconds.

The table gives the counts, q_min percentiles of the valid meshes (all of them, and those with
no curve, whose random kinks cap q by their angle), and the slowest case.  Cases that were not
valid are listed with their seed and message.

Usage::

    python benchmarks/fuzz_csg.py [--count 300] [--seed 0] [--timeout 60]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import machine_note  # noqa: E402

#: Mesh area against the domain's exact area (relative), besides chords and cleaning.
AREA_TOL = 5e-3
STATUSES = ("valid", "invalid", "refused", "crashed", "timeout")


def _star(rng: np.random.Generator, c: np.ndarray, r: float, k: int) -> Any:
    from injmesh import Polygon

    ang = (np.arange(k) + rng.uniform(0, 0.8, k)) * 2 * np.pi / k
    rad = r * rng.uniform(0.4, 1.0, k)
    return Polygon(np.c_[c[0] + rad * np.cos(ang), c[1] + rad * np.sin(ang)])


def _shape(rng: np.random.Generator, lo: float, hi: float, snap: bool) -> Any:
    from injmesh import Circle, Rectangle

    def g(v: Any) -> Any:
        return np.round(np.asarray(v) * 8) / 8 if snap else np.asarray(v)

    kind = rng.integers(3)
    c = g(rng.uniform(lo, hi, 2))
    if kind == 0:
        return Circle(tuple(c), float(g(rng.uniform(0.05, 0.4))) or 0.125)
    if kind == 1:
        a, b = g(rng.uniform(lo, hi, 2)), g(rng.uniform(lo, hi, 2))
        p0, p1 = np.minimum(a, b), np.maximum(a, b)
        if np.any(p1 - p0 < 0.05):
            p1 = p0 + 0.25
        return Rectangle(tuple(p0), tuple(p1))
    return _star(rng, c, rng.uniform(0.1, 0.4), int(rng.integers(3, 9)))


def draw(seed: int) -> tuple[Any, dict[str, Any], dict[str, np.ndarray], Any, str]:
    """The case of ``seed``: domain, regions, curves, size and a one-line description."""
    rng = np.random.default_rng([seed, 9])
    snap = bool(rng.integers(2))
    dom = _shape(rng, 0.0, 1.0, snap)
    ops = []
    for _ in range(int(rng.integers(0, 3))):
        op = int(rng.integers(3))
        other = _shape(rng, 0.0, 1.0, snap)
        dom = dom | other if op == 0 else (dom - other if op == 1 else dom & other)
        ops.append("|-&"[op])
    regions: dict[str, Any] = {}
    curves: dict[str, np.ndarray] = {}
    x0, y0, x1, y1 = dom.bbox
    for i in range(int(rng.integers(0, 3))):
        r = _shape(rng, min(x0, x1), max(x0, x1), snap)
        regions[f"r{i}"] = r & dom if rng.integers(4) else r
    if x1 > x0 and y1 > y0 and rng.integers(2):
        cand = np.c_[rng.uniform(x0, x1, 200), rng.uniform(y0, y1, 200)]
        inside = cand[dom.sdf(cand) < -0.02]
        k = int(rng.integers(2, 5))
        if len(inside) >= k:
            curves["c0"] = inside[rng.choice(len(inside), k, replace=False)]
    kind = int(rng.integers(3))
    h0 = float(rng.uniform(0.02, 0.1))
    if kind == 0:
        size: Any = h0
    elif kind == 1:
        cx, cy = rng.uniform(0, 1, 2)
        size = lambda p: h0 * (0.3 + np.hypot(p[:, 0] - cx, p[:, 1] - cy))  # noqa: E731
    else:
        size = lambda p: np.where(p[:, 0] < 0.5, h0 / 4, h0)  # noqa: E731
    what = (f"{len(ops) + 1} operand(s) {' '.join(ops) or '(no operation)'}, "
            f"{'snapped' if snap else 'free'}, {len(regions)} region(s), {len(curves)} curve(s), "
            f"size {['uniform', 'cone', 'jump'][kind]} h0={h0:.3f}")
    return dom, regions, curves, size, what


def run_case(seed: int) -> dict[str, Any]:
    import injmesh

    dom, regions, curves, size, what = draw(seed)
    out: dict[str, Any] = {"seed": seed, "what": what}
    t = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh = injmesh.generate(dom, size, regions=regions or None, curves=curves or None,
                                    max_nodes=300_000)
    except injmesh.MeshError as exc:
        out.update(status="invalid", detail=str(exc)[:160])
    except (ValueError, TypeError) as exc:
        ours = type(exc).__module__.startswith("injmesh")
        out.update(status="refused" if ours else "crashed", detail=f"{type(exc).__name__}: {str(exc)[:120]}")
    except Exception as exc:  # noqa: BLE001 - every other failure is what this script counts
        out.update(status="crashed", detail=f"{type(exc).__name__}: {str(exc)[:120]}")
    else:
        out.update(_check(mesh, dom, regions))
        out["curves"] = bool(curves)
    out["seconds"] = time.perf_counter() - t
    return out


def _check(mesh: Any, dom: Any, regions: dict[str, Any]) -> dict[str, Any]:
    p, t = mesh.points, mesh.triangles
    a, b = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    area = 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    res: dict[str, Any] = {"status": "valid", "q_min": float(mesh.quality().min()), "n": mesh.n_points}
    exact = dom.exact_brep() if hasattr(dom, "exact_brep") else dom
    if exact is not None and hasattr(exact, "area"):
        want = float(exact.area)
        # Chords of length l cut the arcs' segments off: r^2 (t - sin t) / 2 each, t = l / r,
        # with l the longest boundary edge; a bridged cusp may take a few per cent of a sliver.
        e = mesh.boundary_edges
        longest = float(np.hypot(*(p[e[:, 1]] - p[e[:, 0]]).T).max())
        arc = exact._sw != 0
        chords = 0.0
        if arc.any():
            r = exact._r[arc]
            t = np.minimum(longest / r, np.pi)
            chords = float(np.sum(np.abs(exact._sw[arc]) / t * r * r * (t - np.sin(t)) / 2))
        slack = AREA_TOL * want + 1.5 * chords + 0.05 * want * mesh.stats.cleaning.get("cusps", 0)
        if abs(float(area.sum()) - want) > slack:
            res.update(status="invalid",
                       detail=f"area {area.sum():.6g} against {want:.6g} (slack {slack:.3g})")
    if regions:
        per = np.bincount(mesh.triangle_tags, weights=area, minlength=len(mesh.region_names))
        if abs(per.sum() - area.sum()) > 1e-9 * area.sum():
            res.update(status="invalid", detail="region areas do not add up")
    return res


def _worker(conn: Any) -> None:
    while True:
        seed = conn.recv()
        if seed is None:
            return
        conn.send(run_case(seed))


def run_all(seeds: list[int], timeout: float) -> list[dict[str, Any]]:
    ctx = mp.get_context("spawn")
    results = []
    parent = proc = None

    def start() -> tuple[Any, Any]:
        a, b = ctx.Pipe()
        pr = ctx.Process(target=_worker, args=(b,), daemon=True)
        pr.start()
        return a, pr

    parent, proc = start()
    for seed in seeds:
        parent.send(seed)
        if parent.poll(timeout):
            try:
                results.append(parent.recv())
                continue
            except EOFError:
                res = {"seed": seed, "what": draw(seed)[4], "status": "crashed", "detail": "worker died"}
        else:
            res = {"seed": seed, "what": draw(seed)[4], "status": "timeout",
                   "detail": f"no answer in {timeout:g} s", "seconds": timeout}
        proc.kill()
        proc.join()
        results.append(res)
        parent, proc = start()
    parent.send(None)
    proc.join(timeout=5)
    return results


def _pct(values: list[float], q: float) -> str:
    return f"{np.percentile(values, q):.3f}" if values else "-"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=300)
    ap.add_argument("--seed", type=int, default=0, help="first seed")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per case")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = run_all(list(range(args.seed, args.seed + args.count)), args.timeout)
    wall = time.perf_counter() - t0
    print(f"_{machine_note()}; {args.count} cases from seed {args.seed} in {wall:.0f} s._\n")
    counts = {s: sum(r["status"] == s for r in res) for s in STATUSES}
    q_all = [r["q_min"] for r in res if r["status"] == "valid"]
    q_plain = [r["q_min"] for r in res if r["status"] == "valid" and not r.get("curves")]
    slow = max(res, key=lambda r: r.get("seconds", 0.0))
    print("| cases | " + " | ".join(STATUSES) + " | q_min 1% / 10% / median | without a curve | slowest |")
    print("|---|" + "---|" * len(STATUSES) + "---|---|---|")
    print(f"| {len(res)} | " + " | ".join(str(counts[s]) for s in STATUSES)
          + f" | {_pct(q_all, 1)} / {_pct(q_all, 10)} / {_pct(q_all, 50)}"
          + f" | {_pct(q_plain, 1)} / {_pct(q_plain, 10)} / {_pct(q_plain, 50)}"
          + f" | {slow.get('seconds', 0):.1f} s (seed {slow['seed']}) |")
    refused: dict[str, int] = {}
    for r in res:
        if r["status"] == "refused":
            key = r["detail"].split(":")[0]
            refused[key] = refused.get(key, 0) + 1
    if refused:
        print("\nRefused: " + ", ".join(f"{k} {v}" for k, v in sorted(refused.items())))
    bad = [r for r in res if r["status"] not in ("valid", "refused")]
    if bad:
        print("\n| seed | status | case | detail |\n|---|---|---|---|")
        for r in bad:
            print(f"| {r['seed']} | {r['status']} | {r['what']} | {r.get('detail', '')} |")


if __name__ == "__main__":
    main()
