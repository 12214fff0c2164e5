"""Batch meshing: thousands of meshes from a file of specs, on a Dask cluster.

A batch is a list of *specs*, one mesh each, usually a JSON Lines file (one JSON object a line)::

    {"name": "disc", "domain": "unit_disc"}
    {"name": "ring-coarse", "domain": "POLYGON ((0 0, 4 0, 4 3, 0 3))", "size": 0.2, "format": "vtu"}
    {"name": "wing", "domain": "shapes/wing.geojson", "size": "0.01 + 0.05*hypot(x, y)"}
    {"name": "plate-7", "domain": {"type": "Polygon", "coordinates": [[[0, 0], [2, 0], [2, 1]]]},
     "nodes": 300}
    {"name": "plates-000012", "domain": {"family": "plates", "seed": 12}}

=========  ================================================================================
field      meaning
=========  ================================================================================
name       required; the output is ``OUT/<name>.<format>``.  Letters, digits, ``_ . -``, not
           starting with ``.``; unique (ignoring case).
domain     required; a paper case (``unit_disc``, ...), a GeoJSON geometry (an object with a
           ``"type"``), WKT text (``POLYGON ((...))``), a path to a ``.geojson``/``.json``/
           ``.wkt``/``.poly`` file (relative to the specs file), or a random shape
           ``{"family": "plates", "seed": 12}`` (optionally with ``"params"``; see
           :func:`random_specs` and :mod:`injmesh.shapes`).
size       the target edge length h: a number, an expression in ``x`` and ``y`` (see
           :func:`injmesh.inputs.parse_size`), a case name (that case's h) or a path to a text
           file holding a number or an expression.  Optional for cases and families, which
           bring their own size.
nodes      instead of ``size``: about this many nodes, with a uniform h from the domain's
           area (see :func:`size_for_nodes`).  Give ``size`` or ``nodes``, not both.
format     ``npz`` (default; needs only NumPy), ``msh``, ``vtu``, ``xdmf`` or ``mesh``.
=========  ================================================================================

Every spec is validated before any work starts; the error names the line and the field.  Files
a spec refers to are read by this process and sent to the workers with the task, so the workers
of a remote cluster need no shared file system; the mesh files come back the same way and are
written here, atomically, by this process only.

:func:`mesh_many` writes ``OUT/<name>.<format>`` and ``OUT/summary.csv`` (:data:`SUMMARY_COLUMNS`).
A spec that fails or runs out of time becomes a row of the summary and never stops the batch.
Each row carries a hash of its spec (the spec's canonical JSON, the contents of the files it
names and the injmesh version); a rerun skips every spec whose hash is unchanged and whose
output exists, so an interrupted batch resumes where it stopped.  Every mesh depends on its spec
alone, so the files are bit-identical whatever the number of workers.

Statuses: ``ok`` (mesh written; ``message`` holds any warning), ``failed`` (the spec is at
fault: unreadable file, invalid shape, bad size; skipped on rerun while the spec is unchanged),
``timeout`` (ran out of its time limit) and ``error`` (anything else: a worker lost, out of
memory, a bug); ``timeout`` and ``error`` are tried again by a rerun.

Dask (``pip install 'injmesh[batch]'``) is imported only when a batch runs on a cluster.

Examples
--------
>>> import tempfile, pathlib
>>> specs = [{"name": "disc", "domain": "unit_disc", "size": 0.3},
...          {"name": "square", "domain": "POLYGON ((0 0, 1 0, 1 1, 0 1))", "nodes": 40}]
>>> with tempfile.TemporaryDirectory() as out:
...     summary = mesh_many(specs, out, workers=0)          # workers=0: here, without Dask
...     sorted(p.name for p in pathlib.Path(out).iterdir())
['disc.npz', 'square.npz', 'summary.csv']
>>> summary.counts
{'ok': 2}
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import importlib.util
import inspect
import io
import json
import logging
import math
import os
import re
import secrets
import signal
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .geometry import Domain
from .progress import Callback, Progress
from .shapes import FAMILIES as SHAPE_FAMILIES

logger = logging.getLogger(__name__)

MISSING_DASK = "batch meshing on a cluster needs Dask: pip install 'injmesh[batch]'"

#: Output format of a spec -> file extension.
FORMATS: dict[str, str] = {"npz": ".npz", "msh": ".msh", "vtu": ".vtu", "xdmf": ".xdmf", "mesh": ".mesh"}
DEFAULT_FORMAT = "npz"
SPEC_FIELDS = ("name", "domain", "size", "nodes", "format")
#: Columns of ``summary.csv``, in order.
SUMMARY_COLUMNS = (
    "name", "status", "N", "triangles", "q_min", "q_mean", "size_error", "seconds", "worker",
    "message", "spec_hash", "file", "sha256",
)
STATUSES = ("ok", "failed", "timeout", "error")
SUMMARY_NAME = "summary.csv"
#: Seconds between rewrites of ``summary.csv`` while a batch runs (it is also written at the end).
SUMMARY_INTERVAL = 5.0
MAX_NODES_TARGET = 5_000_000

_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,127}")
_WKT = re.compile(r"\s*(multi)?polygon\b", re.IGNORECASE)
_DOMAIN_FILES = {".geojson": "geojson", ".json": "geojson", ".wkt": "wkt", ".poly": "poly"}


# --- specs ------------------------------------------------------------------------------------


class SpecError(ValueError):
    """One or more specs are invalid; ``errors`` lists ``(where, field, message)``.

    The message's first line names the first problem; further lines list every problem.
    """

    def __init__(self, errors: Sequence[tuple[str, str | None, str]]) -> None:
        self.errors = list(errors)
        lines = [_where(w, f, m) for w, f, m in self.errors]
        head = lines[0]
        if len(lines) > 1:
            head += f" (and {len(lines) - 1} more invalid spec{'s' if len(lines) > 2 else ''})"
        super().__init__("\n".join([head] + [f"  {line}" for line in lines] if len(lines) > 1 else [head]))


def _where(where: str, fieldname: str | None, message: str) -> str:
    return f"{where}, field {fieldname!r}: {message}" if fieldname else f"{where}: {message}"


class _Invalid(Exception):
    def __init__(self, fieldname: str | None, message: str) -> None:
        super().__init__(message)
        self.field = fieldname
        self.message = message


@dataclass(frozen=True)
class MeshSpec:
    """One mesh of a batch, validated (see the module notes for the fields).

    Attributes
    ----------
    name : str
        Output file stem.
    domain : str or dict
        Case name, WKT text, file path, GeoJSON geometry or family member, as given.
    size : float or str or None
        Number, expression, case name or path to a file with an expression.
    nodes : int or None
        Target node count (instead of ``size``).
    format : str
        One of :data:`FORMATS`.
    base_dir : Path or None
        Directory that relative paths are taken from (the specs file's); not part of the spec.
    """

    name: str
    domain: str | dict[str, Any]
    size: float | str | None = None
    nodes: int | None = None
    format: str = DEFAULT_FORMAT
    base_dir: Path | None = field(default=None, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """The spec as a JSON-ready dict (fields left at their default are omitted)."""
        out: dict[str, Any] = {"name": self.name, "domain": self.domain}
        if self.size is not None:
            out["size"] = self.size
        if self.nodes is not None:
            out["nodes"] = self.nodes
        out["format"] = self.format
        return out

    def to_json(self) -> str:
        """One line of a specs file."""
        return json.dumps(self.to_dict(), separators=(", ", ": "), allow_nan=False)

    @property
    def filename(self) -> str:
        """``<name>.<format>``."""
        return self.name + FORMATS[self.format]


def parse_spec(obj: Any, *, base_dir: str | os.PathLike[str] | None = None,
               default_format: str = DEFAULT_FORMAT, where: str = "spec") -> MeshSpec:
    """Validate one spec (a dict as read from JSON) and return it as a :class:`MeshSpec`.

    Parameters
    ----------
    obj : dict or MeshSpec
        The spec.
    base_dir : path, optional
        Where relative file paths in the spec are found (default: the working directory).
    default_format : str
        Format of a spec that names none.
    where : str
        How to name the spec in messages (``"specs.jsonl line 4"``).

    Raises
    ------
    SpecError
        The spec is invalid; the message names ``where`` and the field.

    Examples
    --------
    >>> parse_spec({"name": "a", "domain": "unit_disc", "nodes": 500}).nodes
    500
    >>> parse_spec({"name": "a", "domain": "unit_disc", "sizes": 0.1}, where="line 3")
    ... # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    injmesh.batch.SpecError: line 3, field 'sizes': unknown field; the fields are name, domain, ...
    """
    try:
        return _parse(obj, base_dir, default_format)
    except _Invalid as exc:
        raise SpecError([(where, exc.field, exc.message)]) from None


def _parse(obj: Any, base_dir: str | os.PathLike[str] | None, default_format: str) -> MeshSpec:
    from .cases import CASES

    base = Path(base_dir) if base_dir is not None else None
    if isinstance(obj, MeshSpec):  # validate again: a MeshSpec can be built by hand
        base = obj.base_dir if base is None else base
        obj = obj.to_dict()
    if not isinstance(obj, Mapping):
        raise _Invalid(None, f"a spec must be a JSON object, got {type(obj).__name__}")
    for key in obj:
        if key not in SPEC_FIELDS:
            raise _Invalid(str(key), f"unknown field; the fields are {', '.join(SPEC_FIELDS)}")

    name = obj.get("name")
    if not isinstance(name, str):
        raise _Invalid("name", "missing" if name is None else f"must be a string, got {name!r}")
    if not _NAME.fullmatch(name):
        raise _Invalid("name", f"{name!r} is not a safe file name (letters, digits, '_', '.', '-'; "
                       "not starting with '.'; at most 128 characters)")

    domain = obj.get("domain")
    if domain is None:
        raise _Invalid("domain", "missing")
    if isinstance(domain, Mapping):
        try:  # a plain copy, as it will be hashed and sent to the workers
            domain = json.loads(json.dumps(domain, allow_nan=False))
        except (TypeError, ValueError) as exc:
            raise _Invalid("domain", f"must be plain JSON (no NaN or infinity): {exc}") from None
        _check_domain_object(domain)
    elif isinstance(domain, str):
        _check_domain_text(domain.strip(), CASES)
        domain = domain.strip()
    else:
        raise _Invalid("domain", f"must be a string or a GeoJSON object, got {type(domain).__name__}")

    size = obj.get("size")
    nodes = obj.get("nodes")
    if size is not None and nodes is not None:
        raise _Invalid("nodes", "give 'size' or 'nodes', not both")
    if size is not None:
        size = _check_size(size, CASES)
    if nodes is not None:
        if isinstance(nodes, bool) or not isinstance(nodes, int) and not (
            isinstance(nodes, float) and nodes.is_integer()
        ):
            raise _Invalid("nodes", f"must be a whole number, got {nodes!r}")
        nodes = int(nodes)
        if not 3 <= nodes <= MAX_NODES_TARGET:
            raise _Invalid("nodes", f"must be between 3 and {MAX_NODES_TARGET}, got {nodes}")
    if size is None and nodes is None and not _brings_size(domain, CASES):
        raise _Invalid("size", "missing: give 'size' or 'nodes' (only paper cases and random "
                       "families bring their own size)")

    fmt = obj.get("format", default_format)
    if not isinstance(fmt, str) or fmt.lower().lstrip(".") not in FORMATS:
        raise _Invalid("format", f"{fmt!r} is not one of {', '.join(FORMATS)}")
    return MeshSpec(name, domain, size, nodes, fmt.lower().lstrip("."), base)


def _check_domain_object(domain: dict[str, Any]) -> None:
    if "family" in domain:
        family = domain["family"]
        if family not in FAMILIES:
            raise _Invalid("domain", f"unknown family {family!r}; choose one of {', '.join(FAMILIES)}")
        extra = set(domain) - {"family", "seed", "params"}
        if extra:
            raise _Invalid("domain", f"a family member has 'family', 'seed' and 'params', not "
                           f"{', '.join(map(repr, sorted(extra)))}")
        seed = domain.get("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise _Invalid("domain", f"a family member's 'seed' must be a whole number >= 0, got {seed!r}")
        if "params" in domain:
            _check_params(family, domain["params"])
        return
    kind = domain.get("type")
    kinds = ("Polygon", "MultiPolygon", "Feature", "FeatureCollection", "GeometryCollection")
    if kind not in kinds:
        raise _Invalid("domain", f"a GeoJSON object needs a 'type' of {', '.join(kinds)}, got {kind!r}")


def _check_domain_text(text: str, cases: Mapping[str, Any]) -> None:
    if not text:
        raise _Invalid("domain", "is empty")
    if text in cases or _WKT.match(text):
        return
    ext = Path(text).suffix.lower()
    if ext in _DOMAIN_FILES:
        return
    if ext or "/" in text or "\\" in text:
        raise _Invalid("domain", f"cannot tell the shape format of {text!r} from its extension; "
                       f"use {', '.join(_DOMAIN_FILES)}")
    raise _Invalid("domain", f"{text!r} is no paper case ({', '.join(sorted(cases))}), WKT text "
                   "or file path")


def _check_size(size: Any, cases: Mapping[str, Any]) -> float | str:
    from .inputs import parse_size

    if isinstance(size, bool) or not isinstance(size, (int, float, str)):
        raise _Invalid("size", f"must be a number or a string, got {type(size).__name__}")
    if not isinstance(size, str):
        if not (math.isfinite(size) and size > 0):
            raise _Invalid("size", f"must be a positive finite length, got {size!r}")
        return float(size)
    text = size.strip()
    if text in cases:
        return text
    try:
        parse_size(text)
    except ValueError as exc:
        if _looks_like_path(text):
            return text
        raise _Invalid("size", str(exc).splitlines()[0]) from None
    return text


def _looks_like_path(text: str) -> bool:
    return "/" in text or "\\" in text or bool(re.search(r"\.[A-Za-z]\w*$", text))


def _brings_size(domain: str | dict[str, Any], cases: Mapping[str, Any]) -> bool:
    if isinstance(domain, dict):
        return "family" in domain
    return domain in cases


def load_specs(path: str | os.PathLike[str], *, default_format: str = DEFAULT_FORMAT) -> list[MeshSpec]:
    """Read and validate a JSON Lines file of specs.

    Blank lines are skipped.  Every line is checked, and all problems are reported together.

    Parameters
    ----------
    path : path
        The ``.jsonl`` file; relative paths inside it are taken from its directory.
    default_format : str
        Format of specs that name none.

    Returns
    -------
    list of MeshSpec

    Raises
    ------
    FileNotFoundError
        No such file.
    SpecError
        A line is not JSON or not a valid spec, or two specs share a name; the message names
        the line and the field.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError([(str(path), None, f"not a UTF-8 text file: {exc.reason}")]) from None
    items: list[tuple[str, Any]] = []
    errors: list[tuple[str, str | None, str]] = []
    for n, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        where = f"{path.name} line {n}"
        try:
            items.append((where, json.loads(line)))
        except json.JSONDecodeError as exc:
            errors.append((where, None, f"not valid JSON: {exc.msg} at column {exc.colno}"))
    specs, more = _validate(items, path.parent, default_format)
    errors += more
    if errors:
        raise SpecError(sorted(errors, key=lambda e: _line_number(e[0])))
    if not specs:
        raise SpecError([(str(path), None, "contains no specs")])
    return specs


def _line_number(where: str) -> int:
    m = re.search(r"(\d+)$", where)
    return int(m.group(1)) if m else 0


def _validate(items: Iterable[tuple[str, Any]], base_dir: Path | None,
              default_format: str) -> tuple[list[MeshSpec], list[tuple[str, str | None, str]]]:
    specs: list[MeshSpec] = []
    errors: list[tuple[str, str | None, str]] = []
    seen: dict[str, str] = {}
    for where, obj in items:
        try:
            spec = _parse(obj, base_dir, default_format)
        except _Invalid as exc:
            errors.append((where, exc.field, exc.message))
            continue
        key = spec.name.lower()
        if key in seen:
            errors.append((where, "name", f"{spec.name!r} is already used by {seen[key]} "
                           "(names must differ ignoring case)"))
            continue
        seen[key] = where
        specs.append(spec)
    return specs, errors


def as_specs(specs: str | os.PathLike[str] | Iterable[MeshSpec | Mapping[str, Any]], *,
             default_format: str = DEFAULT_FORMAT) -> list[MeshSpec]:
    """Specs from a JSON Lines path or from an iterable of dicts and :class:`MeshSpec`, validated.

    Raises
    ------
    SpecError
        Any invalid spec (all are listed; ``spec 3`` is the third item) or a repeated name.
    """
    if isinstance(specs, (str, os.PathLike)):
        return load_specs(specs, default_format=default_format)
    if isinstance(specs, Mapping):
        raise TypeError("specs must be a path or an iterable of specs, not a single dict")
    items = [(f"spec {i}", s) for i, s in enumerate(specs, start=1)]
    out, errors = _validate(items, None, default_format)
    if errors:
        raise SpecError(errors)
    return out


def write_specs(specs: Iterable[MeshSpec], path: str | os.PathLike[str]) -> None:
    """Write specs as a JSON Lines file, atomically."""
    from .io import atomic_path

    text = "".join(s.to_json() + "\n" for s in specs)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


# --- sizes from node counts -------------------------------------------------------------------

#: Sampling grid (per side of the bounding box) for the area and perimeter of a domain.
_AREA_GRID = 128


def domain_measure(domain: Domain) -> tuple[float, float]:
    """Area and perimeter of a domain, estimated on a grid over its bounding box.

    The area counts grid cells whose centre is inside; the perimeter counts the cell sides the
    boundary crosses, times ``pi / 4`` (a staircase overestimates a curve of random direction
    by ``4 / pi``).  Deterministic; within a few per cent for shapes a few cells across.

    Examples
    --------
    >>> from injmesh import Circle
    >>> area, perimeter = domain_measure(Circle((0, 0), 1))
    >>> round(area, 1), round(perimeter, 1)
    (3.1, 6.3)
    """
    x0, y0, x1, y1 = domain.bbox
    # Pad the box by a cell so the boundary never sits on the grid's edge.
    dx, dy = (x1 - x0) / (_AREA_GRID - 2), (y1 - y0) / (_AREA_GRID - 2)
    xs = x0 - dx + dx * (np.arange(_AREA_GRID) + 0.5)
    ys = y0 - dy + dy * (np.arange(_AREA_GRID) + 0.5)
    gx, gy = np.meshgrid(xs, ys)
    inside = (domain.sdf(np.column_stack([gx.ravel(), gy.ravel()])) < 0).reshape(gx.shape)
    area = float(inside.sum() * dx * dy)
    crossings_x = np.count_nonzero(inside[:, 1:] != inside[:, :-1])  # vertical cell sides
    crossings_y = np.count_nonzero(inside[1:, :] != inside[:-1, :])  # horizontal cell sides
    perimeter = float(crossings_x * dy + crossings_y * dx) * math.pi / 4
    return area, perimeter


def size_for_nodes(domain: Domain, nodes: int) -> float:
    """A uniform edge length h giving about ``nodes`` nodes on ``domain``.

    In a mesh of equilateral triangles of side h every interior node accounts for an area of
    ``sqrt(3)/2 h^2`` (two triangles of ``sqrt(3)/4 h^2``) and a boundary node for half that
    (Euler's formula: ``T = 2N - N_b - 2``), so with ``N_b = P / h`` boundary nodes on a
    boundary of length P, ``N = 2A / (sqrt(3) h^2) + P / (2h)``; solved for h.  Area and
    perimeter come from :func:`domain_measure`.  This is where ``generate(target_nodes=...)``
    belongs once the pipeline has it.

    Parameters
    ----------
    domain : Domain
        The region.
    nodes : int
        Target node count (>= 3).

    Returns
    -------
    float

    Examples
    --------
    >>> import injmesh
    >>> disc = injmesh.Circle((0, 0), 1)
    >>> n = injmesh.generate(disc, size_for_nodes(disc, 400)).n_points
    >>> bool(360 <= n <= 440)
    True
    """
    from .geometry import GeometryError

    area, perimeter = domain_measure(domain)
    if not area > 0:
        raise GeometryError("the domain has no area on a 128 x 128 grid over its box: too thin "
                            "to size by a node count; give 'size' instead")
    a, b = 2.0 * area / math.sqrt(3.0), perimeter / 2.0
    inverse_h = (-b + math.sqrt(b * b + 4.0 * a * nodes)) / (2.0 * a)
    return 1.0 / inverse_h


# --- random families --------------------------------------------------------------------------


#: Random families of :func:`random_specs`: batch name -> family of :mod:`injmesh.shapes`.  The
#: three of the issue (``polygons``: random star or random-walk polygons with 1-3 holes, the
#: shapes family ``holes``; ``plates``: perforated plates; ``airfoils``: NACA 4-digit profiles
#: in a box, the shapes family ``airfoil``), then the other families of :mod:`injmesh.shapes`
#: under their own names.
FAMILIES: dict[str, str] = {
    "polygons": "holes", "plates": "plates", "airfoils": "airfoil",
    **{name: name for name in SHAPE_FAMILIES if name not in ("holes", "plates", "airfoil")},
}


def family_member(family: str, seed: int, params: Mapping[str, Any] | None = None) -> tuple[Domain, float]:
    """The domain and suggested size of the shape of a random family with this seed.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`.
    seed : int
        The shape's seed (see :mod:`injmesh.shapes`: the same seed, the same shape).
    params : dict, optional
        Keyword parameters of the family's generator (``{"n_holes": 3}``).

    Examples
    --------
    >>> domain, h = family_member("plates", 3)
    >>> float(domain.sdf([[-1.0, 0.5]])[0]), h
    (1.0, 0.05)
    """
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r}; choose one of {', '.join(FAMILIES)}")
    shape = SHAPE_FAMILIES[FAMILIES[family]](int(seed), **dict(params or {}))
    return shape.domain(), float(shape.size)


def _check_params(family: str, params: Any) -> None:
    if not isinstance(params, Mapping):
        raise _Invalid("domain", f"a family member's 'params' must be an object, got {params!r}")
    accepted = [
        name for name, p in inspect.signature(SHAPE_FAMILIES[FAMILIES[family]]).parameters.items()
        if p.kind is inspect.Parameter.KEYWORD_ONLY
    ]
    for key in params:
        if key not in accepted:
            raise _Invalid("domain", f"family {family!r} has no parameter {key!r}; it takes "
                           f"{', '.join(accepted) or 'none'}")


def random_specs(family: str, count: int, seed: int = 0, *, size: float | str | None = None,
                 nodes: int | None = None, format: str = DEFAULT_FORMAT,
                 params: Mapping[str, Any] | None = None) -> list[MeshSpec]:
    """``count`` specs of random shapes of one family: a ready-made training set.

    Spec ``k`` meshes the family's shape with seed ``seed + k`` (as
    :func:`injmesh.shapes.family` numbers them), named ``<family>-<seed + k>``; so a larger
    count extends a smaller one and a rerun into the same directory only meshes the new ones.
    The shapes come from :mod:`injmesh.shapes` (each verified simple, holes inside) with the
    family's suggested size unless ``size`` or ``nodes`` is given.

    Parameters
    ----------
    family : str
        One of :data:`FAMILIES`: ``polygons``, ``plates``, ``airfoils``, or a family of
        :mod:`injmesh.shapes` by its own name.
    count : int
        Number of specs (>= 0).
    seed : int
        Seed of the first shape (>= 0).
    size, nodes : optional
        A size (number or expression) or a target node count for every shape.
    format : str
        Output format of every spec.
    params : dict, optional
        Keyword parameters of the family's generator, JSON values (``{"n_holes": 3}``).

    Returns
    -------
    list of MeshSpec

    Raises
    ------
    SpecError
        A bad family, count, seed, size, node count, format or parameter.

    Examples
    --------
    >>> specs = random_specs("plates", 3, seed=7, nodes=300)
    >>> [s.name for s in specs]
    ['plates-000007', 'plates-000008', 'plates-000009']
    >>> specs[2].to_json()
    '{"name": "plates-000009", "domain": {"family": "plates", "seed": 9}, "nodes": 300, "format": "npz"}'
    """
    for label, value in (("count", count), ("seed", seed)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise SpecError([("random_specs", label, f"must be a whole number >= 0, got {value!r}")])
    width = max(6, len(str(int(seed) + int(count) - 1)))
    out = []
    for k in range(int(count)):
        member: dict[str, Any] = {"family": family, "seed": int(seed) + k}
        if params:
            member["params"] = dict(params)
        obj: dict[str, Any] = {"name": f"{family}-{int(seed) + k:0{width}d}", "domain": member,
                               "format": format}
        if size is not None:
            obj["size"] = size
        if nodes is not None:
            obj["nodes"] = nodes
        out.append(parse_spec(obj, where="random_specs"))  # the first error stops: all are alike
    return out


# --- tasks: prepared here, run on a worker ----------------------------------------------------


def _version() -> str:
    from . import __version__

    return __version__


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


class _InputError(Exception):
    """A file named by a spec cannot be read (reported as a failed row)."""


def _resolve(path_text: str, base_dir: Path | None) -> Path:
    path = Path(path_text).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    return path


def _read_input(path: Path, what: str) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise _InputError(f"{what}: no such file: {str(path)!r}") from None
    except IsADirectoryError:
        raise _InputError(f"{what}: {str(path)!r} is a directory") from None
    except UnicodeDecodeError as exc:
        raise _InputError(f"{what}: {str(path)!r} is not a UTF-8 text file: {exc.reason}") from None
    except OSError as exc:
        raise _InputError(f"{what}: cannot read {str(path)!r}: {exc.strerror or exc}") from None


def _prepare(spec: MeshSpec, timeout: float | None) -> tuple[dict[str, Any], str | None]:
    """The task for a worker (plain data) and an input error message, if a file is unreadable.

    File contents travel with the task and enter the spec's hash, so an edited input file is
    meshed again.
    """
    from .cases import CASES

    task: dict[str, Any] = {"name": spec.name, "format": spec.format, "timeout": timeout,
                            "nodes": spec.nodes}
    digests: dict[str, str] = {}
    problem: str | None = None
    domain = spec.domain
    if isinstance(domain, dict):
        task["domain"] = ("family", domain) if "family" in domain else ("geojson", domain)
    elif domain in CASES:
        task["domain"] = ("case", domain)
    elif _WKT.match(domain):
        task["domain"] = ("wkt", domain)
    else:
        path = _resolve(domain, spec.base_dir)
        kind = _DOMAIN_FILES[path.suffix.lower()]
        try:
            text = _read_input(path, "domain")
            extra = None
            node = path.with_suffix(".node")
            if kind == "poly" and node.is_file():
                extra = _read_input(node, "domain")
            digests["domain"] = _sha256((text + "\0" + (extra or "")).encode())
            task["domain"] = ("file", kind, text, extra, str(path))
        except _InputError as exc:
            problem = str(exc)
            digests["domain"] = "unreadable: " + problem
            task["domain"] = None

    size = spec.size
    if size is None:
        task["size"] = ("own", None)
    elif isinstance(size, float):
        task["size"] = ("number", size)
    elif size in CASES:
        task["size"] = ("case", size)
    else:
        from .inputs import parse_size

        try:
            parse_size(size)
            task["size"] = ("expression", size)
        except ValueError:  # validation let it through as a path
            try:
                text = _read_input(_resolve(size, spec.base_dir), "size").strip()
                digests["size"] = _sha256(text.encode())
                task["size"] = ("expression", text)
            except _InputError as exc:
                problem = problem or str(exc)
                digests["size"] = "unreadable: " + str(exc)
    task["hash"] = _sha256(_canonical(
        {"spec": spec.to_dict(), "inputs": digests, "injmesh": _version()}
    ).encode())
    return task, problem


class BatchTimeout(Exception):
    """A spec ran past its time limit (raised inside ``generate`` by the progress callback)."""


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return "local"


def _build_domain(task: dict[str, Any]) -> tuple[Domain, Any]:
    from .inputs import load_domain, read_geojson, read_poly, read_wkt

    kind, *rest = task["domain"]
    if kind == "case":
        source = load_domain(rest[0])
        return source.domain, source.size
    if kind == "family":
        member = rest[0]
        return family_member(member["family"], member["seed"], member.get("params"))
    if kind == "geojson":
        return read_geojson(rest[0]), None
    if kind == "wkt":
        return read_wkt(rest[0]), None
    fmt, text, extra, original = rest
    if fmt == "poly":
        # read_poly reads files (a .poly may need its .node): recreate them in a scratch directory.
        with tempfile.TemporaryDirectory(prefix="injmesh-") as tmp:
            path = Path(tmp) / Path(original).name
            path.write_text(text, encoding="utf-8")
            if extra is not None:
                path.with_suffix(".node").write_text(extra, encoding="utf-8")
            try:
                return read_poly(path), None
            except (ValueError, OSError) as exc:  # its messages name the file: name the user's
                message = str(exc).replace(str(path.with_suffix("")), original[: -len(".poly")])
                raise (type(exc) if isinstance(exc, ValueError) else ValueError)(message) from None
    try:
        return (read_geojson(text) if fmt == "geojson" else read_wkt(text)), None
    except ValueError as exc:  # name the file: the reader only saw its text
        raise type(exc)(f"{original!r}: {exc}") from None


def _build_size(task: dict[str, Any], domain: Domain, own: Any) -> Any:
    from .cases import CASES
    from .inputs import parse_size

    if task["nodes"] is not None:
        return size_for_nodes(domain, task["nodes"])
    kind, value = task["size"]
    if kind == "number":
        return value
    if kind == "case":
        return CASES[value].size
    if kind == "expression":
        return parse_size(value)
    if own is None:
        raise ValueError("the domain brings no size: give 'size' or 'nodes'")
    return own


def _encode(mesh: Any, name: str, fmt: str) -> bytes:
    from .io import write

    # meshio writes to paths only: write into a private scratch directory and read back.
    with tempfile.TemporaryDirectory(prefix="injmesh-") as tmp:
        path = Path(tmp) / (name + FORMATS[fmt])
        write(mesh, path)
        return path.read_bytes()


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    text = lines[0] if lines else type(exc).__name__
    return text if len(text) <= 500 else text[:497] + "..."


def run_task(task: dict[str, Any], threads: int | None = None) -> dict[str, Any]:
    """Mesh one prepared spec; never raises for a bad spec.  Runs on a Dask worker.

    ``threads`` caps the threads of the mesher's kernels (1 on a cluster's workers, which
    already run one task per core; the mesh is the same for any value).  Returns a dict with
    ``status``, ``message``, ``seconds``, ``worker`` and, when ``ok``, the mesh figures and
    the file's bytes (``data``).
    """
    from .kernels.threads import limit
    from .pipeline import generate

    start = time.perf_counter()
    result: dict[str, Any] = {"name": task["name"], "hash": task["hash"], "worker": _worker_name()}
    timeout = task.get("timeout")
    deadline = None if timeout is None else start + timeout

    def check(event: Progress) -> None:
        if deadline is not None and time.perf_counter() > deadline:
            raise BatchTimeout(f"stopped after {timeout:g} s, in {event.stage} step {event.step}")

    try:
        # Warnings of this spec only: a worker runs one task at a time (threads_per_worker=1).
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            domain, own = _build_domain(task)
            size = _build_size(task, domain, own)
            with limit(threads) if threads else contextlib.nullcontext():
                mesh = generate(domain, size, callback=check)
            data = _encode(mesh, task["name"], task["format"])
        q = mesh.quality()
        report = mesh.size_report()
        notes = list(dict.fromkeys(f"warning: {_first_line(w.message)}" for w in caught))  # type: ignore[arg-type]
        result.update(status="ok", message="; ".join(notes), N=mesh.n_points,
                      triangles=mesh.n_triangles, q_min=float(q.min()), q_mean=float(q.mean()),
                      size_error=float(report.relative), data=data)
    except BatchTimeout as exc:
        result.update(status="timeout", message=str(exc))
    except (ValueError, TypeError) as exc:  # the spec's fault: invalid shape, size, ...
        result.update(status="failed", message=_first_line(exc))
    except Exception as exc:  # anything else is worth another try on a rerun
        stop = _interrupt_in(exc)
        if stop is not None:
            raise stop from None
        result.update(status="error", message=f"{type(exc).__name__}: {_first_line(exc)}")
    result["seconds"] = time.perf_counter() - start
    return result


def _interrupt_in(exc: BaseException) -> KeyboardInterrupt | None:
    """The Ctrl-C or SIGTERM hidden in ``exc``'s chain, if any.

    A signal that arrives while a compiled (numba) kernel runs raises its KeyboardInterrupt as
    the kernel returns, and the dispatcher reports that as ``SystemError: ... returned a result
    with an exception set``, caused by the interrupt: it is the user's stop, not a spec's error.
    """
    seen: set[int] = set()
    cur: BaseException | None = exc
    while cur is not None and id(cur) not in seen:
        if isinstance(cur, KeyboardInterrupt):
            return cur
        seen.add(id(cur))
        cur = cur.__cause__ or cur.__context__
    return None


# --- summary ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class BatchRow:
    """One row of ``summary.csv``: what became of one spec.

    ``N``, ``triangles``, ``q_min``, ``q_mean`` (Eq. 5.1), ``size_error`` (mean ``|lc/h - 1|``),
    ``file`` and ``sha256`` (of the file) are set for ``ok`` rows only.  ``reused`` is True when
    a rerun found the spec up to date and did no work for it (not a column of the file).
    """

    name: str
    status: str
    N: int | None = None
    triangles: int | None = None
    q_min: float | None = None
    q_mean: float | None = None
    size_error: float | None = None
    seconds: float | None = None
    worker: str = ""
    message: str = ""
    spec_hash: str = ""
    file: str = ""
    sha256: str = ""
    reused: bool = field(default=False, compare=False)

    def to_csv(self) -> dict[str, str]:
        out = {}
        for key in SUMMARY_COLUMNS:
            value = getattr(self, key)
            if value is None:
                out[key] = ""
            elif key == "seconds":
                out[key] = f"{value:.3f}"
            else:
                out[key] = repr(value) if isinstance(value, float) else str(value)
        return out

    @classmethod
    def from_csv(cls, row: Mapping[str, str]) -> BatchRow:
        def number(key: str, kind: type) -> Any:
            text = (row.get(key) or "").strip()
            return kind(text) if text else None

        return cls(
            name=row["name"], status=row.get("status", ""), N=number("N", int),
            triangles=number("triangles", int), q_min=number("q_min", float),
            q_mean=number("q_mean", float), size_error=number("size_error", float),
            seconds=number("seconds", float), worker=row.get("worker") or "",
            message=row.get("message") or "", spec_hash=row.get("spec_hash") or "",
            file=row.get("file") or "", sha256=row.get("sha256") or "", reused=True,
        )


@dataclass(frozen=True)
class BatchSummary:
    """What a batch did: one :class:`BatchRow` per finished spec, in the order of the specs.

    Attributes
    ----------
    rows : tuple of BatchRow
        Rows of the finished specs (an interrupted batch lacks the unfinished ones).
    total : int
        Number of specs in the batch.
    path : Path
        The ``summary.csv`` written.
    seconds : float
        Wall-clock time of the batch.
    interrupted : bool
        The batch was stopped (Ctrl-C, SIGTERM) before every spec finished.
    """

    rows: tuple[BatchRow, ...]
    total: int
    path: Path
    seconds: float = 0.0
    interrupted: bool = False

    @property
    def counts(self) -> dict[str, int]:
        """Rows per status, e.g. ``{"ok": 38, "failed": 2}``."""
        out: dict[str, int] = {}
        for row in self.rows:
            out[row.status] = out.get(row.status, 0) + 1
        return {s: out[s] for s in STATUSES if s in out}

    @property
    def computed(self) -> list[str]:
        """Names of the specs worked on in this run (not reused from an earlier one)."""
        return [r.name for r in self.rows if not r.reused]

    @property
    def reused(self) -> list[str]:
        """Names of the specs found up to date and skipped."""
        return [r.name for r in self.rows if r.reused]

    @property
    def ok(self) -> bool:
        """Every spec finished with a mesh."""
        return not self.interrupted and len(self.rows) == self.total and all(
            r.status == "ok" for r in self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self) -> Iterator[BatchRow]:
        return iter(self.rows)

    def __getitem__(self, name: str) -> BatchRow:
        for row in self.rows:
            if row.name == name:
                return row
        raise KeyError(name)

    def as_dicts(self) -> list[dict[str, Any]]:
        """Rows as dicts (``pandas.DataFrame(summary.as_dicts())`` makes a table)."""
        return [asdict(r) for r in self.rows]

    def __repr__(self) -> str:
        counts = ", ".join(f"{n} {s}" for s, n in self.counts.items()) or "nothing"
        tail = ", interrupted" if self.interrupted else ""
        return (f"<BatchSummary: {len(self.rows)} of {self.total} specs: {counts}; "
                f"{len(self.reused)} reused{tail}>")


class BatchInterrupted(KeyboardInterrupt):
    """A batch stopped by Ctrl-C, SIGTERM or SIGHUP; ``summary`` holds what finished (also on
    disk) and ``signal_name`` the signal (``"SIGINT"`` for Ctrl-C)."""

    def __init__(self, summary: BatchSummary, signal_name: str = "SIGINT") -> None:
        super().__init__(f"batch interrupted by {signal_name}: {len(summary.rows)} of "
                         f"{summary.total} specs finished")
        self.summary = summary
        self.signal_name = signal_name


def read_summary(path: str | os.PathLike[str]) -> dict[str, BatchRow]:
    """The rows of a ``summary.csv`` by name; empty if it is missing or unreadable."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames is None or "name" not in reader.fieldnames:
                return {}
            return {row["name"]: BatchRow.from_csv(row) for row in reader if row.get("name")}
    except FileNotFoundError:
        return {}
    except (OSError, ValueError, csv.Error, UnicodeDecodeError) as exc:
        logger.warning("ignoring unreadable %s (%s): every spec is meshed again", path, exc)
        return {}


def _write_summary(path: Path, rows: Iterable[BatchRow]) -> None:
    from .io import atomic_path

    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=SUMMARY_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(row.to_csv())
    with atomic_path(path) as tmp:
        tmp.write_text(buffer.getvalue(), encoding="utf-8")


# --- running a batch --------------------------------------------------------------------------


def _up_to_date(row: BatchRow | None, task_hash: str, output: Path, retry_failed: bool) -> bool:
    if row is None or row.spec_hash != task_hash:
        return False
    if row.status == "ok":
        return output.is_file()
    return row.status == "failed" and not retry_failed


def default_workers() -> int:
    """Worker processes of the embedded cluster: one per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


#: Signals that stop a batch like Ctrl-C does.
_TERMINATING = tuple(getattr(signal, n) for n in ("SIGTERM", "SIGHUP") if hasattr(signal, n))


class _StopSignals:
    """Ctrl-C, SIGTERM and SIGHUP stop a batch cleanly, as a KeyboardInterrupt in the main thread.

    For the duration of the batch (main thread only) SIGTERM and SIGHUP are caught: an earlier
    Python handler (the command line's) is called, and unless it raised, a KeyboardInterrupt
    is; an ignored signal stays ignored.  While a cluster starts, every one of them is held back
    and delivered once it exists, so that it can always be closed: interrupting
    ``LocalCluster()`` half-way leaves processes behind.
    """

    def __init__(self) -> None:
        self.received: str | None = None
        self._holding = False
        self._pending: int | None = None
        self._previous: dict[int, Any] = {}
        self._main = threading.current_thread() is threading.main_thread()

    def __enter__(self) -> _StopSignals:
        if self._main:
            for sig in _TERMINATING:
                if signal.getsignal(sig) is signal.SIG_IGN:
                    continue
                with contextlib.suppress(OSError, ValueError):
                    self._previous[sig] = signal.signal(sig, self._on_signal)
        return self

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self._previous.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(sig, handler)

    def _on_signal(self, signum: int, frame: Any) -> None:
        self.received = signal.Signals(signum).name
        if self._holding:
            self._pending = signum
            return
        self._deliver(signum, frame)

    def _deliver(self, signum: int, frame: Any) -> None:
        previous = self._previous.get(signum)
        if callable(previous):
            previous(signum, frame)
        raise KeyboardInterrupt(signal.Signals(signum).name)

    @contextlib.contextmanager
    def hold(self) -> Iterator[None]:
        """Hold Ctrl-C, SIGTERM and SIGHUP back during the block (SIGINT by blocking it)."""
        if not self._main:
            yield
            return
        can_block = hasattr(signal, "pthread_sigmask")
        previous: Any = None
        if can_block:
            previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        else:  # no signal masks (Windows): ignore Ctrl-C while the cluster starts
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        self._holding = True
        try:
            yield
        finally:
            self._holding = False
            if can_block:
                signal.pthread_sigmask(signal.SIG_SETMASK, previous)  # a held Ctrl-C lands here
            else:
                signal.signal(signal.SIGINT, previous)
            if self._pending is not None:
                pending, self._pending = self._pending, None
                self._deliver(pending, None)


# Run by each worker process of our LocalCluster before it starts.  Ctrl-C in a terminal reaches
# the whole process group; only the client should react to it (by stopping the batch cleanly),
# not the workers (by dying with a traceback).
_WORKER_PRELOAD = """
import signal, threading
def dask_setup(worker):
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
"""


@contextlib.contextmanager
def _cluster(client: Any, workers: int | None, signals: _StopSignals) -> Iterator[Any]:
    """The Dask client to use: the caller's, one connected to an address, or a new LocalCluster."""
    try:
        import distributed
    except ImportError as exc:
        raise ImportError(MISSING_DASK) from exc
    if isinstance(client, distributed.Client):
        yield client
        return
    if isinstance(client, str):
        with distributed.Client(client, timeout="30s") as connected:
            yield connected
        return
    if client is not None:
        raise TypeError(f"client must be a dask.distributed.Client or a scheduler address, not "
                        f"{type(client).__name__}")
    n = default_workers() if workers is None else workers
    cluster = None
    try:
        with signals.hold():
            # dashboard_address=None still binds port 8787 (and warns when it is taken); ":0"
            # takes any free port.
            cluster = distributed.LocalCluster(
                n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                silence_logs=logging.CRITICAL, preload=[_WORKER_PRELOAD],
            )
        with distributed.Client(cluster) as own:
            yield own
    finally:
        if cluster is not None:
            cluster.close()


def mesh_many(
    specs: str | os.PathLike[str] | Iterable[MeshSpec | Mapping[str, Any]],
    out_dir: str | os.PathLike[str],
    *,
    client: Any = None,
    workers: int | None = None,
    timeout: float | None = None,
    retry_failed: bool = False,
    callback: Callback | None = None,
) -> BatchSummary:
    """Mesh every spec into ``out_dir``, on a Dask cluster; skip what is already done.

    Parameters
    ----------
    specs : path or iterable
        A JSON Lines file of specs, or dicts / :class:`MeshSpec` (see the module notes).  All are
        validated before any work starts.
    out_dir : path
        Output directory (created if needed): ``<name>.<format>`` per spec and ``summary.csv``.
    client : dask.distributed.Client or str, optional
        Run on this client's cluster, or on the scheduler at this address
        (``"tcp://host:8786"``); the cluster is left running.  By default a
        ``LocalCluster`` of ``workers`` processes (one thread each) is started and closed.
    workers : int, optional
        Worker processes of the embedded cluster (default: one per core).  ``0`` meshes in this
        process, one spec after another, without Dask.
    timeout : float, optional
        Seconds each spec may take on its worker; a spec past it is recorded as ``timeout``.
        It is checked at every boundary sweep, injection layer and smoothing iteration.
    retry_failed : bool
        Also mesh again the specs that failed before with the same spec.
    callback : callable, optional
        Called with a :class:`~injmesh.Progress` (stage ``"batch"``, step = specs finished,
        total = specs in the batch, ``info`` with ``name`` and ``status``) after each spec.

    Returns
    -------
    BatchSummary
        The rows of ``summary.csv``; the batch's meshes, failures and reused specs.

    Raises
    ------
    SpecError
        An invalid spec (nothing is meshed).
    BatchInterrupted
        Ctrl-C or SIGTERM: unfinished specs are cancelled, the summary of what finished is
        written, and the exception (a ``KeyboardInterrupt``) carries it.
    ImportError
        Dask is needed and missing, or meshio for a format other than ``npz``.
    """
    start = time.perf_counter()
    todo_specs = as_specs(specs)
    if timeout is not None and not (
        isinstance(timeout, (int, float)) and math.isfinite(timeout) and timeout > 0
    ):
        raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise ValueError(f"workers must be a whole number >= 0, got {workers!r}")
    if client is not None and workers is not None:
        raise ValueError("give either client (an existing cluster) or workers (a new one), not both")
    if any(s.format != "npz" for s in todo_specs) and importlib.util.find_spec("meshio") is None:
        from .io import MISSING_MESHIO

        raise ImportError(MISSING_MESHIO)  # now, not once per spec
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / SUMMARY_NAME

    previous = read_summary(summary_path)
    rows: dict[str, BatchRow] = {}
    tasks: list[dict[str, Any]] = []
    for spec in todo_specs:
        task, problem = _prepare(spec, timeout)
        old = previous.get(spec.name)
        if _up_to_date(old, task["hash"], out / spec.filename, retry_failed):
            assert old is not None
            rows[spec.name] = old
        elif problem is not None:
            rows[spec.name] = BatchRow(spec.name, "failed", message=problem, spec_hash=task["hash"],
                                       seconds=0.0, worker="client")
        else:
            tasks.append(task)
    order = {s.name: i for i, s in enumerate(todo_specs)}
    total = len(todo_specs)
    logger.info("batch of %d specs: %d up to date, %d to mesh", total, len(rows), len(tasks))

    def ordered() -> list[BatchRow]:
        return sorted(rows.values(), key=lambda r: order[r.name])

    done = len(rows)
    last_write = time.monotonic()

    def finish(result: dict[str, Any]) -> None:
        nonlocal done, last_write
        name = result["name"]
        fmt = task_by_name[name]["format"]
        data = result.pop("data", None)
        file, digest = "", ""
        if result["status"] == "ok" and data is not None:
            from .io import atomic_path

            file = name + FORMATS[fmt]
            with atomic_path(out / file) as tmp:
                tmp.write_bytes(data)
            digest = _sha256(data)
        rows[name] = BatchRow(
            name=name, status=result["status"], N=result.get("N"), triangles=result.get("triangles"),
            q_min=result.get("q_min"), q_mean=result.get("q_mean"),
            size_error=result.get("size_error"), seconds=result.get("seconds"),
            worker=result.get("worker", ""), message=result.get("message", ""),
            spec_hash=result["hash"], file=file, sha256=digest,
        )
        done += 1
        logger.debug("%s: %s %s", name, result["status"], result.get("message", ""))
        if callback is not None:
            callback(Progress("batch", done, total, {"name": name, "status": result["status"]}))
        if time.monotonic() - last_write > SUMMARY_INTERVAL:
            _write_summary(summary_path, ordered())
            last_write = time.monotonic()

    task_by_name = {t["name"]: t for t in tasks}
    if callback is not None and done:
        callback(Progress("batch", done, total, {"name": "", "status": "reused"}))
    interrupted: str | None = None
    with _StopSignals() as signals:
        try:
            if tasks and workers == 0:
                for task in tasks:
                    finish(run_task(task))
            elif tasks:
                with _cluster(client, workers, signals) as dask_client:
                    _run_on_dask(dask_client, tasks, finish)
        except KeyboardInterrupt:
            interrupted = signals.received or "SIGINT"
        finally:
            _write_summary(summary_path, ordered())
    summary = BatchSummary(tuple(ordered()), total, summary_path, time.perf_counter() - start,
                           interrupted is not None)
    logger.info("%r in %.1f s", summary, summary.seconds)
    if interrupted is not None:
        raise BatchInterrupted(summary, interrupted)
    return summary


def _run_on_dask(client: Any, tasks: list[dict[str, Any]], finish: Callable[[dict[str, Any]], None]) -> None:
    from distributed import as_completed

    run = secrets.token_hex(4)  # keys unique to this run, readable on the Dask dashboard
    futures = client.map(run_task, tasks, threads=1, key=[f"injmesh-{t['name']}-{run}" for t in tasks])
    by_key = {f.key: t for f, t in zip(futures, tasks, strict=True)}
    pending = set(futures)
    finished = as_completed(futures)
    futures.clear()  # results are released one by one below, as soon as they are written
    try:
        for future in finished:
            pending.discard(future)
            task = by_key[future.key]
            try:
                result = future.result()
            except Exception as exc:  # the worker died (KilledWorker), the task was lost, ...
                result = {"name": task["name"], "hash": task["hash"], "status": "error",
                          "message": f"{type(exc).__name__}: {_first_line(exc)}", "worker": ""}
            future.release()
            finish(result)
    finally:
        if pending:
            client.cancel(list(pending), force=True)
