"""Domains from what users already have: shapely geometries, GeoJSON, WKT and vertex lists.

:func:`to_domain` is what :func:`~injmesh.geometry.as_domain` calls for anything that is not a
:class:`Domain` or a plain callable ``d(p)``.  It accepts

* any object with a ``__geo_interface__`` (shapely's Polygon and MultiPolygon, GeoPandas
  geometries, ...): shapely stays optional, it is never imported here;
* a GeoJSON mapping (Polygon, MultiPolygon, Feature, FeatureCollection, GeometryCollection),
  with coordinates as lists, tuples or arrays, and GeoJSON text;
* WKT text (``POLYGON``, ``MULTIPOLYGON``);
* an ``(n, 2)`` array or a list of ``(x, y)`` vertices: a simple polygon.

A polygon's first ring is its outline and further rings are holes; several polygons are united
with ``|``.  Every parser's work and memory are bounded by the size of its input: counts are
never taken on trust and nesting is limited, so a malicious or corrupt input fails with a
:class:`ValueError` naming the problem, never with unbounded allocation or a RecursionError.

Examples
--------
>>> from injmesh.geometry.convert import to_domain
>>> square = {"type": "Polygon", "coordinates": (((0, 0), (2, 0), (2, 2), (0, 2), (0, 0)),)}
>>> float(to_domain(square).sdf([[1, 1]])[0])
-1.0
>>> ring = to_domain("POLYGON ((0 0, 4 0, 4 4, 0 4), (1 1, 3 1, 3 3, 1 3))")
>>> ring.sdf([[2.0, 2.0], [0.5, 2.0]]).round(2)
array([ 1. , -0.5])
>>> float(to_domain([(0, 0), (1, 0), (0, 1)]).sdf([[0.25, 0.25]])[0])
-0.25
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .base import Domain, GeometryError
from .primitives import Polygon

__all__ = ["looks_like_text_geometry", "polygon_with_holes", "read_geojson", "read_wkt", "to_domain"]

#: GeoJSON objects nest Feature/GeometryCollection at most this deep; deeper input is refused
#: (well before Python's recursion limit).
MAX_NESTING = 32

_WKT_START = re.compile(r"\s*(multi)?polygon\s*(z|m|zm)?\s*(\(|empty\b)", re.IGNORECASE)


def looks_like_text_geometry(text: str) -> bool:
    """Whether ``text`` is WKT (``POLYGON (...``, ``MULTIPOLYGON ...``) or GeoJSON (``{...``).

    Such text is never a file name, whatever its length.

    Examples
    --------
    >>> looks_like_text_geometry("POLYGON ((0 0, 1 0, 0 1))"), looks_like_text_geometry("a.wkt")
    (True, False)
    """
    return bool(_WKT_START.match(text)) or text.lstrip().startswith("{")


def polygon_with_holes(
    shell: ArrayLike, holes: Sequence[ArrayLike] = (), *, where: str = "polygon"
) -> Domain:
    """The polygon ``shell`` with the polygons ``holes`` removed.

    The one place where a polygon with holes is built from rings, so that it can become
    ``Polygon(shell, holes=...)`` in one edit.  An exactly repeated closing vertex is dropped.

    Parameters
    ----------
    shell : (k, 2) array_like
        The outline; coordinates beyond x and y are ignored.
    holes : sequence of (k, 2) array_like
        Rings inside the outline.
    where : str
        How to name this polygon in error messages.

    Raises
    ------
    GeometryError
        A ring is not a list of positions, has too few vertices or crosses itself; the message
        names the ring.

    Examples
    --------
    >>> d = polygon_with_holes([(0, 0), (4, 0), (4, 4), (0, 4)], [[(1, 1), (3, 1), (3, 3), (1, 3)]])
    >>> d.sdf([[2, 2], [0.5, 2]]).round(2)
    array([ 1. , -0.5])
    """
    shape: Domain = _ring(shell, f"{where}, outer ring")
    for k, hole in enumerate(holes, start=1):
        shape = shape - _ring(hole, f"{where}, hole {k}")
    return shape


def _ring(ring: ArrayLike, where: str) -> Polygon:
    try:
        v = np.asarray(ring, dtype=float)
    except (TypeError, ValueError):
        raise GeometryError(f"{where}: coordinates must be numbers") from None
    if v.ndim != 2 or v.shape[1] < 2:
        raise GeometryError(f"{where}: a ring must be a list of [x, y] positions, got shape {v.shape}")
    v = v[:, :2]
    if len(v) > 1 and np.array_equal(v[0], v[-1]):
        v = v[:-1]  # GeoJSON and WKT close their rings; vertex lists usually do not
    try:
        return Polygon(v)
    except GeometryError as exc:
        raise GeometryError(f"{where}: {exc}") from None


def _union(parts: list[Domain], what: str) -> Domain:
    if not parts:
        raise GeometryError(f"{what} contains no polygon")
    out = parts[0]
    for part in parts[1:]:
        out = out | part
    return out


def to_domain(obj: Any) -> Domain:
    """Convert a geometry in one of the forms listed in the module notes to a :class:`Domain`.

    Parameters
    ----------
    obj : object
        A ``__geo_interface__`` object, a GeoJSON mapping or text, WKT text, or ``(n, 2)``
        vertices.

    Returns
    -------
    Domain

    Raises
    ------
    TypeError
        ``obj`` is none of these forms.
    ValueError
        The content is malformed or not an area (a :class:`GeometryError` for invalid rings).
    """
    if isinstance(obj, Domain):
        return obj
    if isinstance(obj, str):
        if obj.lstrip().startswith("{"):
            return read_geojson(obj)
        if _WKT_START.match(obj):
            return read_wkt(obj)
        raise GeometryError(
            f"a string domain must be WKT (POLYGON or MULTIPOLYGON) or GeoJSON text, "
            f"got {obj[:40]!r}; to read a file use injmesh.inputs.load_domain"
        )
    interface = getattr(obj, "__geo_interface__", None)
    if interface is not None:
        if not isinstance(interface, Mapping):
            raise TypeError(f"{type(obj).__name__}.__geo_interface__ is not a mapping")
        return read_geojson(interface)
    if isinstance(obj, Mapping):
        return read_geojson(obj)
    if isinstance(obj, (np.ndarray, list, tuple)):
        return _vertices(obj)
    raise TypeError(
        "domain must be a Domain or a callable d(p), or a shapely/__geo_interface__ geometry, a "
        f"GeoJSON dict, WKT text or (n, 2) vertices; got {type(obj).__name__}"
    )


def _vertices(obj: Any) -> Domain:
    try:
        v = np.asarray(obj, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(
            "a sequence given as a domain must be (n, 2) vertices (numbers); for holes use a "
            "GeoJSON dict or injmesh.Polygon"
        ) from None
    if v.ndim != 2 or v.shape[1] != 2:
        raise GeometryError(f"vertices given as a domain must have shape (n, 2), got {v.shape}")
    return polygon_with_holes(v, where="vertex list")


# --- GeoJSON ------------------------------------------------------------------------------------


def read_geojson(text: str | Mapping[str, Any]) -> Domain:
    """A domain from GeoJSON: Polygon, MultiPolygon, Feature, FeatureCollection.

    A polygon's first ring is its outline and further rings are holes; several polygons are
    united.  Coordinates may be lists, tuples or arrays (``shapely.geometry.mapping`` gives
    tuples); values beyond x and y are ignored; the orientation of rings does not matter.

    Parameters
    ----------
    text : str or mapping
        The GeoJSON text, or the parsed object.

    Returns
    -------
    Domain

    Raises
    ------
    ValueError
        Invalid JSON, an unsupported geometry type, nesting deeper than :data:`MAX_NESTING`, or
        an invalid polygon (self-intersecting rings raise :class:`GeometryError`).

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
        except RecursionError:
            raise ValueError("invalid JSON: nested too deeply") from None
    else:
        obj = text
    return _union(_geojson_parts(obj, "GeoJSON", 0), "the GeoJSON")


def _geojson_parts(obj: Any, where: str, depth: int) -> list[Domain]:
    if depth > MAX_NESTING:
        raise ValueError(f"{where}: features and collections nested more than {MAX_NESTING} deep")
    if not isinstance(obj, Mapping) or "type" not in obj:
        raise ValueError(f"{where}: expected a GeoJSON object with a 'type'")
    kind = obj["type"]
    if kind == "FeatureCollection":
        out: list[Domain] = []
        for i, feature in enumerate(_sequence(obj.get("features") or [], where, "features")):
            out += _geojson_parts(feature, f"{where} feature {i}", depth + 1)
        return out
    if kind == "Feature":
        if obj.get("geometry") is None:
            return []
        return _geojson_parts(obj["geometry"], where, depth + 1)
    if kind == "GeometryCollection":
        out = []
        for i, geometry in enumerate(_sequence(obj.get("geometries") or [], where, "geometries")):
            out += _geojson_parts(geometry, f"{where} geometry {i}", depth + 1)
        return out
    coords = obj.get("coordinates")
    if kind == "Polygon":
        return [_geojson_polygon(coords, f"{where} polygon")]
    if kind == "MultiPolygon":
        return [
            _geojson_polygon(rings, f"{where} polygon {i}")
            for i, rings in enumerate(_sequence(coords, where, "coordinates"))
        ]
    raise ValueError(f"{where}: geometry type {kind!r} is not an area; use Polygon or MultiPolygon")


def _geojson_polygon(rings: Any, where: str) -> Domain:
    rings = _sequence(rings, where, "coordinates")
    if len(rings) == 0:
        raise GeometryError(f"{where}: a polygon needs at least its outer ring")
    return polygon_with_holes(rings[0], rings[1:], where=where)


def _sequence(value: Any, where: str, key: str) -> Sequence[Any]:
    if isinstance(value, np.ndarray):
        return list(value)
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{where}: {key!r} must be nested lists")
    return value


# --- WKT ----------------------------------------------------------------------------------------

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
    # POLYGON nests (rings (positions)), MULTIPOLYGON one level more: deeper is malformed.
    depth = 2 if kind == "POLYGON" else 3
    tree, pos = _wkt_group(tokens, pos, depth)
    if pos != len(tokens):
        raise ValueError(f"unexpected {' '.join(tokens[pos:pos + 3])!r} after the WKT geometry")
    if kind == "POLYGON":
        return polygon_with_holes(tree[0], tree[1:], where="WKT polygon")
    parts = [polygon_with_holes(p[0], p[1:], where=f"WKT polygon {i}") for i, p in enumerate(tree)]
    return _union(parts, "the MULTIPOLYGON")


def _wkt_group(tokens: list[str], pos: int, depth: int) -> tuple[Any, int]:
    """Parse ``( item, item, ... )``: groups ``depth - 1`` levels deep, then runs of numbers."""
    if pos >= len(tokens) or tokens[pos] != "(":
        found = tokens[pos] if pos < len(tokens) else "the end"
        raise ValueError(f"malformed WKT: expected '(' but found {found!r}")
    pos += 1
    items: list[Any] = []
    while True:
        if depth > 1:
            item, pos = _wkt_group(tokens, pos, depth - 1)
        else:
            numbers = []
            while pos < len(tokens) and tokens[pos] not in ("(", ")", ","):
                try:
                    numbers.append(float(tokens[pos]))
                except ValueError:
                    raise ValueError(f"malformed WKT: {tokens[pos]!r} is not a number") from None
                pos += 1
            if pos < len(tokens) and tokens[pos] == "(":
                raise ValueError("malformed WKT: too many '(' for the geometry type")
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
