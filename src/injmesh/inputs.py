"""Shapes and sizes from outside Python: the inputs of the command line.

Domains come from

* GeoJSON (``.geojson``, ``.json``): Polygon, MultiPolygon, Feature, FeatureCollection and
  GeometryCollection; a polygon's further rings are holes (``Polygon(shell) - Polygon(hole)``) and
  several polygons are joined with ``|``;
* WKT (``.wkt`` files, or the text itself): ``POLYGON`` and ``MULTIPOLYGON``; GeoJSON or WKT
  text is always read as text, never looked up as a file name;
* Triangle's ``.poly`` files: vertices, segments that form closed loops, and hole points (the
  innermost loop around a hole point is a hole);
* a Python file ``path.py:name`` defining a :class:`~injmesh.Domain` or a plain ``d(p)`` (then
  also ``name_bbox``), and optionally a size as ``name_size`` or a module-level ``size``;
* the paper's named cases (:mod:`injmesh.cases`), which bring their own size.

The parsing of GeoJSON and WKT lives in :mod:`injmesh.geometry.convert` (Python callers reach it
through :func:`~injmesh.geometry.as_domain`); this module adds files, cases and sizes.

Sizes come from :func:`parse_size`, a safe expression in ``x`` and ``y`` (never ``eval``), and
:func:`graded_size`, growing away from the boundary.

Examples
--------
>>> from injmesh.inputs import parse_size, read_wkt
>>> domain = read_wkt("POLYGON ((0 0, 4 0, 4 3, 0 3), (1 1, 2 1, 2 2, 1 2))")
>>> float(domain.sdf([[0.5, 0.5]])[0])
-0.5
>>> h = parse_size("0.05 + 0.1 * hypot(x - 1, y)")
>>> h([[1.0, 0.0], [1.0, 1.0]])
array([0.05, 0.15])
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .expression import SizeExpression, parse_size, size_expression
from .geometry import Domain, GeometryError, Polygon, as_domain
from .geometry.convert import looks_like_text_geometry, read_geojson, read_wkt
from .sizing import SizeError, SizeLike

__all__ = [
    "DomainInput",
    "SizeExpression",
    "graded_size",
    "load_domain",
    "parse_size",
    "read_geojson",
    "read_poly",
    "read_python",
    "read_wkt",
    "size_expression",
]

FloatArray = NDArray[np.float64]

#: Input kinds recognised by extension.
DOMAIN_EXTENSIONS = (".geojson", ".json", ".wkt", ".poly", ".py")


@dataclass(frozen=True)
class DomainInput:
    """A domain read from the outside world, with the size it brought (if any).

    Attributes
    ----------
    domain : Domain
        The region to mesh.
    size : float or callable or None
        A size that came with the input (a named case's h, a Python file's ``size``).
    name : str
        A short description for messages and file names.
    """

    domain: Domain
    size: SizeLike | None
    name: str


# --- domains ----------------------------------------------------------------------------------


def load_domain(spec: str) -> DomainInput:
    """Read a domain from a file, a Python object, WKT text or the name of a paper case.

    Parameters
    ----------
    spec : str
        ``shape.geojson``, ``shape.json``, ``shape.wkt``, ``shape.poly``, ``file.py:name``
        (``name`` defaults to ``domain``), ``POLYGON ((...))`` text, or a case name such as
        ``unit_disc``.

    Returns
    -------
    DomainInput

    Raises
    ------
    FileNotFoundError
        A file named by ``spec`` does not exist.
    ValueError
        The file cannot be parsed, the shape is invalid (for example self-intersecting: a
        :class:`~injmesh.GeometryError`), or ``spec`` names no case.

    Examples
    --------
    >>> load_domain("unit_disc").name
    'unit_disc'
    """
    from .cases import CASES, get_case

    spec = spec.strip()
    if spec in CASES:
        case = get_case(spec)
        return DomainInput(case.geometry, case.size, case.name)
    # WKT and GeoJSON text are never file names, however long (a path longer than the file
    # system allows would otherwise fail with "File name too long").
    if looks_like_text_geometry(spec):
        if spec.startswith("{"):
            return DomainInput(read_geojson(spec), None, "geojson")
        return DomainInput(read_wkt(spec), None, "wkt")
    py = re.fullmatch(r"(.+\.py)(?::([A-Za-z_]\w*))?", spec)
    if py:
        return read_python(py.group(1), py.group(2) or "domain")
    path = Path(spec)
    ext = path.suffix.lower()
    if _is_file(path):
        if ext in (".geojson", ".json"):
            return DomainInput(read_geojson(_read_text(path)), None, path.stem)
        if ext == ".wkt":
            return DomainInput(read_wkt(_read_text(path)), None, path.stem)
        if ext == ".poly":
            return DomainInput(read_poly(path), None, path.stem)
        raise ValueError(
            f"cannot tell the shape format of {spec!r} from its extension; "
            f"supported: {', '.join(DOMAIN_EXTENSIONS)} or a case name"
        )
    if re.match(r"\s*(multi)?polygon\b", spec, re.IGNORECASE):
        return DomainInput(read_wkt(spec), None, "wkt")
    if _exists(path):
        raise ValueError(f"{spec!r} is not a regular file")
    if ext or "/" in spec or "\\" in spec:
        raise FileNotFoundError(f"no such file: {spec!r}")
    case = get_case(spec)  # an unknown name raises, listing the cases
    return DomainInput(case.geometry, case.size, case.name)


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:  # a name too long for the file system, for example: not a file
        return False


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:
        return False


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{str(path)!r} is not a UTF-8 text file: {exc.reason}") from None


def _polygon(ring: ArrayLike, where: str) -> Polygon:
    try:
        v = np.asarray(ring, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: coordinates must be numbers") from None
    try:
        return Polygon(v)
    except GeometryError as exc:
        raise GeometryError(f"{where}: {exc}") from None


def read_poly(path: str | Path) -> Domain:
    """A domain from a Triangle ``.poly`` file.

    The segments must form closed loops (every vertex on a segment has exactly two).  The
    innermost loop around each hole point is a hole; every other loop adds area.  Loops are
    combined from the largest to the smallest, so an island inside a hole is kept.  A vertex count
    of 0 reads the vertices from the ``.node`` file of the same name.

    Parameters
    ----------
    path : str or Path
        The ``.poly`` file.

    Returns
    -------
    Domain

    Raises
    ------
    ValueError
        Malformed file, segments that do not form closed loops, or an invalid loop.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> text = ("4 2 0 0\\n1 0 0\\n2 1 0\\n3 1 1\\n4 0 1\\n"     # vertices: index x y
    ...         "4 0\\n1 1 2\\n2 2 3\\n3 3 4\\n4 4 1\\n0\\n")     # segments; no holes
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     p = pathlib.Path(tmp) / "square.poly"
    ...     _ = p.write_text(text)
    ...     float(read_poly(p).sdf([[0.5, 0.5]])[0])
    -0.5
    """
    path = Path(path)
    name = repr(str(path))
    rows = _poly_rows(_read_text(path), str(path))
    cursor = 0

    def take(count: float, what: str) -> list[list[float]]:
        # Counts in headers are checked against the lines actually present before anything
        # is allocated: a header claiming 10^12 vertices must not reserve memory for them.
        nonlocal cursor
        n = _count(count, what, name)
        if n > len(rows) - cursor:
            raise ValueError(
                f"{name}: the {what} section announces {n if n < 10**15 else f'{n:.3g}'} lines "
                "but the file has only "
                f"{len(rows) - cursor} left (the file ends inside the {what} section)"
            )
        out = rows[cursor : cursor + n]
        cursor += n
        return out

    head = take(1, "header")[0]
    if _count(head[0], "vertex", name) == 0:
        node = path.with_suffix(".node")
        if not node.is_file():
            raise FileNotFoundError(f"{name} has 0 vertices and there is no {str(node)!r}")
        node_rows = _poly_rows(_read_text(node), str(node))
        n_vertices = _count(node_rows[0][0], "vertex", repr(str(node)))
        if n_vertices > len(node_rows) - 1:
            raise ValueError(
                f"{str(node)!r} announces {n_vertices} vertices but has {len(node_rows) - 1} lines"
            )
        vertex_rows = node_rows[1 : 1 + n_vertices]
    else:
        vertex_rows = take(head[0], "vertex")
    n_vertices = len(vertex_rows)
    if any(len(r) < 3 for r in vertex_rows):
        raise ValueError(f"{name}: expected {n_vertices} vertex lines 'index x y'")
    vertices = np.array([r[1:3] for r in vertex_rows], dtype=float)
    ids = np.array([r[0] for r in vertex_rows], dtype=np.int64)
    seg_head = take(1, "segment")[0]
    seg_rows = take(seg_head[0], "segment")
    if any(len(r) < 3 for r in seg_rows):
        raise ValueError(f"{name}: segment lines must be 'index a b'")
    seg_ids = np.array([r[1:3] for r in seg_rows], dtype=np.int64).reshape(-1, 2)
    hole_head = take(1, "hole")[0] if cursor < len(rows) else [0.0]
    hole_rows = take(hole_head[0], "hole")
    if any(len(r) < 3 for r in hole_rows):
        raise ValueError(f"{name}: hole lines must be 'index x y'")
    holes = np.array([r[1:3] for r in hole_rows], dtype=float).reshape(-1, 2)

    # Vertices are numbered from 0 or from 1; map the file's numbers to row indices.
    order = np.argsort(ids)
    pos = np.searchsorted(ids[order], seg_ids)
    pos = np.clip(pos, 0, len(ids) - 1)
    if len(seg_ids) == 0:
        raise ValueError(f"{str(path)!r} has no segments: they must outline the domain")
    if not np.all(ids[order][pos] == seg_ids):
        bad = seg_ids[ids[order][pos] != seg_ids][0]
        raise ValueError(f"{str(path)!r}: a segment refers to vertex {bad}, which is not defined")
    segments = order[pos]
    loops = _closed_loops(segments, str(path))
    polygons = [_polygon(vertices[loop], f"{str(path)!r} loop {k}") for k, loop in enumerate(loops)]
    return _combine_loops(polygons, holes, str(path))


def _count(value: float, what: str, name: str) -> int:
    """A count from a header field: a whole number >= 0."""
    if not (math.isfinite(value) and value >= 0 and value == int(value)):
        raise ValueError(f"{name}: the {what} count must be a whole number >= 0, got {value!r}")
    return int(value)


def _poly_rows(text: str, name: str) -> list[list[float]]:
    rows = []
    for n, line in enumerate(text.splitlines(), start=1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        try:
            rows.append([float(f) for f in fields])
        except ValueError:
            raise ValueError(f"{name!r} line {n}: {line.strip()!r} is not numbers") from None
    if not rows:
        raise ValueError(f"{name!r} is empty")
    return rows


def _closed_loops(segments: NDArray[np.intp], name: str) -> list[NDArray[np.intp]]:
    """Split segments ``(k, 2)`` into closed loops of vertex indices."""
    keys = np.unique(np.sort(segments, axis=1), axis=0)
    keys = keys[keys[:, 0] != keys[:, 1]]
    used, degree = np.unique(keys, return_counts=True)
    if np.any(degree != 2):
        v = used[degree != 2][0]
        raise ValueError(
            f"{name!r}: the segments do not form closed loops (vertex {v} is on "
            f"{degree[degree != 2][0]} segments; each needs exactly 2)"
        )
    neighbours: dict[int, list[int]] = {int(v): [] for v in used}
    for a, b in keys.tolist():
        neighbours[a].append(b)
        neighbours[b].append(a)
    loops, seen = [], set()
    for start in neighbours:  # walk each loop once: the input's size, not a meshing hot path
        if start in seen:
            continue
        loop, prev, cur = [start], -1, start
        seen.add(start)
        while True:
            a, b = neighbours[cur]
            nxt = a if a != prev else b
            if nxt == start:
                break
            loop.append(nxt)
            seen.add(nxt)
            prev, cur = cur, nxt
        loops.append(np.array(loop, dtype=np.intp))
    return loops


def _combine_loops(polygons: list[Polygon], holes: FloatArray, name: str) -> Domain:
    areas = np.array([p.area for p in polygons])
    is_hole = np.zeros(len(polygons), dtype=bool)
    for point in holes:
        inside = np.array([p.sdf(point[None, :])[0] < 0 for p in polygons])
        if inside.any():
            is_hole[np.flatnonzero(inside)[np.argmin(areas[inside])]] = True
    domain: Domain | None = None
    for k in np.argsort(-areas, kind="stable"):
        if is_hole[k]:
            if domain is None:
                raise ValueError(f"{name!r}: hole loop {k} lies in no region")
            domain = domain - polygons[k]
        else:
            domain = polygons[k] if domain is None else domain | polygons[k]
    if domain is None:
        raise ValueError(f"{name!r}: every loop is a hole; nothing is left to mesh")
    return domain


def read_python(path: str | Path, name: str = "domain") -> DomainInput:
    """Run a Python file and take the domain it defines as ``name``.

    ``name`` may be a :class:`~injmesh.Domain` or a plain ``d(p)``; a plain callable needs
    ``name_bbox = (xmin, ymin, xmax, ymax)`` (or a module-level ``bbox``) and may give
    ``name_fixed_points``.  A size is taken from ``name_size`` or a module-level ``size``.

    The file is executed with the full power of Python: only run files you trust.

    Parameters
    ----------
    path : str or Path
        The ``.py`` file.
    name : str
        The variable holding the domain.

    Returns
    -------
    DomainInput

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        The file fails to run, or does not define ``name`` as a domain.
    """
    import runpy

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no such file: {str(path)!r}")
    try:
        namespace = runpy.run_path(str(path), run_name=f"injmesh_input_{path.stem}")
    except (SystemExit, KeyboardInterrupt):
        raise
    except BaseException as exc:  # any error in the user's file becomes one clear message
        raise ValueError(f"running {str(path)!r} failed: {type(exc).__name__}: {exc}") from None
    if name not in namespace:
        raise ValueError(f"{str(path)!r} defines no {name!r}; name the domain with path.py:NAME")
    obj = namespace[name]
    if not isinstance(obj, Domain):
        if not callable(obj):
            raise ValueError(f"{str(path)!r}: {name!r} is a {type(obj).__name__}, not a domain")
        bbox = namespace.get(f"{name}_bbox", namespace.get("bbox"))
        if bbox is None:
            raise ValueError(
                f"{str(path)!r}: {name!r} is a plain function d(p); also define "
                f"{name}_bbox = (xmin, ymin, xmax, ymax)"
            )
        obj = as_domain(obj, bbox=bbox, fixed_points=namespace.get(f"{name}_fixed_points"))
    size = namespace.get(f"{name}_size", namespace.get("size"))
    if size is not None and not (callable(size) or isinstance(size, (int, float, str))):
        raise ValueError(f"{str(path)!r}: size must be a number, a callable or an expression")
    if isinstance(size, str):
        size = parse_size(size)
    return DomainInput(obj, size, f"{path.stem}.{name}" if name != "domain" else path.stem)


def graded_size(
    domain: Domain,
    size_min: float,
    growth: float = 0.2,
    size_max: float | None = None,
) -> Callable[[FloatArray], FloatArray]:
    """A size that is ``size_min`` on the boundary and grows linearly into the interior.

    ``h(p) = min(size_max, size_min + growth * max(0, -d(p)))``, where ``d`` is the domain's
    signed distance (negative inside), so ``-d`` is the distance to the nearest boundary: the
    boundary, holes included, is resolved with ``size_min``, and edges lengthen by ``growth``
    per unit of distance inward.  ``growth`` is a slope (dimensionless, like the 0.2 in the
    paper's ``h = 0.2 r + 0.05``); neighbouring edges then differ by a factor of about
    ``1 + growth``, so values up to about 0.5 give smooth gradings.  For CSG domains and plain
    callables ``d`` is a bound on the distance rather than the exact distance, which still gives
    a graded size.

    Parameters
    ----------
    domain : Domain
        The domain.
    size_min : float
        Size on the boundary (> 0).
    growth : float
        Increase of h per unit distance from the boundary (>= 0).
    size_max : float, optional
        Cap on h (>= size_min); none by default.

    Returns
    -------
    callable
        ``h(p) -> (n,)``.

    Raises
    ------
    SizeError
        A parameter outside its range.

    Examples
    --------
    >>> from injmesh import Circle
    >>> h = graded_size(Circle((0, 0), 1), 0.05, growth=0.2, size_max=0.2)
    >>> h([[1, 0], [0.5, 0], [0, 0]])
    array([0.05, 0.15, 0.2 ])
    """
    if not (math.isfinite(size_min) and size_min > 0):
        raise SizeError(f"size_min must be a positive finite length, got {size_min!r}")
    if not (math.isfinite(growth) and growth >= 0):
        raise SizeError(f"growth must be a non-negative finite number, got {growth!r}")
    cap = math.inf if size_max is None else float(size_max)
    if not cap >= size_min:
        raise SizeError(f"size_max ({size_max!r}) must be at least size_min ({size_min!r})")

    def h(p: ArrayLike) -> FloatArray:
        q = np.asarray(p, dtype=float).reshape(-1, 2)
        depth = np.maximum(0.0, -domain.sdf(q))
        return np.minimum(cap, size_min + growth * depth)

    return h
