"""Fingerprints of generate()'s output on the cases whose meshes a speed-up must not change.

Each case's mesh is hashed (SHA-256 of ``points.tobytes()`` and ``triangles.tobytes()``, first 16
hex digits): the unit square and the 20:1 graded disc at 1e5 and 1e6 nodes (``scale.py``), the
six paper cases on both paths (composed geometry, plain sdf), the same six with the circular
inclusion of ``regions.py`` and a 1e4-node square with its two inclusions and crack, and the real
outlines of ``robustness.py``.  Run it on main, then on a branch, and compare the two JSON files::

    PYTHONPATH=src python benchmarks/mesh_hashes.py main.json
    PYTHONPATH=src python benchmarks/mesh_hashes.py branch.json --compare main.json

``--only NAME ...`` runs some cases; ``--small`` leaves out the two 1e6 meshes (minutes).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from regions import INCLUSIONS, SQUARE_CURVES, SQUARE_REGIONS  # noqa: E402
from robustness import REAL_CASES, build_real  # noqa: E402
from scale import size_function  # noqa: E402


def cases(small: bool) -> Iterator[tuple[str, Callable[[], Any]]]:
    import injmesh
    from injmesh.cases import CASES

    square = injmesh.Rectangle((0, 0), (1, 1))
    disc = injmesh.Circle((0, 0), 1.0)
    sizes = ("1e5",) if small else ("1e5", "1e6")
    for n in sizes:
        for name, dom in (("square", square), ("graded", disc)):
            size = size_function(name, float(n))
            yield f"{name}-{n}", partial(injmesh.generate, dom, size, max_nodes=10**8)
    for name, case in sorted(CASES.items()):
        yield f"{name}-geom", partial(injmesh.generate, case.geometry, case.size)
        yield f"{name}-sdf", partial(injmesh.generate, case.sdf, case.size, bbox=case.bbox,
                                     fixed_points=case.fixed_points)
    for name, case in sorted(CASES.items()):
        centre, radius = INCLUSIONS[name]
        yield f"{name}-region", partial(injmesh.generate, case.geometry, case.size,
                                        regions={"inclusion": injmesh.Circle(centre, radius)})
    yield "square-1e4-regions", partial(injmesh.generate, square, size_function("square", 1e4),
                                        regions=SQUARE_REGIONS, curves=SQUARE_CURVES)
    for name in REAL_CASES:
        def real(name: str = name) -> Any:
            _, (domain, size), *_ = build_real(name)
            return injmesh.generate(domain, size, strict=False)  # as robustness.py meshes them

        yield f"real-{name}", real


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="JSON file of case -> hash (written as cases finish)")
    parser.add_argument("--compare", help="a JSON file from another run to compare with")
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--small", action="store_true")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    hashes: dict[str, str] = {}
    for name, run in cases(args.small):
        if args.only and name not in args.only:
            continue
        t = time.perf_counter()
        mesh = run()
        digest = hashlib.sha256(mesh.points.tobytes() + b"|" + mesh.triangles.tobytes()).hexdigest()[:16]
        hashes[name] = digest
        print(f"{name:32s} {digest}  N={len(mesh.points)}  {time.perf_counter() - t:.1f} s", flush=True)
        Path(args.out).write_text(json.dumps(hashes, indent=1))
    if args.compare:
        other = json.loads(Path(args.compare).read_text())
        differ = sorted(k for k in hashes if k in other and other[k] != hashes[k])
        print("identical" if not differ else f"DIFFERENT: {', '.join(differ)}",
              f"({len(hashes)} cases, {sum(k in other for k in hashes)} compared)")
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
