"""``python -m injmesh``: the command line (see :mod:`injmesh.cli`)."""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
