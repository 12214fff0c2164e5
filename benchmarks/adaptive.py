"""Benchmark: adaptive meshing (``injmesh.adapt``), the full convergence studies.

1. **L-shape corner singularity** (``examples/adaptive_lshape.py``): u = r^(2/3) sin(2 theta/3),
   uniform meshes against meshes from ``adapt`` driven by the residual estimator.
2. **Interior layer on the unit disc**: u = atan(60 (r - 0.5)), -Laplace(u) = f, uniform against
   ``adapt`` driven by ``size_from_solution`` alone (the recovered Hessian of u_h, no estimator).
3. **Node count**: meshes made for ``target_nodes`` against the target, on the adaptive
   sequences above and on the paper's six cases (nodal h sampled from the case's own size
   function on a finer mesh, then ``NodalSize``'s estimate against the mesh of that h).
4. **Point location**: ``interpolate`` of 1e5 points on a 1e5-node mesh.

Each study prints a Markdown table (N, target, H1 error, rate, the uniform error at the same N
over the adaptive one, q_min) and the plots go to ``--out`` (default ./adaptive-results).

Usage::

    python benchmarks/adaptive.py [--out DIR] [--quick] [--skip-location]
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import injmesh
from injmesh import adapt
from injmesh.cases import CASES

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
from adaptive_lshape import Study, l_shape_study  # noqa: E402

LAYER = 60.0


def layer_exact(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    return np.arctan(LAYER * (np.hypot(x, y) - 0.5))


def layer_gradient(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = np.maximum(np.hypot(x, y), 1e-300)
    du = LAYER / (1 + (LAYER * (r - 0.5)) ** 2)
    return du * x / r, du * y / r


def layer_source(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """f = -(u'' + u'/r) for the radial u."""
    r = np.maximum(np.hypot(x, y), 1e-12)
    s = LAYER * (r - 0.5)
    du = LAYER / (1 + s * s)
    d2u = -2 * LAYER * LAYER * s / (1 + s * s) ** 2
    return -(d2u + du / r)


def disc_study(quick: bool) -> Study:
    return Study(
        name="disc_layer",
        title="unit disc, u = atan(60 (r - 0.5)), size_from_solution",
        domain=injmesh.Circle((0, 0), 1),
        exact=layer_exact,
        gradient=layer_gradient,
        source=layer_source,
        driver="solution",
        start=0.1,
        uniform_sizes=[0.1, 0.05, 0.025] if quick else [0.1, 0.05, 0.025, 0.0125],
        targets=[600, 1200] if quick else [600, 1200, 2400, 4800, 9600, 14400],
    )


def report(study: Study, out: Path) -> None:
    t = time.perf_counter()
    study.run()
    seconds = time.perf_counter() - t
    print(f"\n### {study.title}\n")
    print(study.table())
    n_last = study.adaptive[-1][0]
    print(
        f"\nrate over the last 3 adaptive meshes: {study.last_rate():.3f}; at N = {n_last} the "
        f"uniform error is {study.uniform_error_at(n_last) / study.adaptive[-1][1]:.2f}x the adaptive one"
    )
    print(f"plot: {study.plot(out / f'adaptive_{study.name}.png')}  ({seconds:.0f} s for the study)")


def node_counts(studies: list[Study]) -> None:
    print("\n### Node count against target\n")
    print("| sequence | target | N | error |")
    print("|---|---|---|---|")
    errors = []
    for study in studies:
        assert study.result is not None
        for step in study.result.steps[1:]:
            assert step.target_nodes is not None
            err = step.nodes / step.target_nodes - 1
            errors.append(err)
            print(f"| {study.name} | {step.target_nodes:.0f} | {step.nodes} | {100 * err:+.1f} % |")
    for name, case in sorted(CASES.items()):
        for scale in (1.0, 0.5, 0.25):
            def h(p: np.ndarray, s: float = scale, size=case.size) -> np.ndarray:  # type: ignore[no-untyped-def]
                return s * size(p)

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", injmesh.ConvergenceWarning)
                background = injmesh.generate(case.geometry, lambda p: 0.7 * h(p))  # noqa: B023
                nodal = adapt.NodalSize(background, h(background.points), 0.0)
                mesh = injmesh.generate(case.geometry, nodal)
            expected = adapt._Graph.of(background).expected_nodes(nodal.values)
            err = mesh.n_points / expected - 1
            errors.append(err)
            print(f"| {name} x{scale} | {expected:.0f} (estimate) | {mesh.n_points} | {100 * err:+.1f} % |")
    e = np.abs(errors)
    print(f"\nlargest |error| {100 * e.max():.1f} %, mean {100 * e.mean():.1f} % over {len(e)} meshes")


def location() -> None:
    from scipy.spatial import Delaunay

    from injmesh.triangulation import boundary_edges

    rng = np.random.default_rng(1)
    p = rng.random((100_000, 2)) ** 2  # graded towards a corner
    t = Delaunay(p).simplices
    ab, ac = p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]
    cw = ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0] < 0
    t[cw] = t[cw][:, [0, 2, 1]]
    mesh = injmesh.Mesh(p, t, boundary_edges(t), np.zeros(len(boundary_edges(t)), dtype=np.intp))
    q = rng.random((100_000, 2))
    u = 3 * p[:, 0] - p[:, 1]
    t0 = time.perf_counter()
    v = adapt.interpolate(mesh, u, q)
    seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    size = adapt.NodalSize(mesh, np.ones(len(p)), 0.0)  # the locator's set-up alone
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    size(q)
    query = time.perf_counter() - t0
    inside = Delaunay(p).find_simplex(q) >= 0
    err = np.abs(v[inside] - (3 * q[inside, 0] - q[inside, 1])).max()
    print(
        f"\n### Point location\n\ninterpolate: 1e5 points on a 1e5-node graded mesh in {seconds:.2f} s "
        f"(set-up {setup:.2f} s, query {query:.2f} s); max error of a linear field {err:.1e}; "
        f"{int((~inside).sum())} points outside"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("adaptive-results"))
    parser.add_argument("--quick", action="store_true", help="small sizes (a minute)")
    parser.add_argument("--skip-location", action="store_true")
    parser.add_argument("--gradation", type=float, default=adapt.GRADATION)
    parser.add_argument("--only", choices=["l_shape", "disc_layer"], default=None)
    args = parser.parse_args()
    studies = [l_shape_study(args.quick), disc_study(args.quick)]
    studies = [s for s in studies if args.only in (None, s.name)]
    for s in studies:
        s.gradation = args.gradation
    for study in studies:
        report(study, args.out)
    node_counts(studies)
    if not args.skip_location:
        location()
    if math.isnan(studies[0].last_rate()):
        sys.exit(1)


if __name__ == "__main__":
    main()
