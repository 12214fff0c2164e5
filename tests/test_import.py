"""``import injmesh`` stays light: numba and SciPy load when a mesh is first made, not before
(a command line's ``--help`` or a script that only reads meshes should not pay for them)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"


def test_import_loads_neither_numba_nor_scipy() -> None:
    code = ("import sys, injmesh, injmesh.cli; injmesh.cli.build_parser(); "
            "heavy = sorted({m.split('.')[0] for m in sys.modules} & {'numba', 'scipy'}); "
            "assert not heavy, heavy")
    env = dict(os.environ, PYTHONPATH=str(SRC))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)
