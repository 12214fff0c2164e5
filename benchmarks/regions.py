"""Benchmark: regions and interior curves (issue 9) against the same meshes without them.

Three tables:

1. The paper's six domains, each meshed as it is, with one circular inclusion (a region), and
   with the same circle cut out as a hole (``domain - Circle``, no regions): N, q_min, q_mean,
   the inclusion's area error (its polygon against the circle), milliseconds and the time
   ratios to the plain domain.  The hole has the same curve and the same thin parts as the
   inclusion, with no region machinery: what the curve costs as geometry.
2. The plain domains and the inclusions again with ``feature_layers=None`` on both sides: the
   inclusions, one or two h across, then make no thin part (no lowered h, no chord search).
3. A unit square of about ``--large-nodes`` nodes (default 1e5; give several to see the
   trend), without and with the issue's constraints (two circular inclusions and a polyline
   crack): the time ratio, which issue 9 wants within 1.3x, and the stages' seconds; the
   square with the same circles as holes; and with the two regions alone.  With several
   sizes, a last table lists the ratios by size.

Seconds are the best of ``--repeat`` calls in one process (the squares' variants timed in
turn, round after round, with the median of the rounds' ratios as well); the machines these
run on are shared and noisy, so compare the ratios measured in one run, not seconds across
runs.

Usage::

    python benchmarks/regions.py [--repeat 1] [--skip-large] [--large-nodes 1e5 [1e6 ...]]
"""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

import injmesh
from injmesh import Circle, Rectangle
from injmesh.cases import CASES

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _bench import best_time, machine_note  # noqa: E402

#: One circular inclusion in each of the paper's domains (centre, radius), as in the tests.
INCLUSIONS = {
    "unit_disc": ((0.4, 0.0), 0.25),
    "square_with_hole": ((0.2, 0.2), 0.12),
    "circle_with_hole": ((0.55, 0.0), 0.2),
    "square_with_four_holes": ((0.0, 0.0), 0.25),
    "two_circles_and_square": ((-0.4, -0.3), 0.3),
    "l_shape": ((0.8, 0.2), 0.1),
}

SQUARE_REGIONS = {"a": Circle((0.3, 0.3), 0.15), "b": Circle((0.7, 0.65), 0.2)}
SQUARE_CURVES = {"crack": np.array([(0.1, 0.8), (0.3, 0.75), (0.5, 0.9)])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="timing repeats (best is reported)")
    ap.add_argument("--skip-large", action="store_true", help="skip the large unit square")
    ap.add_argument("--large-nodes", type=float, nargs="+", default=[1e5],
                    help="target nodes of the square (one table per size)")
    args = ap.parse_args()
    warnings.simplefilter("ignore", injmesh.ConvergenceWarning)
    print(f"_{machine_note()}; best of {args.repeat}._\n")
    print("| case | N | q_min | q_mean | ms | N (inclusion) | q_min | q_mean | area error | ms | ratio "
          "| N (hole) | q_min | ms | ratio |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    injmesh.generate(Rectangle((0, 0), (1, 1)), 0.2, regions={"w": Circle((0.5, 0.5), 0.2)})  # warm-up
    injmesh.generate(Rectangle((0, 0), (1, 1)) - Circle((0.5, 0.5), 0.2), 0.2)
    for name, case in CASES.items():
        t0, plain = best_time(lambda c=case: injmesh.generate(c.geometry, c.size), args.repeat)
        centre, radius = INCLUSIONS[name]
        regions = {"inclusion": Circle(centre, radius)}
        t1, mesh = best_time(lambda c=case, r=regions: injmesh.generate(c.geometry, c.size, regions=r),
                             args.repeat)
        holed = case.geometry - Circle(centre, radius)
        t2, hole = best_time(lambda c=case, d=holed: injmesh.generate(d, c.size), args.repeat)
        q0, q1, q2 = plain.quality(), mesh.quality(), hole.quality()
        err = mesh.region_areas()[1] / (np.pi * radius**2) - 1
        print(f"| {name} | {plain.n_points} | {q0.min():.3f} | {q0.mean():.3f} | {t0 * 1e3:.1f} | "
              f"{mesh.n_points} | {q1.min():.3f} | {q1.mean():.3f} | {err:+.2%} | {t1 * 1e3:.1f} | "
              f"{t1 / t0:.2f} | {hole.n_points} | {q2.min():.3f} | {t2 * 1e3:.1f} | {t2 / t0:.2f} |")
    _without_feature_size(args.repeat)

    if args.skip_large:
        return
    trend = [_large(n, args.repeat) for n in args.large_nodes]
    if len(trend) > 1:
        print("\n| N | without regions (s) | with regions and crack (s) | ratio | as holes (s) | ratio "
              "| regions alone (s) | ratio |")
        print("|---|---|---|---|---|---|---|---|")
        for n, (t0, t1, t2, t3) in zip(args.large_nodes, trend, strict=True):
            print(f"| {n:.0e} | {t0:.2f} | {t1:.2f} | {t1 / t0:.2f} | {t2:.2f} | {t2 / t0:.2f} "
                  f"| {t3:.2f} | {t3 / t0:.2f} |")


def _without_feature_size(repeat: int) -> None:
    """The first table's plain and inclusion meshes again with ``feature_layers=None`` on both
    sides: h as given, so the inclusion adds no thin part (no lowered h, no chord search).

    At the paper cases' resolution every inclusion is one or two h across, a thin part by the
    default rule (``feature_layers=2``); this separates what the regions cost from what the
    thin parts they make cost.
    """
    print("\nThe same, with `feature_layers=None` on both sides (h as given, no thin-part "
          "lowering):\n")
    print("| case | N | q_min | ms | N (inclusion) | q_min | ms | ratio |")
    print("|---|---|---|---|---|---|---|---|")
    for name, case in CASES.items():
        centre, radius = INCLUSIONS[name]
        regions = {"inclusion": Circle(centre, radius)}
        t0, plain = best_time(lambda c=case: injmesh.generate(c.geometry, c.size, feature_layers=None),
                              repeat)
        t1, mesh = best_time(lambda c=case, r=regions: injmesh.generate(c.geometry, c.size, regions=r,
                                                                        feature_layers=None), repeat)
        print(f"| {name} | {plain.n_points} | {plain.quality().min():.3f} | {t0 * 1e3:.1f} | "
              f"{mesh.n_points} | {mesh.quality().min():.3f} | {t1 * 1e3:.1f} | {t1 / t0:.2f} |")


def _large(nodes: float, repeat: int) -> tuple[float, ...]:
    """The unit square of about ``nodes`` nodes without regions, with the inclusions and the
    crack, with the inclusions as holes and with the inclusions alone: the table, and the four
    best seconds.

    The four meshes are timed in turn, ``repeat`` rounds: each round's ratios compare calls a
    few seconds apart, and their median is printed with the ratio of the best times (on a
    shared machine one slow call of the plain square moves the latter by 0.05 or more)."""
    h = float(np.sqrt(2 / (np.sqrt(3) * nodes)))
    square = Rectangle((0, 0), (1, 1))
    holes = square
    for r in SQUARE_REGIONS.values():
        holes = holes - r
    variants = (
        ("without regions", square, {}),
        ("with regions and crack", square, {"regions": SQUARE_REGIONS, "curves": SQUARE_CURVES}),
        ("the inclusions as holes (no regions)", holes, {}),
        ("with the regions alone (no crack)", square, {"regions": SQUARE_REGIONS}),
    )
    rounds: list[list[float]] = []
    for _ in range(max(1, repeat)):
        row, meshes = [], []
        for _label, dom, kw in variants:
            t, mesh = best_time(lambda d=dom, k=kw: injmesh.generate(d, h, max_nodes=10**8, **k), 1)
            row.append(t)
            meshes.append(mesh)
        rounds.append(row)
    seconds = np.array(rounds)
    times = seconds.min(axis=0)
    ratio = seconds / seconds[:, :1]
    print(f"\nUnit square, h = {h:.5f}, two circular inclusions and a crack:\n")
    print("| mesh | N | q_min | q_mean | iterations | seconds | stages |")
    print("|---|---|---|---|---|---|---|")
    for (label, _, _), t, mesh in zip(variants, times, meshes, strict=True):
        q = mesh.quality()
        stages = ", ".join(f"{k} {v:.2f}" for k, v in mesh.stats.seconds.items())
        print(f"| {label} | {mesh.n_points} | {q.min():.3f} | {q.mean():.3f} | {mesh.stats.iterations} | "
              f"{t:.2f} | {stages} |")
    print(f"\nTime with / without regions: {times[1] / times[0]:.2f}x by the best times, median "
          f"{np.median(ratio[:, 1]):.2f}x of {len(rounds)} rounds ({ratio[:, 1].min():.2f}-"
          f"{ratio[:, 1].max():.2f}x; issue 9 target: <= 1.3x); the regions alone "
          f"{times[3] / times[0]:.2f}x, median {np.median(ratio[:, 3]):.2f}x "
          f"({ratio[:, 3].min():.2f}-{ratio[:, 3].max():.2f}x)")
    # What the curves cost as geometry: the square with the same circles as holes has the same
    # curved fronts to mesh and relax, with no region machinery.
    print(f"Time with regions / the same circles as holes: {times[1] / times[2]:.2f}x")
    return tuple(float(t) for t in times)


if __name__ == "__main__":
    main()
