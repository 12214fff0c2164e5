"""Shapes and sizes from outside Python: the inputs of the command line.

Domains come from

* GeoJSON (``.geojson``, ``.json``): Polygon, MultiPolygon, Feature, FeatureCollection and
  GeometryCollection; a polygon's further rings are holes (``Polygon(shell) - Polygon(hole)``) and
  several polygons are joined with ``|``;
* WKT (``.wkt`` files, or the text itself): ``POLYGON`` and ``MULTIPOLYGON``;
* Triangle's ``.poly`` files: vertices, segments that form closed loops, and hole points (the
  innermost loop around a hole point is a hole);
* a Python file ``path.py:name`` defining a :class:`~injmesh.Domain` or a plain ``d(p)`` (then
  also ``name_bbox``), and optionally a size as ``name_size`` or a module-level ``size``;
* the paper's named cases (:mod:`injmesh.cases`), which bring their own size.

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

import ast
import json
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .geometry import Domain, GeometryError, Polygon, as_domain
from .sizing import SizeError, SizeLike

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
    py = re.fullmatch(r"(.+\.py)(?::([A-Za-z_]\w*))?", spec)
    if py:
        return read_python(py.group(1), py.group(2) or "domain")
    path = Path(spec)
    ext = path.suffix.lower()
    if path.is_file():
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
    if path.exists():
        raise ValueError(f"{spec!r} is not a regular file")
    if ext or "/" in spec or "\\" in spec:
        raise FileNotFoundError(f"no such file: {spec!r}")
    case = get_case(spec)  # an unknown name raises, listing the cases
    return DomainInput(case.geometry, case.size, case.name)


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
    if v.ndim != 2 or v.shape[1] < 2:
        raise ValueError(f"{where}: a ring must be a list of [x, y] positions, got shape {v.shape}")
    try:
        return Polygon(v[:, :2])
    except GeometryError as exc:
        raise GeometryError(f"{where}: {exc}") from None


def _with_holes(rings: Sequence[Any], where: str) -> Domain:
    if len(rings) == 0:
        raise ValueError(f"{where}: a polygon needs at least its outer ring")
    shape: Domain = _polygon(rings[0], f"{where}, outer ring")
    for k, hole in enumerate(rings[1:], start=1):
        shape = shape - _polygon(hole, f"{where}, hole {k}")
    return shape


def _union(parts: list[Domain], what: str) -> Domain:
    if not parts:
        raise ValueError(f"{what} contains no polygon")
    out = parts[0]
    for part in parts[1:]:
        out = out | part
    return out


def read_geojson(text: str | dict[str, Any]) -> Domain:
    """A domain from GeoJSON: Polygon, MultiPolygon, Feature, FeatureCollection.

    A polygon's first ring is its outline and further rings are holes; several polygons are
    united.  Coordinates beyond x and y are ignored; the orientation of rings does not matter.

    Parameters
    ----------
    text : str or dict
        The GeoJSON text, or the parsed object.

    Returns
    -------
    Domain

    Raises
    ------
    ValueError
        Invalid JSON, an unsupported geometry type, or an invalid polygon (self-intersecting
        rings raise :class:`~injmesh.GeometryError`).

    Examples
    --------
    >>> square = {"type": "Polygon", "coordinates": [[[0, 0], [2, 0], [2, 2], [0, 2], [0, 0]]]}
    >>> float(read_geojson(square).sdf([[1, 1]])[0])
    -1.0
    """
    if isinstance(text, str):
        try:
            obj = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"invalid JSON: {exc}") from None
    else:
        obj = text
    return _union(_geojson_parts(obj, "GeoJSON"), "the GeoJSON")


def _geojson_parts(obj: Any, where: str) -> list[Domain]:
    if not isinstance(obj, dict) or "type" not in obj:
        raise ValueError(f"{where}: expected a GeoJSON object with a 'type'")
    kind = obj["type"]
    if kind == "FeatureCollection":
        out: list[Domain] = []
        for i, feature in enumerate(obj.get("features") or []):
            out += _geojson_parts(feature, f"{where} feature {i}")
        return out
    if kind == "Feature":
        if obj.get("geometry") is None:
            return []
        return _geojson_parts(obj["geometry"], where)
    if kind == "GeometryCollection":
        out = []
        for i, geometry in enumerate(obj.get("geometries") or []):
            out += _geojson_parts(geometry, f"{where} geometry {i}")
        return out
    coords = obj.get("coordinates")
    if kind == "Polygon":
        return [_with_holes(_list(coords, where), f"{where} polygon")]
    if kind == "MultiPolygon":
        return [
            _with_holes(_list(rings, where), f"{where} polygon {i}")
            for i, rings in enumerate(_list(coords, where))
        ]
    raise ValueError(
        f"{where}: geometry type {kind!r} is not an area; use Polygon or MultiPolygon"
    )


def _list(value: Any, where: str) -> list[Any]:
    if not isinstance(value, list):
        raise ValueError(f"{where}: 'coordinates' must be nested lists")
    return value


_WKT_TOKEN = re.compile(r"\s*(\(|\)|,|[^\s(),]+)")


def read_wkt(text: str) -> Domain:
    """A domain from Well-Known Text: ``POLYGON`` or ``MULTIPOLYGON``.

    Parameters
    ----------
    text : str
        For example ``"POLYGON ((0 0, 1 0, 1 1, 0 1, 0 0), (0.4 0.4, 0.6 0.4, 0.5 0.6))"``;
        ``Z``/``M`` coordinates are accepted and ignored.

    Returns
    -------
    Domain

    Raises
    ------
    ValueError
        Malformed text, another geometry type, or an invalid polygon.

    Examples
    --------
    >>> d = read_wkt("MULTIPOLYGON (((0 0, 1 0, 1 1, 0 1)), ((2 0, 3 0, 3 1, 2 1)))")
    >>> d.sdf([[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]]).round(2)
    array([-0.5,  0.5, -0.5])
    """
    tokens = _WKT_TOKEN.findall(text.strip())
    if not tokens:
        raise ValueError("empty WKT")
    kind = tokens[0].upper()
    pos = 1
    while pos < len(tokens) and tokens[pos].upper() in ("Z", "M", "ZM"):
        pos += 1
    if kind not in ("POLYGON", "MULTIPOLYGON"):
        raise ValueError(f"WKT type {tokens[0]!r} is not an area; use POLYGON or MULTIPOLYGON")
    if pos < len(tokens) and tokens[pos].upper() == "EMPTY":
        raise ValueError(f"WKT {kind} EMPTY has no area")
    tree, pos = _wkt_group(tokens, pos)
    if pos != len(tokens):
        raise ValueError(f"unexpected {' '.join(tokens[pos:pos + 3])!r} after the WKT geometry")
    if kind == "POLYGON":
        return _with_holes(tree, "WKT polygon")
    parts = [_with_holes(p, f"WKT polygon {i}") for i, p in enumerate(tree)]
    return _union(parts, "the MULTIPOLYGON")


def _wkt_group(tokens: list[str], pos: int) -> tuple[Any, int]:
    """Parse ``( item, item, ... )`` where an item is a group or a run of numbers."""
    if pos >= len(tokens) or tokens[pos] != "(":
        found = tokens[pos] if pos < len(tokens) else "the end"
        raise ValueError(f"malformed WKT: expected '(' but found {found!r}")
    pos += 1
    items: list[Any] = []
    while True:
        if pos < len(tokens) and tokens[pos] == "(":
            item, pos = _wkt_group(tokens, pos)
        else:
            numbers = []
            while pos < len(tokens) and tokens[pos] not in ("(", ")", ","):
                try:
                    numbers.append(float(tokens[pos]))
                except ValueError:
                    raise ValueError(f"malformed WKT: {tokens[pos]!r} is not a number") from None
                pos += 1
            if len(numbers) < 2:
                raise ValueError("malformed WKT: a position needs at least two numbers")
            item = numbers
        items.append(item)
        if pos >= len(tokens):
            raise ValueError("malformed WKT: missing ')'")
        if tokens[pos] == ")":
            return items, pos + 1
        if tokens[pos] != ",":
            raise ValueError(f"malformed WKT: unexpected {tokens[pos]!r}")
        pos += 1


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
    rows = _poly_rows(_read_text(path), str(path))
    it = iter(rows)

    def take(n: int, what: str) -> list[list[float]]:
        out = [next(it, None) for _ in range(n)]
        if any(r is None for r in out):
            raise ValueError(f"{str(path)!r}: the file ends inside the {what} section")
        return out  # type: ignore[return-value]

    head = take(1, "header")[0]
    n_vertices = int(head[0])
    if n_vertices == 0:
        node = path.with_suffix(".node")
        if not node.is_file():
            raise FileNotFoundError(f"{str(path)!r} has 0 vertices and there is no {str(node)!r}")
        node_rows = _poly_rows(_read_text(node), str(node))
        n_vertices = int(node_rows[0][0])
        vertex_rows = node_rows[1 : 1 + n_vertices]
    else:
        vertex_rows = take(n_vertices, "vertex")
    if len(vertex_rows) != n_vertices or any(len(r) < 3 for r in vertex_rows):
        raise ValueError(f"{str(path)!r}: expected {n_vertices} vertex lines 'index x y'")
    vertices = np.array([r[1:3] for r in vertex_rows], dtype=float)
    ids = np.array([r[0] for r in vertex_rows], dtype=np.int64)
    seg_head = take(1, "segment")[0]
    seg_rows = take(int(seg_head[0]), "segment")
    if any(len(r) < 3 for r in seg_rows):
        raise ValueError(f"{str(path)!r}: segment lines must be 'index a b'")
    seg_ids = np.array([r[1:3] for r in seg_rows], dtype=np.int64).reshape(-1, 2)
    hole_head = next(it, [0.0])
    hole_rows = take(int(hole_head[0]), "hole")
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


# --- sizes ------------------------------------------------------------------------------------

_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "sqrt": np.sqrt,
    "exp": np.exp,
    "log": np.log,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "tanh": np.tanh,
    "abs": np.abs,
    "hypot": np.hypot,
    "atan2": np.arctan2,
    "min": lambda *a: np.minimum.reduce(np.broadcast_arrays(*a)),
    "max": lambda *a: np.maximum.reduce(np.broadcast_arrays(*a)),
}
_ARITY = {"hypot": (2, 2), "atan2": (2, 2), "min": (1, 64), "max": (1, 64)}
_CONSTANTS = {"pi": math.pi, "e": math.e}
_BINARY: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: np.add,
    ast.Sub: np.subtract,
    ast.Mult: np.multiply,
    ast.Div: np.divide,
    ast.Pow: np.power,
}
_UNARY: dict[type, Callable[[Any], Any]] = {ast.UAdd: np.positive, ast.USub: np.negative}
_MAX_EXPRESSION = 2000

_REFUSED = {
    ast.Attribute: "attribute access",
    ast.Subscript: "subscripts",
    ast.Lambda: "lambda",
    ast.ListComp: "comprehensions",
    ast.SetComp: "comprehensions",
    ast.DictComp: "comprehensions",
    ast.GeneratorExp: "comprehensions",
    ast.Compare: "comparisons",
    ast.BoolOp: "boolean operators",
    ast.IfExp: "conditional expressions",
    ast.NamedExpr: "assignment",
    ast.Starred: "starred arguments",
    ast.List: "lists",
    ast.Tuple: "tuples",
    ast.Dict: "dicts",
    ast.Set: "sets",
    ast.JoinedStr: "strings",
}


class SizeExpression:
    """A size h(x, y) parsed from text; call it with an ``(n, 2)`` array of points.

    Only numbers, ``x``, ``y``, ``pi``, ``e``, ``+ - * / **``, unary ``+``/``-``, parentheses
    and the functions ``sqrt exp log sin cos tan tanh abs hypot atan2 min max`` are allowed
    (``min``/``max`` are element-wise over their arguments).  The expression is checked once
    against this whitelist and then evaluated by walking its syntax tree with NumPy: it is never
    handed to ``eval``.  Numbers are float64, so ``9**9**9`` overflows to ``inf`` (and is then
    rejected as a size) instead of hanging.

    Parameters
    ----------
    text : str
        The expression.

    Raises
    ------
    ValueError
        Invalid syntax, or a construct outside the whitelist; the message names it.

    Examples
    --------
    >>> h = SizeExpression("min(0.05 + 0.2 * sqrt(x**2 + y**2), 0.2)")
    >>> h([[0, 0], [3, 4]])
    array([0.05, 0.2 ])
    """

    def __init__(self, text: str) -> None:
        if len(text) > _MAX_EXPRESSION:
            raise ValueError(f"size expression is longer than {_MAX_EXPRESSION} characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise ValueError(f"size expression {text!r} is not valid: {exc.msg}") from None
        except (RecursionError, MemoryError):
            raise ValueError(f"size expression {text[:40]!r}... is nested too deeply") from None
        self.text = text
        self._tree = tree.body
        self.uses_xy = False
        self._check(self._tree)

    def __repr__(self) -> str:
        return f"SizeExpression({self.text!r})"

    def _check(self, node: ast.AST) -> None:
        what = _REFUSED.get(type(node))
        if what is not None:
            raise ValueError(f"size expression: {what} not allowed ({ast.unparse(node)!r})")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                kind = "strings" if isinstance(node.value, (str, bytes)) else repr(node.value)
                raise ValueError(f"size expression: {kind} not allowed ({ast.unparse(node)!r})")
        elif isinstance(node, ast.Name):
            if node.id in ("x", "y"):
                self.uses_xy = True
            elif node.id not in _CONSTANTS:
                raise ValueError(
                    f"size expression: unknown name {node.id!r}; use x, y, pi, e and the functions "
                    f"{', '.join(_FUNCTIONS)}"
                )
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in _BINARY:
                raise ValueError(
                    f"size expression: operator {type(node.op).__name__} not allowed "
                    f"({ast.unparse(node)!r}); use + - * / **"
                )
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in _UNARY:
                raise ValueError(f"size expression: {ast.unparse(node)!r} not allowed")
            self._check(node.operand)
        elif isinstance(node, ast.Call):
            fname = node.func.id if isinstance(node.func, ast.Name) else None
            if fname not in _FUNCTIONS:
                called = fname or ast.unparse(node.func)
                raise ValueError(
                    f"size expression: function {called!r} not allowed; allowed: "
                    f"{', '.join(_FUNCTIONS)}"
                )
            if node.keywords:
                raise ValueError(f"size expression: keyword arguments not allowed in {fname}()")
            lo, hi = _ARITY.get(fname, (1, 1))
            if not lo <= len(node.args) <= hi:
                want = str(lo) if lo == hi else f"{lo} or more"
                raise ValueError(
                    f"size expression: {fname}() takes {want} argument(s), got {len(node.args)}"
                )
            for arg in node.args:
                self._check(arg)
        else:
            raise ValueError(
                f"size expression: {type(node).__name__} not allowed ({ast.unparse(node)!r})"
            )

    def _eval(self, node: ast.AST, x: FloatArray, y: FloatArray) -> Any:
        if isinstance(node, ast.Constant):
            try:
                return np.float64(cast(float, node.value))
            except OverflowError:  # an int beyond float range
                return np.float64(math.inf)
        if isinstance(node, ast.Name):
            return x if node.id == "x" else y if node.id == "y" else np.float64(_CONSTANTS[node.id])
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](self._eval(node.left, x, y), self._eval(node.right, x, y))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](self._eval(node.operand, x, y))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            return _FUNCTIONS[node.func.id](*(self._eval(a, x, y) for a in node.args))
        raise ValueError(f"size expression: cannot evaluate {ast.unparse(node)!r}")  # unreachable

    def __call__(self, p: ArrayLike) -> FloatArray:
        q = np.asarray(p, dtype=float).reshape(-1, 2)
        with np.errstate(all="ignore"):
            h = self._eval(self._tree, q[:, 0], q[:, 1])
        return np.broadcast_to(np.asarray(h, dtype=float), (len(q),)).copy()


def parse_size(text: str) -> float | SizeExpression:
    """Turn the text of ``--size`` into a number or a function of ``x`` and ``y``.

    Parameters
    ----------
    text : str
        A number (``0.05``) or an expression (``0.02 + 0.1 * hypot(x, y)``); see
        :class:`SizeExpression` for what is allowed.

    Returns
    -------
    float or SizeExpression
        A float when the text does not mention ``x`` or ``y``.

    Raises
    ------
    ValueError
        Refused or invalid expression, or a constant size that is not positive and finite
        (a :class:`~injmesh.SizeError`).

    Examples
    --------
    >>> parse_size("1/20")
    0.05
    >>> parse_size("__import__('os')")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: size expression: function '__import__' not allowed; allowed: sqrt, exp, ...
    """
    text = str(text).strip()
    if not text:
        raise ValueError("size is empty")
    expr = SizeExpression(text)
    if expr.uses_xy:
        return expr
    value = float(expr(np.zeros((1, 2)))[0])
    if not (math.isfinite(value) and value > 0):
        raise SizeError(f"size must be a positive finite length, got {text} = {value:g}")
    return value


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
