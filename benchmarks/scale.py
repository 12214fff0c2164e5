"""Benchmark: injmesh from 1e3 to 1e6 nodes, against scipy's Delaunay, gmsh and Triangle.

The uniform unit square is meshed with ``h = sqrt(2 / (sqrt(3) N))`` (equilateral packing: a
triangle of edge h has area sqrt(3)/4 h^2 and there are about two per node), so that the mesh
has about N nodes.  With ``--graded`` the unit disc is meshed too with
``h(p) = h_min (1 + 19 |p|)`` (20:1 from the centre to the rim), h_min chosen so that
``(2/sqrt(3)) * integral of h^-2`` over the disc is N.

Every run is a fresh subprocess, so its peak RSS (VmHWM) is its own.  An injmesh run first
meshes a tiny domain of the same kind (~200 nodes) and reports its time as the *first call*:
once kernels are compiled by numba, that is where the compilation cost shows.  Runs of 1e5
nodes and more then mesh the case once more at ~2e4 nodes, untimed: the kernels' threaded
variants (lists of more than 8192 nodes) and the paths a tiny mesh never takes are loaded from
numba's cache there, not in the timed run (0.3-0.8 s at 1e6 otherwise).  Then it meshes
the timed case with a progress callback that reads the CPU clock when the stage changes, so CPU
seconds per stage are measured between progress events (smoothing's includes the final validity
check; the wall seconds per stage are ``mesh.stats.seconds``).  ``B/node`` is
``(peak RSS - RSS after imports and the first call) / N``: the memory the mesh itself needed.

In the same run, the yardstick: ``scipy.spatial.Delaunay`` of as many random points as the
mesh has nodes (one Qhull call; ``ratio`` = injmesh wall / scipy wall).  With ``--peers``:
gmsh 2-D Frontal-Delaunay (Mesh.Algorithm 6, one thread) on the same domain and size function,
and Triangle (``pq30a...``, its area bound calibrated to give the same N; square only) if the
``triangle`` package is importable.  With ``--one-thread``: injmesh again with
``NUMBA_NUM_THREADS=1`` (its step kernels then run on the calling thread only), to show what
the threads gain in the same run and that the mesh is the same.  Quality q is Eq. (5.1) and
the size error is the mean of ``|l / h(midpoint) - 1|`` over edges, with respect to the same
h, for every mesher.

The issue's targets (issue 7, "A compiled core") are printed beside the measurements with a
pass/fail column.  These machines are shared and loaded: compare ratios measured in one run
(injmesh / scipy, growth exponents), not seconds across runs.

Usage::

    python benchmarks/scale.py [--sizes 1e3,1e4,1e5] [--repeat 1] [--peers] [--graded]
                               [--one-thread] [--json results.json]
    python benchmarks/scale.py --tables-from results.json   # print the tables again

``--sizes 1e3,1e4,1e5,1e6`` adds the million-node run (minutes with today's code).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import machine_note, markdown_table, peak_rss_bytes, rss_bytes  # noqa: E402

MARK = "SCALEBENCH-JSON "
GRADE = 20.0  # h_max / h_min of the graded disc
CASES = ("square", "graded")
MIB = 2.0**20
ONE_THREAD = "injmesh-1-thread"  # injmesh with NUMBA_NUM_THREADS=1 (--one-thread)

# The issue's targets (on this 2-core machine).
T_1E6 = 10.0  # seconds, uniform square, 1e6 nodes
T_1E6_SCIPY = 1.2  # at most this many scipy Delaunay calls of 1e6 points
T_1E5 = 1.0  # seconds, uniform square, 1e5 nodes
GROWTH_1E6_1E5 = 12.0  # t(1e6) / t(1e5)
RSS_PER_NODE = 1000.0  # bytes
Q_MIN = 0.8
Q_MEAN = 0.999
SIZE_ERROR = 0.01
T_GRADED_1E6 = 15.0  # seconds, graded disc, 1e6 nodes


# --- sizes ---------------------------------------------------------------------------------


def uniform_h(n: float) -> float:
    """Edge length giving about ``n`` nodes on the unit square (equilateral packing)."""
    return math.sqrt(2.0 / (math.sqrt(3.0) * n))


def graded_hmin(n: float) -> float:
    """h_min giving about ``n`` nodes on the unit disc with ``h = h_min (1 + (G-1) r)``.

    N = (2/sqrt(3)) * integral of 2 pi r / h(r)^2 dr over [0, 1], and with u = 1 + (G-1) r,
    integral of r / (1 + (G-1) r)^2 dr = (ln G + 1/G - 1) / (G-1)^2.
    """
    g = GRADE
    integral = (math.log(g) + 1.0 / g - 1.0) / (g - 1.0) ** 2
    return math.sqrt(2.0 / math.sqrt(3.0) * 2.0 * math.pi * integral / n)


def size_function(case: str, n: float) -> Callable[[np.ndarray], np.ndarray]:
    """The size function h(p) of a case at about ``n`` nodes."""
    if case == "square":
        h = uniform_h(n)
        return lambda p: np.full(len(p), h)
    hmin = graded_hmin(n)
    return lambda p: hmin * (1.0 + (GRADE - 1.0) * np.hypot(p[:, 0], p[:, 1]))


def quality_figures(points: np.ndarray, triangles: np.ndarray, h: Callable[..., np.ndarray]) -> dict:
    """q_min, q_mean (Eq. 5.1) and relative size error of any mesher's output."""
    from injmesh.quality import size_report, triangle_quality

    q = triangle_quality(points, triangles)
    return {
        "N": int(len(np.unique(triangles))),
        "triangles": int(len(triangles)),
        "q_min": float(q.min()),
        "q_mean": float(q.mean()),
        "size_error": size_report(points, triangles, h).relative,
    }


# --- children: one measured run each, in a fresh process ----------------------------------


class StageClock:
    """Progress callback: CPU seconds per stage, read when the stage changes."""

    def __init__(self, first: str) -> None:
        self.cpu: dict[str, float] = {}
        self.stage: str | None = first
        self.t = time.process_time()

    def __call__(self, event: Any) -> None:
        if event.stage != self.stage:
            self.switch(event.stage)

    def switch(self, stage: str | None) -> None:
        now = time.process_time()
        if self.stage is not None:
            self.cpu[self.stage] = self.cpu.get(self.stage, 0.0) + now - self.t
        self.stage, self.t = stage, now


def child_injmesh(case: str, n: float) -> dict:
    import injmesh

    warnings.simplefilter("ignore", injmesh.ConvergenceWarning)
    domain = injmesh.Rectangle((0, 0), (1, 1)) if case == "square" else injmesh.Circle((0, 0), 1)
    t = time.perf_counter()
    injmesh.generate(domain, size_function(case, 200))
    first_call = time.perf_counter() - t
    base = rss_bytes()  # before the second warm-up: what it keeps counts against B/node
    if n >= 1e5:
        injmesh.generate(domain, size_function(case, 2e4))

    size = size_function(case, n)
    clock = StageClock("boundary")
    c0, t0 = time.process_time(), time.perf_counter()
    mesh = injmesh.generate(domain, size, max_nodes=10**8, callback=clock)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    clock.switch(None)
    peak = peak_rss_bytes()
    out = quality_figures(mesh.points, mesh.triangles, size)
    out.update(
        wall=wall, cpu=cpu, stage_wall=dict(mesh.stats.seconds), stage_cpu=clock.cpu,
        iterations=mesh.stats.iterations, converged=mesh.stats.converged, valid=mesh.stats.valid,
        peak_rss=peak, base_rss=base, first_call=first_call,
        digest=hashlib.sha256(mesh.points.tobytes() + mesh.triangles.tobytes()).hexdigest()[:16],
    )
    return out


def child_scipy(n: float) -> dict:
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(0)
    Delaunay(rng.random((100, 2)))  # load Qhull before the baseline
    pts = rng.random((int(n), 2))
    base = rss_bytes()
    c0, t0 = time.process_time(), time.perf_counter()
    tri = Delaunay(pts)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"N": int(n), "triangles": int(len(tri.simplices)), "wall": wall, "cpu": cpu,
            "peak_rss": peak_rss_bytes(), "base_rss": base}


def child_gmsh(case: str, n: float) -> dict:
    import gmsh

    size = size_function(case, n)
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay
        for name in ("Mesh.MeshSizeFromPoints", "Mesh.MeshSizeFromCurvature",
                     "Mesh.MeshSizeExtendFromBoundary"):
            gmsh.option.setNumber(name, 0)
        gmsh.model.add(case)
        if case == "square":
            gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
            h = uniform_h(n)
            gmsh.option.setNumber("Mesh.MeshSizeMin", h)
            gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        else:
            gmsh.model.occ.addDisk(0, 0, 0, 1, 1)
            field = gmsh.model.mesh.field.add("MathEval")
            gmsh.model.mesh.field.setString(
                field, "F", f"{graded_hmin(n)!r} * (1 + {GRADE - 1.0!r} * Sqrt(x*x + y*y))"
            )
            gmsh.model.mesh.field.setAsBackgroundMesh(field)
        gmsh.model.occ.synchronize()
        base = rss_bytes()
        c0, t0 = time.process_time(), time.perf_counter()
        gmsh.model.mesh.generate(2)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, nodes = gmsh.model.mesh.getElementsByType(2)  # 3-node triangles
        peak = peak_rss_bytes()
    finally:
        gmsh.finalize()
    index = np.zeros(int(tags.max()) + 1, dtype=np.intp)
    index[tags.astype(np.intp)] = np.arange(len(tags))
    points = coords.reshape(-1, 3)[:, :2]
    triangles = index[nodes.astype(np.intp).reshape(-1, 3)]
    out = quality_figures(points, triangles, size)
    out.update(wall=wall, cpu=cpu, peak_rss=peak, base_rss=base)
    return out


def child_triangle(n: float) -> dict:
    import triangle

    pslg = {"vertices": np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
            "segments": np.array([[0, 1], [1, 2], [2, 3], [3, 0]])}
    # Calibrate the area bound (twice) so that the mesh has about n nodes: Triangle's triangles
    # are on average well below the bound, so sqrt(3)/4 h^2 alone would give too many.
    area = math.sqrt(3.0) / 4.0 * uniform_h(n) ** 2
    for _ in range(2):
        got = len(triangle.triangulate(pslg, f"pq30a{area:.15f}")["vertices"])
        area *= got / n
    base = rss_bytes()
    c0, t0 = time.process_time(), time.perf_counter()
    res = triangle.triangulate(pslg, f"pq30a{area:.15f}")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    peak = peak_rss_bytes()
    out = quality_figures(res["vertices"], res["triangles"], size_function("square", n))
    out.update(wall=wall, cpu=cpu, peak_rss=peak, base_rss=base)
    return out


def child(tool: str, case: str, n: float) -> dict:
    import injmesh.quality  # noqa: F401  (scipy: loaded before any baseline RSS is read)

    if tool in ("injmesh", ONE_THREAD):
        return child_injmesh(case, n)
    if tool == "scipy":
        return child_scipy(n)
    if tool == "gmsh":
        return child_gmsh(case, n)
    if tool == "triangle":
        return child_triangle(n)
    raise ValueError(f"unknown tool {tool!r}")


# --- parent: runs, tables, targets --------------------------------------------------------


def available(module: str) -> bool:
    """Whether a peer's Python package is importable (checked in a child: gmsh loads a big .so)."""
    code = f"import importlib.util, sys; sys.exit(importlib.util.find_spec({module!r}) is None)"
    return subprocess.run([sys.executable, "-c", code], check=False).returncode == 0


def run(tool: str, case: str, n: float, repeat: int, timeout: float) -> dict:
    """The best (least wall time) of ``repeat`` runs, each in a fresh process."""
    best: dict | None = None
    for _ in range(repeat):
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", tool, "--case", case,
               "--n", repr(float(n))]
        env = dict(os.environ, NUMBA_NUM_THREADS="1") if tool == ONE_THREAD else None
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False,
                               env=env)
        except subprocess.TimeoutExpired:
            return {"error": f"timed out after {timeout:.0f} s"}
        lines = [ln for ln in p.stdout.splitlines() if ln.startswith(MARK)]
        if p.returncode != 0 or not lines:
            tail = (p.stderr.strip().splitlines() or ["no output"])[-1]
            return {"error": f"exit {p.returncode}: {tail}"}
        rec = json.loads(lines[-1][len(MARK):])
        if best is None or rec["wall"] < best["wall"]:
            best = rec
    assert best is not None
    return best


def fmt(x: float | None, spec: str) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def per_node(rec: dict) -> float:
    return (rec["peak_rss"] - rec["base_rss"]) / rec["N"]


def stage_cell(rec: dict, stage: str) -> str:
    w = rec["stage_wall"].get(stage)
    c = rec["stage_cpu"].get(stage)
    return f"{fmt(w, '.2f')} / {fmt(c, '.2f')}"


def exponent(t1: float, t2: float, n1: float, n2: float) -> float:
    return math.log(t2 / t1) / math.log(n2 / n1)


def injmesh_table(results: dict) -> str:
    header = ["target N", "N", "triangles", "wall s", "CPU s", "boundary s (wall / CPU)",
              "injection s", "smoothing s", "iter", "q_min", "q_mean", "size err", "peak MiB",
              "B/node", "first call s", "scipy Delaunay s",
              "injmesh / scipy (wall, CPU)"]
    rows = []
    for n, r in results.items():
        inj, sci = r["injmesh"], r.get("scipy", {})
        if "error" in inj:
            rows.append([f"{n:.0e}", inj["error"]] + [""] * (len(header) - 2))
            continue
        sci_ok = "error" not in sci and "wall" in sci
        flags = "" if inj["converged"] and inj["valid"] else " (" + ", ".join(
            w for w, ok in (("not converged", inj["converged"]), ("INVALID", inj["valid"])) if not ok
        ) + ")"
        rows.append([
            f"{n:.0e}", inj["N"], inj["triangles"], f"{inj['wall']:.2f}", f"{inj['cpu']:.2f}",
            stage_cell(inj, "boundary"), stage_cell(inj, "injection"), stage_cell(inj, "smoothing"),
            f"{inj['iterations']}{flags}", f"{inj['q_min']:.4f}", f"{inj['q_mean']:.5f}",
            f"{inj['size_error']:.4f}", f"{inj['peak_rss'] / MIB:.0f}", f"{per_node(inj):.0f}",
            f"{inj['first_call']:.2f}", fmt(sci.get("wall") if sci_ok else None, ".3f"),
            f"{inj['wall'] / sci['wall']:.1f} (CPU {inj['cpu'] / sci['cpu']:.1f})" if sci_ok else "-",
        ])
    return markdown_table(header, rows)


def growth_table(results: dict, tools: list[str]) -> str:
    ns = [n for n in results if all("error" not in results[n].get(t, {"error": 1}) for t in ["injmesh"])]
    rows = []
    for a, b in zip(ns, ns[1:], strict=False):
        row = [f"{a:.0e} -> {b:.0e}"]
        for tool in tools:
            ra, rb = results[a].get(tool, {}), results[b].get(tool, {})
            if not all("wall" in r for r in (ra, rb)):
                row += ["-", "-"]
                continue
            ew = exponent(ra["wall"], rb["wall"], ra["N"], rb["N"])
            ec = exponent(ra["cpu"], rb["cpu"], ra["N"], rb["N"])
            row += [f"{ew:.2f} / {ec:.2f}", f"{rb['wall'] / ra['wall']:.1f} / {rb['cpu'] / ra['cpu']:.1f}"]
        rows.append(row)
    header = ["sizes"] + [c for t in tools for c in (f"{t} exponent", f"{t} time ratio")]
    return markdown_table(header, rows)


def peers_table(results: dict, tools: list[str]) -> str:
    header = ["target N", "mesher", "N", "triangles", "wall s", "CPU s", "q_min", "q_mean",
              "size err", "peak MiB", "B/node"]
    rows = []
    for n, r in results.items():
        for tool in tools:
            rec = r.get(tool)
            if rec is None:
                continue
            if "error" in rec:
                rows.append([f"{n:.0e}", tool, rec["error"]] + [""] * (len(header) - 3))
                continue
            rows.append([
                f"{n:.0e}", tool, rec["N"], rec["triangles"], f"{rec['wall']:.3f}", f"{rec['cpu']:.3f}",
                fmt(rec.get("q_min"), ".4f"), fmt(rec.get("q_mean"), ".5f"),
                fmt(rec.get("size_error"), ".4f"), f"{rec['peak_rss'] / MIB:.0f}", f"{per_node(rec):.0f}",
            ])
    return markdown_table(header, rows)


def targets(square: dict, graded: dict | None) -> list[list[str]]:
    """Rows (target, measured, pass) for the issue's targets; '-' where a size did not run."""

    def get(res: dict | None, n: float, tool: str = "injmesh") -> dict | None:
        rec = (res or {}).get(n, {}).get(tool)
        return rec if rec and "error" not in rec else None

    def check(ok: bool | None) -> str:
        return "not run" if ok is None else ("pass" if ok else "FAIL")

    def seconds(rec: dict | None) -> str:
        return "-" if rec is None else f"{rec['wall']:.2f} (CPU {rec['cpu']:.2f})"

    def ratio(a: dict | None, b: dict | None) -> tuple[float | None, str]:
        if a is None or b is None:
            return None, "-"
        return a["wall"] / b["wall"], f"{a['wall'] / b['wall']:.2f} (CPU {a['cpu'] / b['cpu']:.2f})"

    # Time targets are judged on wall seconds; CPU seconds are shown beside them because on a
    # loaded machine wall time also counts the other processes' turns.
    rows = []
    i6, i5, s6 = get(square, 1e6), get(square, 1e5), get(square, 1e6, "scipy")
    rows.append([f"square 1e6 wall <= {T_1E6:g} s", seconds(i6),
                 check(None if i6 is None else i6["wall"] <= T_1E6)])
    r, text = ratio(i6, s6)
    rows.append([f"square 1e6 <= {T_1E6_SCIPY:g} x scipy Delaunay of 1e6 points", text,
                 check(None if r is None else r <= T_1E6_SCIPY)])
    rows.append([f"square 1e5 wall <= {T_1E5:g} s", seconds(i5),
                 check(None if i5 is None else i5["wall"] <= T_1E5)])
    r, text = ratio(i6, i5)
    rows.append([f"t(1e6) / t(1e5) <= {GROWTH_1E6_1E5:g}", text,
                 check(None if r is None else r <= GROWTH_1E6_1E5)])
    # Memory and quality at every size from 1e5 up (below that the import baseline and
    # boundary layer dominate); at the largest size run when none reached 1e5.
    big = [n for n in square if n >= 1e5 and get(square, n)] or [max(square)]
    for n in big:
        rec = get(square, n)
        label = f"square {n:.0e}"
        if rec is None:
            rows.append([f"{label}: run", (square[n].get("injmesh") or {}).get("error", "-"), "FAIL"])
            continue
        rows.append([f"{label}: peak RSS <= {RSS_PER_NODE:g} B/node", f"{per_node(rec):.0f}",
                     check(per_node(rec) <= RSS_PER_NODE)])
        rows.append([f"{label}: q_min >= {Q_MIN:g}", f"{rec['q_min']:.4f}", check(rec["q_min"] >= Q_MIN)])
        rows.append([f"{label}: q_mean >= {Q_MEAN:g}", f"{rec['q_mean']:.5f}",
                     check(rec["q_mean"] >= Q_MEAN)])
        rows.append([f"{label}: size error <= {SIZE_ERROR:g}", f"{rec['size_error']:.4f}",
                     check(rec["size_error"] <= SIZE_ERROR)])
    if graded is not None:
        g6 = get(graded, 1e6)
        rows.append([f"graded disc 1e6 wall <= {T_GRADED_1E6:g} s, valid", seconds(g6),
                     check(None if g6 is None else g6["wall"] <= T_GRADED_1E6 and g6["valid"])])
    return rows


def case_tables(case: str, results: dict, peers: list[str]) -> str:
    """The injmesh, growth and peers tables of one case."""
    title = "uniform unit square" if case == "square" else f"unit disc, h graded {GRADE:g}:1"
    tools = ["injmesh", "scipy"] + [p for p in peers if case == "square" or p != "triangle"]
    out = [
        f"### injmesh, {title}\n",
        "Stage cells are wall / CPU seconds. B/node = (peak RSS - RSS after imports and the "
        "first call) / N.\n",
        injmesh_table(results) + "\n",
        f"Growth between successive sizes, wall / CPU (exponent = log t ratio / log N ratio), {title}:\n",
        growth_table(results, tools) + "\n",
    ]
    if peers:
        out += [f"### Peers, {title} (same h; one thread)\n", peers_table(results, tools) + "\n"]
    if any(ONE_THREAD in r for r in results.values()):
        out += [f"### Threads, {title}: the default against NUMBA_NUM_THREADS=1 in the same run\n",
                threads_table(results) + "\n"]
    return "\n".join(out)


def threads_table(results: dict) -> str:
    """injmesh's default threads against one thread: wall, CPU, and whether the meshes are the
    same bit for bit (a hash of points and triangles)."""
    header = ["target N", "wall s (default)", "wall s (1 thread)", "ratio", "CPU s (default)",
              "CPU s (1 thread)", "same mesh (hash)"]
    rows = []
    for n, r in results.items():
        a, b = r.get("injmesh", {}), r.get(ONE_THREAD, {})
        if "wall" not in a or "wall" not in b:
            continue
        same = a.get("digest") is not None and a.get("digest") == b.get("digest")
        rows.append([f"{n:.0e}", f"{a['wall']:.2f}", f"{b['wall']:.2f}", f"{a['wall'] / b['wall']:.2f}",
                     f"{a['cpu']:.2f}", f"{b['cpu']:.2f}", "yes" if same else "NO"])
    return markdown_table(header, rows)


def targets_table(all_results: dict) -> tuple[str, list[list[str]]]:
    rows = targets(all_results["square"], all_results.get("graded"))
    table = markdown_table(["target", "measured", "result"], rows)
    return "### Targets of issue 7\n\n" + table, rows


def reprint(path: Path) -> None:
    """Print the tables of a ``--json`` file again, without measuring."""
    report = json.loads(path.read_text())
    print(f"_{report['environment']}. Shared machine: compare ratios within this run, "
          "not seconds across runs._\n")
    all_results = {
        case: {float(n): r for n, r in res.items()} for case, res in report["cases"].items()
    }
    for case, results in all_results.items():
        peers = sorted({t for r in results.values() for t in r} - {"injmesh", "scipy", ONE_THREAD})
        print(case_tables(case, results, peers))
    print(targets_table(all_results)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1e3,1e4,1e5", help="comma-separated node counts (1e6 on request)")
    ap.add_argument("--repeat", type=int, default=1, help="runs per measurement (least wall time kept)")
    ap.add_argument("--peers", action="store_true", help="also gmsh Frontal-Delaunay and Triangle")
    ap.add_argument("--graded", action="store_true", help="also the 20:1 graded disc")
    ap.add_argument("--one-thread", action="store_true",
                    help="also injmesh with NUMBA_NUM_THREADS=1, to compare in the same run")
    ap.add_argument("--json", type=Path, help="write every measurement to this file")
    ap.add_argument("--tables-from", type=Path, metavar="JSON",
                    help="print the tables of an earlier --json file and exit")
    ap.add_argument("--timeout", type=float, default=3600.0, help="seconds allowed to one run")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    ap.add_argument("--case", default="square", choices=CASES, help=argparse.SUPPRESS)
    ap.add_argument("--n", type=float, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(MARK + json.dumps(child(args.child, args.case, args.n)), flush=True)
        return
    if args.tables_from:
        reprint(args.tables_from)
        return

    sizes = sorted(float(s) for s in args.sizes.split(","))
    peers = []
    if args.peers:
        peers = [m for m in ("gmsh", "triangle") if available(m)]
        missing = {"gmsh", "triangle"} - set(peers)
        if missing:
            print(f"peers not importable, skipped: {', '.join(sorted(missing))}\n")
    env = f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; {machine_note()}; " \
          f"Python {sys.version.split()[0]}, numpy {np.__version__}"
    print(f"_{env}. Shared machine: compare ratios within this run, not seconds across runs._\n")

    report: dict[str, Any] = {"environment": env, "cases": {}}
    all_results = {}
    for case in ["square"] + (["graded"] if args.graded else []):
        results: dict[float, dict[str, dict]] = {}
        for n in sizes:
            r = results[n] = {"injmesh": run("injmesh", case, n, args.repeat, args.timeout)}
            n_real = r["injmesh"].get("N", n)
            r["scipy"] = run("scipy", case, n_real, args.repeat, args.timeout)
            if args.one_thread:
                r[ONE_THREAD] = run(ONE_THREAD, case, n, args.repeat, args.timeout)
            for peer in peers:
                if peer == "triangle" and case != "square":
                    continue
                r[peer] = run(peer, case, n, args.repeat, args.timeout)
            print(f"<!-- {case} {n:.0e} done -->", file=sys.stderr, flush=True)
        all_results[case] = results
        print(case_tables(case, results, peers), flush=True)
        report["cases"][case] = {f"{n:.0e}": r for n, r in results.items()}

    table, rows = targets_table(all_results)
    print(table)
    report["targets"] = [dict(zip(("target", "measured", "result"), r, strict=True)) for r in rows]
    if args.json:
        tmp = args.json.with_name(args.json.name + ".tmp")
        tmp.write_text(json.dumps(report, indent=1))
        os.replace(tmp, args.json)


if __name__ == "__main__":
    main()
