"""injmesh.inputs: GeoJSON, WKT, .poly, Python files, named cases, safe size expressions."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh import Circle, Domain, GeometryError, Rectangle, SizeError
from injmesh.inputs import (
    SizeExpression,
    graded_size,
    load_domain,
    parse_size,
    read_geojson,
    read_poly,
    read_python,
    read_wkt,
)

SHELL = [[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]
HOLE_A = [[1, 1], [1, 2], [2, 2], [2, 1], [1, 1]]
HOLE_B = [[2.5, 0.5], [3.5, 0.5], [3, 1.5], [2.5, 0.5]]
BOWTIE = [[0, 0], [3, 0], [0, 2], [2, 2.5], [0, 0]]


def inside(domain: Domain, points) -> np.ndarray:
    return domain.sdf(np.asarray(points, dtype=float)) < 0


def area(domain: Domain, n: int = 400) -> float:
    """Area by counting grid cells (enough to tell shapes apart)."""
    x0, y0, x1, y1 = domain.bbox
    xs = np.linspace(x0, x1, n, endpoint=False) + (x1 - x0) / (2 * n)
    ys = np.linspace(y0, y1, n, endpoint=False) + (y1 - y0) / (2 * n)
    gx, gy = np.meshgrid(xs, ys)
    frac = np.mean(inside(domain, np.column_stack([gx.ravel(), gy.ravel()])))
    return float(frac * (x1 - x0) * (y1 - y0))


# --- GeoJSON ----------------------------------------------------------------------------------


def test_geojson_polygon_with_two_holes():
    d = read_geojson({"type": "Polygon", "coordinates": [SHELL, HOLE_A, HOLE_B]})
    assert list(inside(d, [[0.5, 0.5], [1.5, 1.5], [3, 0.9], [3.9, 2.9], [5, 1]])) == [
        True, False, False, True, False]
    assert area(d) == pytest.approx(12 - 1 - 0.5, rel=0.01)


def test_geojson_wrappers_and_multipolygon():
    far = [[10, 0], [11, 0], [11, 1], [10, 1], [10, 0]]
    geometry = {"type": "MultiPolygon", "coordinates": [[SHELL, HOLE_A], [far]]}
    for obj in (
        geometry,
        {"type": "Feature", "properties": {}, "geometry": geometry},
        {"type": "FeatureCollection", "features": [{"type": "Feature", "geometry": geometry}]},
        {"type": "FeatureCollection", "features": [
            {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [SHELL, HOLE_A]}},
            {"type": "Feature", "geometry": None},
            {"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [far]}}]},
    ):
        d = read_geojson(json.dumps(obj))
        assert list(inside(d, [[0.5, 0.5], [1.5, 1.5], [10.5, 0.5], [7, 0.5]])) == [
            True, False, True, False]


def test_geojson_ignores_z_and_orientation():
    shell = [[x, y, 7.0] for x, y in SHELL[::-1]]
    d = read_geojson({"type": "Polygon", "coordinates": [shell]})
    assert inside(d, [[1, 1]])[0]


@pytest.mark.parametrize(
    ("obj", "match"),
    [
        ({"type": "Point", "coordinates": [1, 2]}, "not an area"),
        ({"type": "LineString", "coordinates": [[0, 0], [1, 1]]}, "not an area"),
        ({"coordinates": []}, "type"),
        ({"type": "Polygon", "coordinates": []}, "outer ring"),
        ({"type": "Polygon", "coordinates": "x"}, "nested lists"),
        ({"type": "Polygon", "coordinates": [[["a", "b"], [1, 0], [0, 1]]]}, "numbers"),
        ({"type": "FeatureCollection", "features": []}, "no polygon"),
    ],
)
def test_geojson_errors(obj, match):
    with pytest.raises(ValueError, match=match):
        read_geojson(obj)


def test_geojson_invalid_json():
    with pytest.raises(ValueError, match="invalid JSON"):
        read_geojson('{"type": ')


def test_geojson_self_intersecting_polygon():
    with pytest.raises(GeometryError, match="outer ring.*not simple"):
        read_geojson({"type": "Polygon", "coordinates": [BOWTIE]})
    with pytest.raises(GeometryError, match="hole 1"):
        read_geojson({"type": "Polygon", "coordinates": [[[-5, -5], [5, -5], [5, 5], [-5, 5]],
                                                         BOWTIE]})


# --- WKT --------------------------------------------------------------------------------------


def test_wkt_polygon_and_multipolygon():
    d = read_wkt("POLYGON ((0 0, 4 0, 4 3, 0 3, 0 0), (1 1, 2 1, 2 2, 1 2, 1 1))")
    assert area(d) == pytest.approx(11, rel=0.01)
    m = read_wkt("multipolygon(((0 0,1 0,1 1,0 1)),((2 0,3 0,3 1,2 1)))")
    assert list(inside(m, [[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]])) == [True, False, True]
    z = read_wkt("POLYGON Z ((0 0 1, 1 0 1, 1 1 1, 0 1 1))")
    assert inside(z, [[0.5, 0.5]])[0]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("POINT (1 2)", "not an area"),
        ("POLYGON EMPTY", "no area"),
        ("POLYGON ((0 0, 1 0, 1 1)", "missing"),
        ("POLYGON ((0 0, 1 0, 1 a))", "not a number"),
        ("POLYGON ((0 0, 1, 1 1))", "two numbers"),
        ("POLYGON ((0 0, 1 0, 1 1)) trailing", "after"),
        ("POLYGON 0 0", "expected"),
        ("", "empty"),
    ],
)
def test_wkt_errors(text, match):
    with pytest.raises(ValueError, match=match):
        read_wkt(text)


def test_wkt_self_intersecting():
    with pytest.raises(GeometryError, match="not simple"):
        read_wkt("POLYGON ((0 0, 3 0, 0 2, 2 2.5, 0 0))")


# --- Triangle .poly ---------------------------------------------------------------------------

SQUARE_WITH_HOLE_POLY = """\
# a square with a square hole, vertices numbered from 1
8 2 0 1
1 0 0 1
2 4 0 1
3 4 4 1
4 0 4 1
5 1 1 2
6 3 1 2
7 3 3 2
8 1 3 2
8 1
1 1 2 1
2 2 3 1
3 3 4 1
4 4 1 1
5 5 6 2
6 6 7 2
7 7 8 2
8 8 5 2
1
1 2 2
"""


def test_poly_square_with_hole(tmp_path):
    path = tmp_path / "sq.poly"
    path.write_text(SQUARE_WITH_HOLE_POLY)
    d = read_poly(path)
    assert list(inside(d, [[0.5, 0.5], [2, 2], [3.5, 3.5]])) == [True, False, True]
    assert area(d) == pytest.approx(12, rel=0.01)


def test_poly_without_hole_points_keeps_inner_loop_filled(tmp_path):
    path = tmp_path / "sq.poly"
    path.write_text(SQUARE_WITH_HOLE_POLY.rsplit("1\n1 2 2\n", 1)[0] + "0\n")
    assert inside(read_poly(path), [[2, 2]])[0]


def test_poly_island_in_hole_zero_based_and_node_file(tmp_path):
    square = lambda k, a, b: [f"{k + i} {x} {y}" for i, (x, y) in  # noqa: E731
                              enumerate([(a, a), (b, a), (b, b), (a, b)])]
    nodes = square(0, 0, 6) + square(4, 1, 5) + square(8, 2, 4)
    segs = [f"{k} {k} {k - k % 4 + (k + 1) % 4}" for k in range(12)]
    (tmp_path / "isl.node").write_text("12 2 0 0\n" + "\n".join(nodes) + "\n")
    (tmp_path / "isl.poly").write_text("0 2 0 0\n12 0\n" + "\n".join(segs) + "\n1\n0 1.5 1.5\n")
    d = read_poly(tmp_path / "isl.poly")
    assert list(inside(d, [[0.5, 0.5], [1.5, 1.5], [3, 3]])) == [True, False, True]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n2 0\n1 1 2\n2 2 3\n0\n", "closed loops"),
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n3 0\n1 1 2\n2 2 3\n3 3 9\n0\n", "vertex 9"),
        ("3 2 0 0\n1 0 0\n2 1 0\n", "ends inside"),
        ("3 2 0 0\n1 0 0\n2 x 0\n", "not numbers"),
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n0 0\n0\n", "no segments"),
        ("", "empty"),
    ],
)
def test_poly_errors(tmp_path, text, match):
    path = tmp_path / "bad.poly"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        read_poly(path)


# --- Python files and load_domain -------------------------------------------------------------


def test_python_file_domain_and_sizes(tmp_path):
    path = tmp_path / "shapes.py"
    path.write_text(
        "import numpy as np\n"
        "import injmesh\n"
        "domain = injmesh.Rectangle((0, 0), (2, 1))\n"
        "size = 0.1\n"
        "ring = injmesh.Circle((0, 0), 1) - injmesh.Circle((0, 0), 0.5)\n"
        "ring_size = lambda p: 0.05 + 0.1 * np.hypot(p[:, 0], p[:, 1])\n"
        "def blob(p):\n"
        "    return np.hypot(p[:, 0], p[:, 1]) - 1\n"
        "blob_bbox = (-1, -1, 1, 1)\n"
        "text_size = 'hypot(x, y) + 0.1'\n"
        "text = injmesh.Circle((0, 0), 1)\n"
        "number = 3\n"
    )
    plain = read_python(path)
    assert isinstance(plain.domain, Rectangle) and plain.size == 0.1
    ring = read_python(path, "ring")
    assert ring.size(np.array([[1.0, 0.0]]))[0] == pytest.approx(0.15)
    blob = read_python(path, "blob")
    assert blob.domain.sdf(np.zeros((1, 2)))[0] == pytest.approx(-1) and blob.size == 0.1
    assert isinstance(read_python(path, "text").size, SizeExpression)
    assert load_domain(f"{path}:ring").name == "shapes.ring"
    with pytest.raises(ValueError, match="not a domain"):
        read_python(path, "number")
    with pytest.raises(ValueError, match="defines no 'missing'"):
        read_python(path, "missing")


def test_python_file_errors(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("raise RuntimeError('nope')\n")
    with pytest.raises(ValueError, match="RuntimeError: nope"):
        read_python(bad)
    nobox = tmp_path / "nobox.py"
    nobox.write_text("domain = lambda p: p[:, 0]\n")
    with pytest.raises(ValueError, match="domain_bbox"):
        read_python(nobox)
    with pytest.raises(FileNotFoundError):
        read_python(tmp_path / "none.py")


def test_load_domain_dispatch(tmp_path):
    case = load_domain("unit_disc")
    assert isinstance(case.domain, Circle) and callable(case.size)
    (tmp_path / "a.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [SHELL]}))
    (tmp_path / "b.json").write_text(json.dumps({"type": "Polygon", "coordinates": [SHELL]}))
    (tmp_path / "c.wkt").write_text("POLYGON ((0 0, 4 0, 4 3, 0 3))\n")
    for name in ("a.geojson", "b.json", "c.wkt"):
        got = load_domain(str(tmp_path / name))
        assert got.size is None and inside(got.domain, [[2, 1]])[0]
    assert inside(load_domain("POLYGON ((0 0, 1 0, 1 1, 0 1))").domain, [[0.5, 0.5]])[0]


def test_load_domain_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown case 'nope'.*unit_disc"):
        load_domain("nope")
    with pytest.raises(FileNotFoundError):
        load_domain(str(tmp_path / "missing.geojson"))
    (tmp_path / "shape.txt").write_text("x")
    with pytest.raises(ValueError, match="extension"):
        load_domain(str(tmp_path / "shape.txt"))
    (tmp_path / "bin.geojson").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match="UTF-8"):
        load_domain(str(tmp_path / "bin.geojson"))


# --- sizes ------------------------------------------------------------------------------------


def test_parse_size_numbers():
    assert parse_size("0.05") == 0.05
    assert parse_size(" 1/20 ") == pytest.approx(0.05)
    assert parse_size("2*pi/100") == pytest.approx(2 * math.pi / 100)
    assert parse_size("e") == pytest.approx(math.e)


def test_parse_size_expression_vectorised():
    h = parse_size("min(0.05 + 0.2*sqrt((x-1)**2 + y**2), 0.3)")
    p = np.array([[1.0, 0.0], [0.0, 0.0], [-5.0, 0.0]])
    np.testing.assert_allclose(h(p), [0.05, 0.25, 0.3])
    g = parse_size("max(x, y, 0.1) + abs(-x)*0 + exp(0)*log(1) + sin(0) + cos(0) - 1 + tan(0)"
                   " + tanh(0) + atan2(0, 1) + hypot(3, 4) - 5")
    np.testing.assert_allclose(g(p), [1.0, 0.1, 0.1])
    assert parse_size("-(-x) + +y").__call__(np.array([[1.0, 2.0]]))[0] == 3.0


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("__import__('os')", "function '__import__' not allowed"),
        ("x.real", "attribute access not allowed"),
        ("os.system('ls')", "'os.system' not allowed"),
        ("x[0]", "subscripts"),
        ("lambda: 1", "lambda"),
        ("[t for t in x]", "comprehensions"),
        ("(t for t in x)", "comprehensions"),
        ("'0.1'", "strings"),
        ("b'0.1'", "strings"),
        ("f'{x}'", "strings"),
        ("z + 1", "unknown name 'z'"),
        ("open", "unknown name 'open'"),
        ("x if y else 1", "conditional"),
        ("x < y", "comparisons"),
        ("x and y", "boolean"),
        ("x // 2", "FloorDiv"),
        ("x % 2", "Mod"),
        ("~x", "not allowed"),
        ("(x, y)", "tuples"),
        ("[x]", "lists"),
        ("{1: 2}", "dicts"),
        ("True", "not allowed"),
        ("1j", "not allowed"),
        ("sqrt(x, y)", "takes 1"),
        ("hypot(x)", "takes 2"),
        ("min()", "1 or more"),
        ("sqrt(x=1)", "keyword"),
        ("sqrt(*x)", "starred"),
        ("(y := 2)", "assignment"),
        ("x +", "not valid"),
        ("0.1; import os", "not valid"),
        ("", "empty"),
        ("(" * 500 + "x" + ")" * 500, "nested|not valid"),
        ("x" * 3000, "longer"),
    ],
)
def test_parse_size_refuses(text, match):
    with pytest.raises(ValueError, match=match):
        parse_size(text)


@pytest.mark.parametrize("text", ["0", "-0.1", "1 - 1", "9**9**9**9", "log(0)", "10**400"])
def test_parse_size_constant_must_be_positive_and_finite(text):
    with pytest.raises(SizeError, match="positive"):
        parse_size(text)


def test_size_expression_repr_and_shape():
    h = SizeExpression("0.1")
    assert repr(h) == "SizeExpression('0.1')"
    assert h(np.zeros((4, 2))).shape == (4,)


def test_graded_size():
    disc = Circle((0, 0), 1)
    h = graded_size(disc, 0.05, growth=0.2, size_max=0.15)
    np.testing.assert_allclose(h(np.array([[1.0, 0], [0.75, 0], [0.0, 0], [2.0, 0]])),
                               [0.05, 0.1, 0.15, 0.05])
    uncapped = graded_size(disc, 0.05)
    assert uncapped(np.zeros((1, 2)))[0] == pytest.approx(0.25)
    for args in [(0, 0.2, None), (-1, 0.2, None), (0.1, -0.1, None), (0.1, 0.2, 0.05),
                 (math.nan, 0.2, None), (0.1, math.inf, None)]:
        with pytest.raises(SizeError):
            graded_size(disc, *args)


@settings(max_examples=50, deadline=None)
@given(
    x=st.floats(-3, 3), y=st.floats(-3, 3),
    size_min=st.floats(0.001, 1), growth=st.floats(0, 2), extra=st.floats(0, 5),
)
def test_graded_size_stays_between_its_bounds(x, y, size_min, growth, extra):
    domain = Rectangle((-1, -1), (2, 1)) - Circle((0.5, 0), 0.3)
    h = graded_size(domain, size_min, growth, size_min + extra)(np.array([[x, y]]))[0]
    assert size_min <= h <= size_min + extra + 1e-12


# --- bounded readers (issue 8: a header must not make the reader allocate without bound) -----


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("1000000000000 2 0 0\n1 0 0\n2 1 0\n3 0 1\n", "announces 1000000000000"),
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n1000000000000 0\n1 1 2\n", "segment section announces"),
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n3 0\n1 1 2\n2 2 3\n3 3 1\n1000000000000\n", "hole section"),
        ("1e300 2 0 0\n1 0 0\n", r"announces 1e\+300 lines"),
        ("-3 2 0 0\n1 0 0\n", "whole number"),
        ("2.5 2 0 0\n1 0 0\n", "whole number"),
        ("3 2 0 0\n1 0 0\n2 1 0\n3 0 1\n3 0\n1 1 2\n2 2 3\n3 3 1\n1\n1 0.2\n", "hole lines"),
    ],
)
def test_poly_counts_checked_against_the_file(tmp_path, text, match):
    import tracemalloc

    path = tmp_path / "huge.poly"
    path.write_text(text)
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=match):
            read_poly(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10_000_000, f"the reader allocated {peak} bytes for a {len(text)}-byte file"


def test_node_file_count_checked(tmp_path):
    (tmp_path / "a.poly").write_text("0 2 0 0\n3 0\n1 1 2\n2 2 3\n3 3 1\n0\n")
    (tmp_path / "a.node").write_text("1000000000000 2 0 0\n1 0 0\n2 1 0\n3 0 1\n")
    with pytest.raises(ValueError, match="announces 1000000000000 vertices"):
        read_poly(tmp_path / "a.poly")


def test_load_domain_never_treats_geometry_text_as_a_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    angles = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    wkt = "POLYGON ((" + ", ".join(f"{np.cos(a):.6f} {np.sin(a):.6f}" for a in angles) + "))"
    assert len(wkt) > 300
    disc = load_domain(wkt)
    assert disc.name == "wkt" and area(disc.domain) == pytest.approx(np.pi, rel=0.02)
    with pytest.raises(ValueError, match="WKT") as info:
        load_domain(wkt[:-1])  # malformed: a WKT error, never "File name too long"
    assert not isinstance(info.value, OSError)
    square = load_domain("POLYGON ((0 0, 1 0, 1 1, 0 1))" + " " * 300)
    assert square.name == "wkt" and inside(square.domain, [[0.5, 0.5]])[0]
    geojson = load_domain(json.dumps({"type": "Polygon", "coordinates": [SHELL]}))
    assert geojson.name == "geojson" and area(geojson.domain) == pytest.approx(12, rel=0.01)
    with pytest.raises(FileNotFoundError):
        load_domain("x" * 5000 + ".geojson")
