"""Natural inputs: every form as_domain accepts gives the same mesh as the equivalent Polygon.

Covers shapely (when installed) and any ``__geo_interface__`` object, GeoJSON dicts with tuples
or lists and GeoJSON text, WKT, ``(n, 2)`` arrays and vertex lists, and size expressions given
as strings or through ``injmesh.size_expression``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import injmesh
from injmesh import GeometryError, Polygon
from injmesh.geometry import as_domain
from injmesh.geometry.convert import looks_like_text_geometry, polygon_with_holes, to_domain

SHELL = [(0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0)]
HOLE = [(1.0, 1.0), (2.0, 1.0), (2.0, 2.0), (1.0, 2.0)]
FAR = [(6.0, 0.0), (7.0, 0.0), (7.0, 1.0), (6.0, 1.0)]
H = 0.45


def closed(ring):
    return [*ring, ring[0]]


def same_mesh(a: injmesh.Mesh, b: injmesh.Mesh) -> bool:
    return (np.array_equal(a.points, b.points) and np.array_equal(a.triangles, b.triangles)
            and np.array_equal(a.boundary_edges, b.boundary_edges))


class GeoThing:
    """A minimal third-party geometry: only ``__geo_interface__``, with tuples like shapely."""

    def __init__(self, mapping):
        self.__geo_interface__ = mapping


@pytest.fixture(scope="module")
def with_hole() -> injmesh.Mesh:
    return injmesh.generate(Polygon(SHELL) - Polygon(HOLE), H)


@pytest.fixture(scope="module")
def plain() -> injmesh.Mesh:
    return injmesh.generate(Polygon(SHELL), H)


def tuple_geojson():
    return {"type": "Polygon", "coordinates": (tuple(closed(SHELL)), tuple(closed(HOLE)))}


@pytest.mark.parametrize(
    "form",
    [
        pytest.param(tuple_geojson(), id="geojson-tuples"),
        pytest.param({"type": "Polygon", "coordinates": [closed(SHELL), closed(HOLE)]},
                     id="geojson-lists"),
        pytest.param({"type": "Feature", "properties": {},
                      "geometry": {"type": "MultiPolygon", "coordinates": [[SHELL, HOLE]]}},
                     id="geojson-feature"),
        pytest.param(json.dumps({"type": "Polygon", "coordinates": [SHELL, HOLE]}),
                     id="geojson-text"),
        pytest.param("POLYGON ((0 0, 4 0, 4 3, 0 3, 0 0), (1 1, 2 1, 2 2, 1 2, 1 1))", id="wkt"),
        pytest.param("  multipolygon (((0 0, 4 0, 4 3, 0 3)), ((6 0, 7 0, 7 1, 6 1)))",
                     id="wkt-multi-not-equal"),
        pytest.param(GeoThing(tuple_geojson()), id="geo-interface"),
        pytest.param({"type": "Polygon", "coordinates": np.array([closed(SHELL)], dtype=float)},
                     id="geojson-array-ring-no-hole"),
    ],
)
def test_text_and_mapping_forms_mesh_like_the_polygon(form, with_hole, plain):
    if isinstance(form, str) and form.strip().startswith("multipolygon"):
        # Two polygons: the same mesh as their union written with Polygon.
        expected = injmesh.generate(Polygon(SHELL) | Polygon(FAR), H)
    elif isinstance(form, dict) and isinstance(form.get("coordinates"), np.ndarray):
        expected = plain
    else:
        expected = with_hole
    mesh = injmesh.generate(form, H)
    assert same_mesh(mesh, expected)


@pytest.mark.parametrize(
    "form",
    [
        pytest.param(np.array(SHELL), id="array"),
        pytest.param(SHELL, id="tuples"),
        pytest.param([list(v) for v in closed(SHELL)], id="closed-lists"),
        pytest.param(tuple(SHELL[::-1]), id="clockwise-tuple"),
        pytest.param(GeoThing({"type": "Polygon", "coordinates": (tuple(closed(SHELL)),)}),
                     id="geo-interface"),
    ],
)
def test_vertex_forms_mesh_like_the_polygon(form, plain):
    assert same_mesh(injmesh.generate(form, H), plain)


def test_shapely_geometries(with_hole):
    shapely_geometry = pytest.importorskip("shapely.geometry")
    poly = shapely_geometry.Polygon(SHELL, [HOLE])
    assert same_mesh(injmesh.generate(poly, H), with_hole)
    assert same_mesh(injmesh.generate(shapely_geometry.MultiPolygon([poly]), H), with_hole)
    # read_geojson(mapping(poly)) failed on shapely's tuples (issue 12).
    assert same_mesh(injmesh.generate(shapely_geometry.mapping(poly), H), with_hole)
    assert same_mesh(injmesh.generate(poly.wkt, H), with_hole)


def test_shapely_is_never_imported_by_the_library():
    import subprocess
    import sys

    code = ("import sys, injmesh; injmesh.generate([(0, 0), (1, 0), (0, 1)], 0.3); "
            "injmesh.generate('POLYGON ((0 0, 1 0, 0 1))', 0.3); "
            "assert 'shapely' not in sys.modules, 'shapely imported'")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_polygon_with_holes_is_the_difference():
    d = polygon_with_holes(SHELL, [HOLE])
    p = np.array([[0.5, 0.5], [1.5, 1.5], [3.5, 2.5], [5.0, 1.0]])
    ref = Polygon(SHELL) - Polygon(HOLE)
    assert np.array_equal(d.sdf(p), ref.sdf(p))


def test_size_expression_in_python(plain):
    expr = injmesh.size_expression("0.3 + 0.1*x")
    p = np.array([[0.0, 0.0], [2.0, 1.0]])
    assert np.allclose(expr(p), [0.3, 0.5])
    by_lambda = injmesh.generate(Polygon(SHELL), lambda q: 0.3 + 0.1 * q[:, 0])
    assert same_mesh(injmesh.generate(Polygon(SHELL), expr), by_lambda)
    assert same_mesh(injmesh.generate(Polygon(SHELL), "0.3 + 0.1*x"), by_lambda)
    # A constant expression is a constant size.
    assert same_mesh(injmesh.generate(Polygon(SHELL), str(H)), plain)
    assert same_mesh(injmesh.generate(Polygon(SHELL), "0.9 / 2"), plain)


@pytest.mark.parametrize(
    ("text", "error", "match"),
    [
        ("__import__('os')", ValueError, "not allowed"),
        ("x.real", ValueError, "attribute"),
        ("-1", injmesh.SizeError, "positive"),
        ("", ValueError, "empty"),
    ],
)
def test_size_expression_refuses(text, error, match):
    with pytest.raises(error, match=match):
        injmesh.size_expression(text)
    with pytest.raises(error, match=match):
        injmesh.generate(Polygon(SHELL), text)


@pytest.mark.parametrize(
    ("obj", "error", "match"),
    [
        (42, TypeError, "got int"),
        ("shape.wkt", GeometryError, "WKT .* or GeoJSON text"),
        (np.zeros((4, 3)), GeometryError, r"shape \(n, 2\)"),
        ([[SHELL, HOLE]], GeometryError, r"shape \(n, 2\)"),
        ([("a", "b"), (1, 0), (0, 1)], TypeError, "vertices"),
        ([(0, 0), (1, 1)], GeometryError, "3 distinct vertices"),
        ({"type": "LineString", "coordinates": [(0, 0), (1, 1)]}, ValueError, "not an area"),
        (GeoThing("POLYGON"), TypeError, "not a mapping"),
        ({"type": "Polygon", "coordinates": ()}, GeometryError, "outer ring"),
    ],
)
def test_bad_forms_name_the_problem(obj, error, match):
    with pytest.raises(error, match=match):
        as_domain(obj)


def test_text_geometry_detection():
    assert looks_like_text_geometry("POLYGON((0 0, 1 0, 0 1))")
    assert looks_like_text_geometry(" MultiPolygon Z (((0 0 0, 1 0 0, 0 1 0)))")
    assert looks_like_text_geometry('{"type": "Polygon"}')
    for name in ("polygon.wkt", "polygons/a.geojson", "unit_disc", "POLYGON"):
        assert not looks_like_text_geometry(name)


def test_nesting_is_bounded():
    deep = {"type": "Feature", "geometry": None}
    for _ in range(100):
        deep = {"type": "Feature", "geometry": deep}
    with pytest.raises(ValueError, match="nested more than"):
        to_domain(deep)
    with pytest.raises(ValueError, match="nested too deeply|invalid JSON"):
        to_domain("{" + '"a": [' * 200_000)
    with pytest.raises(ValueError, match="too many"):
        to_domain("POLYGON " + "(" * 100_000)
    with pytest.raises(ValueError, match="too many|expected"):
        to_domain("MULTIPOLYGON ((((((0 0, 1 0, 0 1))))))")
