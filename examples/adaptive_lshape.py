"""Adaptive meshing of Poisson's equation on the L-shape, with scikit-fem.

    -Laplace(u) = 0 on the L-shape (-1, 1)^2 minus [0, 1] x [-1, 0],
    u = r^(2/3) sin(2 theta / 3) on the boundary (the exact solution),

theta measured from the positive x axis, so that u vanishes on the two edges that meet at the
re-entrant corner (the origin), where grad u ~ r^(-1/3) is singular.  On uniform meshes the P1
error converges in H1 like N^(-1/3) only; meshes from :func:`injmesh.adapt.adapt`, driven by
the residual error estimator below, recover the optimal N^(-1/2).

Run ``python examples/adaptive_lshape.py [--out DIR] [--quick]``: it prints the table of H1
errors against N, uniform and adaptive, and writes the log-log convergence plot
``DIR/adaptive_lshape.png`` (default: the current directory).  ``benchmarks/adaptive.py`` runs
this study and an interior layer on the unit disc with the same machinery.
"""

# ruff: noqa: T201  (an example prints its table)
from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skfem import Basis, BilinearForm, ElementTriP1, Functional, LinearForm, MeshTri, condense, solve
from skfem.helpers import dot, grad

import injmesh
from injmesh import adapt

Field = Callable[[np.ndarray, np.ndarray], np.ndarray]
Gradient = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]

L_SHAPE = injmesh.Polygon([(-1, -1), (0, -1), (0, 0), (1, 0), (1, 1), (-1, 1)])


def exact(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """u = r^(2/3) sin(2 theta / 3), theta in [0, 3 pi / 2] on the L-shape."""
    theta = np.mod(np.arctan2(y, x), 2 * np.pi)
    return np.hypot(x, y) ** (2 / 3) * np.sin(2 * theta / 3)


def exact_gradient(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """grad u = (2/3) r^(-1/3) (-sin(theta / 3), cos(theta / 3))."""
    theta = np.mod(np.arctan2(y, x), 2 * np.pi)
    r = np.maximum(np.hypot(x, y), 1e-300)
    c = 2 / 3 * r ** (-1 / 3)
    return -c * np.sin(theta / 3), c * np.cos(theta / 3)


@BilinearForm
def laplace(u, v, w):
    return dot(grad(u), grad(v))


@LinearForm
def load(v, w):
    return w["f"] * v


@Functional
def gradient_error_squared(w):
    return (w["uh"].grad[0] - w["gx"]) ** 2 + (w["uh"].grad[1] - w["gy"]) ** 2


def to_skfem(mesh: injmesh.Mesh) -> MeshTri:
    return MeshTri(np.ascontiguousarray(mesh.points.T), np.ascontiguousarray(mesh.triangles.T))


def solve_poisson(
    mesh: injmesh.Mesh, dirichlet: Field, source: Field | None = None
) -> tuple[np.ndarray, Basis]:
    """P1 solution of -Laplace(u) = source with u = dirichlet on the whole boundary."""
    basis = Basis(to_skfem(mesh), ElementTriP1())
    A = laplace.assemble(basis)
    b = np.zeros(basis.N) if source is None else load.assemble(basis, f=source(*basis.global_coordinates()))
    boundary = basis.get_dofs().all()
    x = basis.zeros()
    x[boundary] = dirichlet(*mesh.points[boundary].T)
    return solve(*condense(A, b, x=x, D=boundary)), basis


def h1_error(uh: np.ndarray, basis: Basis, gradient: Gradient) -> float:
    """|u - u_h|_H1 by a quadrature of order 6 on every triangle."""
    fine = Basis(basis.mesh, ElementTriP1(), intorder=6)
    gx, gy = gradient(*fine.global_coordinates())
    return math.sqrt(gradient_error_squared.assemble(fine, uh=fine.interpolate(uh), gx=gx, gy=gy))


def residual_indicator(mesh: injmesh.Mesh, uh: np.ndarray) -> np.ndarray:
    """The residual estimator of P1 for -Laplace u = 0, per triangle (not squared).

    eta_T^2 = h_T^2 ||f + Laplace u_h||_T^2 + 1/2 sum over T's interior sides E of
    |E| ||[du_h/dn]||_E^2; for f = 0 and P1 the first term vanishes and the normal-derivative
    jump is constant on each side, so ||[du_h/dn]||_E^2 = |E| jump^2.
    """
    p, t = mesh.points, mesh.triangles
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    area = 0.5 * ((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    sides = np.stack([c - b, a - c, b - a], axis=1)  # side k is opposite vertex k
    gphi = np.stack([sides[..., 1], -sides[..., 0]], axis=-1) / (2 * area)[:, None, None]
    g = np.einsum("tk,tkd->td", uh[t], gphi)  # the constant gradient of u_h on each triangle
    # Interior sides: pairs of triangles sharing a side (sorted node pairs seen twice).
    m = len(t)
    side_nodes = np.stack([t[:, [1, 2, 0]], t[:, [2, 0, 1]]], axis=-1).reshape(-1, 2)
    key = np.sort(side_nodes, axis=1)
    key = key[:, 0].astype(np.int64) * len(p) + key[:, 1]
    order = np.argsort(key, kind="stable")
    pair = np.flatnonzero(key[order][1:] == key[order][:-1])
    s1, s2 = order[pair], order[pair + 1]
    t1, t2 = s1 // 3, s2 // 3
    e = p[side_nodes[s1, 1]] - p[side_nodes[s1, 0]]
    length = np.hypot(*e.T)
    normal = np.stack([e[:, 1], -e[:, 0]], axis=1) / length[:, None]
    jump = np.sum((g[t1] - g[t2]) * normal, axis=1)
    contrib = 0.5 * length**2 * jump**2
    eta2 = np.bincount(t1, contrib, minlength=m) + np.bincount(t2, contrib, minlength=m)
    return np.sqrt(eta2)


@dataclass
class Study:
    """A Poisson problem with a known solution, studied on uniform and adaptive meshes."""

    name: str
    title: str
    domain: injmesh.Domain
    exact: Field
    gradient: Gradient
    source: Field | None
    #: "residual": adapt to the residual estimator; "solution": to u_h's recovered Hessian.
    driver: str
    start: float
    uniform_sizes: list[float]
    targets: list[int]
    gradation: float = adapt.GRADATION
    uniform: list[tuple[int, float]] = field(default_factory=list)
    adaptive: list[tuple[int, float]] = field(default_factory=list)
    result: adapt.AdaptResult | None = None

    def solve(self, mesh: injmesh.Mesh) -> tuple[np.ndarray, np.ndarray | None]:
        uh, basis = solve_poisson(mesh, self.exact, self.source)
        self.adaptive.append((mesh.n_points, h1_error(uh, basis, self.gradient)))
        return uh, residual_indicator(mesh, uh) if self.driver == "residual" else None

    def run(self) -> Study:
        for h in self.uniform_sizes:
            mesh = injmesh.generate(self.domain, h)
            uh, basis = solve_poisson(mesh, self.exact, self.source)
            self.uniform.append((mesh.n_points, h1_error(uh, basis, self.gradient)))
        self.result = adapt.adapt(
            self.domain, self.solve, self.start, steps=len(self.targets), target_nodes=self.targets,
            gradation=self.gradation,
        )
        return self

    def uniform_error_at(self, n: float) -> float:
        """The uniform meshes' error at n nodes, interpolated (or extrapolated) in log-log."""
        ns, es = np.log(np.array(self.uniform)).T
        k = int(np.clip(np.searchsorted(ns, math.log(n)), 1, len(ns) - 1))
        slope = (es[k] - es[k - 1]) / (ns[k] - ns[k - 1])
        return math.exp(es[k - 1] + slope * (math.log(n) - ns[k - 1]))

    def last_rate(self, meshes: int = 3) -> float:
        """Least-squares rate -d log(error) / d log(N) over the last ``meshes`` adaptive meshes."""
        n, e = np.log(np.array(self.adaptive[-meshes:])).T
        return -float(np.polyfit(n, e, 1)[0])

    def table(self) -> str:
        """Markdown table: N, H1 error and rate of each mesh; ratio to uniform at equal N."""
        assert self.result is not None
        lines = [
            "| mesh | N | target | H1 error | rate | uniform / adaptive at equal N | q_min |",
            "|---|---|---|---|---|---|---|",
        ]
        for (n, e), r in zip(self.uniform, rates(self.uniform), strict=True):
            lines.append(f"| uniform | {n} | - | {e:.4e} | {r:.3f} | 1 | - |")
        for (n, e), r, step in zip(self.adaptive, rates(self.adaptive), self.result.steps, strict=True):
            target = "-" if step.target_nodes is None else f"{step.target_nodes:.0f}"
            gain = self.uniform_error_at(n) / e
            q = float(step.mesh.quality().min())
            lines.append(f"| adaptive | {n} | {target} | {e:.4e} | {r:.3f} | {gain:.2f} | {q:.3f} |")
        return "\n".join(lines)

    def plot(self, path: Path) -> Path:
        """Log-log plot of the H1 error against N, uniform and adaptive, written as PNG."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(5.5, 4.2))
        for rows, label, marker in ((self.uniform, "uniform", "s"), (self.adaptive, "adaptive", "o")):
            n, e = np.array(rows).T
            ax.loglog(n, e, marker=marker, label=label)
        n0, e0 = self.adaptive[-1]
        ref = np.array([self.adaptive[0][0], n0], dtype=float)
        ax.loglog(ref, e0 * (ref / n0) ** -0.5, "k--", lw=0.8, label="N^(-1/2)")
        nu, eu = self.uniform[-1]
        ref = np.array([self.uniform[0][0], nu], dtype=float)
        ax.loglog(ref, eu * (ref / nu) ** (-1 / 3), "k:", lw=0.8, label="N^(-1/3)")
        ax.set_xlabel("nodes N")
        ax.set_ylabel("H1 error |u - u_h|")
        ax.set_title(self.title, fontsize=10)
        ax.grid(True, which="both", lw=0.3)
        ax.legend()
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.png")
        fig.savefig(tmp, dpi=120)
        plt.close(fig)
        tmp.replace(path)  # atomic: a reader never sees half a PNG
        return path


def rates(rows: list[tuple[int, float]]) -> list[float]:
    """Rate between consecutive rows; NaN for the first."""
    return [math.nan] + [
        -math.log(e1 / e0) / math.log(n1 / n0) for (n0, e0), (n1, e1) in zip(rows[:-1], rows[1:], strict=True)
    ]


def l_shape_study(quick: bool = False) -> Study:
    """The corner singularity, adapted to the residual estimator."""
    return Study(
        name="l_shape",
        title="L-shape, u = r^(2/3) sin(2θ/3), residual estimator",
        domain=L_SHAPE,
        exact=exact,
        gradient=exact_gradient,
        source=None,
        driver="residual",
        start=0.2,
        uniform_sizes=[0.2, 0.1, 0.05] if quick else [0.2, 0.1, 0.05, 0.025, 0.0125],
        targets=[300, 600, 1200] if quick else [300, 600, 1200, 2400, 4800, 9600, 14400],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="directory of the PNG")
    parser.add_argument("--quick", action="store_true", help="small sizes only (seconds)")
    args = parser.parse_args()
    study = l_shape_study(args.quick).run()
    print(study.table())
    print(f"rate over the last 3 adaptive meshes: {study.last_rate():.3f}")
    print(f"plot: {study.plot(args.out / 'adaptive_lshape.png')}")


if __name__ == "__main__":
    main()
