"""injmesh.io: every format round-trips, boundary components keep distinct tags, writes are atomic."""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

import injmesh
from conftest import assert_valid_mesh, canonical_triangles
from injmesh import Circle, Mesh, Rectangle
from injmesh.io import EXTENSIONS, MeshFileError, boundary_names, format_for, read, write
from injmesh.triangulation import boundary_edges, delaunay

DOMAIN = Rectangle((0, 0), (3, 2)) - Circle((1, 1), 0.4) - Circle((2.2, 1), 0.3)
FORMATS = [(".msh", None), (".msh", "gmsh22"), (".vtu", None), (".xdmf", None), (".mesh", None),
           (".npz", None)]


@pytest.fixture(scope="module")
def holed() -> Mesh:
    """A coarse mesh of a rectangle with two round holes: tags 0 (outer), 1 and 2 (holes)."""
    return injmesh.generate(DOMAIN, 0.25)


def delaunay_mesh(points: np.ndarray) -> Mesh:
    t = delaunay(points)
    e = boundary_edges(t)
    return Mesh(points, t, e, np.zeros(len(e), dtype=int))


def edge_tags(mesh: Mesh) -> dict[tuple[int, int], int]:
    return {tuple(sorted(e)): int(t) for e, t in zip(mesh.boundary_edges.tolist(),
                                                   mesh.boundary_tags.tolist(), strict=True)}


def test_fixture_has_three_boundary_components(holed):
    assert sorted(set(holed.boundary_tags.tolist())) == [0, 1, 2]


@pytest.mark.parametrize(("ext", "fmt"), FORMATS)
def test_round_trip(tmp_path, holed, ext, fmt):
    path = tmp_path / f"mesh{ext}"
    write(holed, path, file_format=fmt)
    back = read(path)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary or companion files
    np.testing.assert_allclose(back.points, holed.points, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.triangles, holed.triangles)
    assert edge_tags(back) == edge_tags(holed)
    assert back.size is None
    assert_valid_mesh(back, DOMAIN)


def test_read_orients_boundary_edges_domain_on_left(tmp_path, holed):
    write(holed, tmp_path / "m.vtu")
    back = read(tmp_path / "m.vtu")
    half = {tuple(e) for e in np.concatenate([back.triangles[:, [0, 1]], back.triangles[:, [1, 2]],
                                              back.triangles[:, [2, 0]]]).tolist()}
    assert all(tuple(e) in half for e in back.boundary_edges.tolist())


def test_gmsh41_physical_groups(tmp_path, holed):
    path = tmp_path / "m.msh"
    write(holed, path)
    assert path.read_text().splitlines()[1].startswith("4.1 0")  # MSH 4.1, ASCII
    m = meshio.read(path, file_format="gmsh")
    assert set(m.field_data) == {"domain", "outer boundary", "hole 1", "hole 2"}
    tags = {name: int(v[0]) for name, v in m.field_data.items()}
    assert len(set(tags.values())) == 4  # distinct across dimensions
    assert int(m.field_data["domain"][1]) == 2 and int(m.field_data["hole 1"][1]) == 1
    physical = m.cell_data_dict["gmsh:physical"]
    assert set(physical["triangle"].tolist()) == {tags["domain"]}
    assert set(physical["line"].tolist()) == {tags["outer boundary"], tags["hole 1"], tags["hole 2"]}
    assert "gmsh:geometrical" in m.cell_data
    # Each group's lines lie on its own curve.
    lines = m.cells_dict["line"]
    mid = m.points[lines].mean(axis=1)[:, :2]
    hole1 = lines[physical["line"] == tags["hole 1"]]
    r = np.hypot(*(m.points[hole1.ravel(), :2] - [1, 1]).T)
    np.testing.assert_allclose(r, 0.4, atol=1e-9)
    assert len(mid) == len(holed.boundary_edges)


def test_gmsh22_on_request(tmp_path, holed):
    path = tmp_path / "m.msh"
    write(holed, path, file_format="gmsh22")
    assert path.read_text().splitlines()[1].startswith("2.2")
    m = meshio.read(path, file_format="gmsh")
    assert {"domain", "outer boundary", "hole 1", "hole 2"} == set(m.field_data)


@pytest.mark.parametrize(("ext", "key"), [(".vtu", "cell_tags"), (".mesh", "medit:ref")])
def test_vtu_and_medit_carry_integer_cell_tags(tmp_path, holed, ext, key):
    path = tmp_path / f"m{ext}"
    write(holed, path)
    m = meshio.read(path, file_format={".vtu": "vtu", ".mesh": "medit"}[ext])
    data = m.cell_data_dict[key]
    assert np.issubdtype(data["line"].dtype, np.integer)
    assert len(set(data["line"].tolist())) == 3
    assert set(data["triangle"].tolist()).isdisjoint(data["line"].tolist())


def test_xdmf_is_inline_xml(tmp_path, holed):
    path = tmp_path / "m.xdmf"
    write(holed, path)
    text = path.read_text()
    assert 'Format="XML"' in text and "HDF" not in text and 'Name="cell_tags"' in text


def test_npz_holds_the_four_arrays(tmp_path, holed):
    write(holed, tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as data:
        assert set(data.files) == {"points", "triangles", "boundary_edges", "boundary_tags"}


def test_boundary_names_tell_holes_from_components():
    p = np.array([[0, 0], [4, 0], [4, 4], [0, 4], [1, 1], [1, 2], [2, 2], [2, 1],
                  [5, 0], [6, 0], [6, 1]], float)
    e = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                  [8, 9], [9, 10], [10, 8]])
    names = boundary_names(e, np.repeat([0, 1, 2], [4, 4, 3]), p)
    assert names == {0: "outer boundary", 1: "hole 1", 2: "outer boundary 2"}


def test_unknown_extension_names_supported(tmp_path, holed):
    with pytest.raises(ValueError, match=r"\.msh.*\.vtu.*\.xdmf.*\.mesh.*\.npz"):
        write(holed, tmp_path / "m.stl")
    with pytest.raises(ValueError, match="file_format"):
        write(holed, tmp_path / "m.msh", file_format="gmsh3")
    assert list(tmp_path.iterdir()) == []


def test_format_for():
    assert {format_for(f"a{ext}") for ext in EXTENSIONS} == {"gmsh", "vtu", "xdmf", "medit", "npz"}
    assert format_for("a.MSH") == "gmsh"


def _partial(tmp: Path) -> None:
    """Leave a half-written file, as a crash in the middle of a write would, then fail."""
    Path(tmp).write_text("partial")
    raise OSError("disk full")


@pytest.mark.parametrize("ext", [".msh", ".vtu", ".xdmf", ".npz"])
def test_failed_write_leaves_nothing(tmp_path, holed, monkeypatch, ext):
    import injmesh.io as io_module

    monkeypatch.setattr(io_module, "_write_meshio", lambda meshio_, mesh, tmp, fmt: _partial(tmp))
    monkeypatch.setattr(io_module, "_write_xdmf", lambda tmp, *args: _partial(tmp))
    monkeypatch.setattr(np, "savez_compressed", lambda fh, **arrays: _partial(Path(fh.name)))
    with pytest.raises(OSError, match="disk full"):
        write(holed, tmp_path / f"m{ext}")
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_the_old_file(tmp_path, holed, monkeypatch):
    import injmesh.io as io_module

    target = tmp_path / "m.vtu"
    write(holed, target)
    before = target.read_bytes()

    def partial(meshio_mod, mesh, tmp, fmt):
        Path(tmp).write_text("partial")
        raise RuntimeError("boom")

    monkeypatch.setattr(io_module, "_write_meshio", partial)
    with pytest.raises(RuntimeError):
        write(holed, target)
    assert target.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["m.vtu"]


def test_write_into_missing_directory(tmp_path, holed):
    with pytest.raises(FileNotFoundError):
        write(holed, tmp_path / "nope" / "m.msh")


def test_read_missing_and_garbage(tmp_path):
    with pytest.raises(FileNotFoundError):
        read(tmp_path / "none.msh")
    for name, content in [("bad.msh", b"not a mesh\n"), ("bad.vtu", b"\x00\x01"),
                          ("bad.xdmf", b"<Xdmf"), ("bad.npz", b"PK\x03\x04 not a zip"),
                          ("bad.mesh", b"MeshVersionFormatted x\n")]:
        (tmp_path / name).write_bytes(content)
        with pytest.raises(MeshFileError, match="cannot read|has no"):
            read(tmp_path / name)
    with pytest.raises(MeshFileError, match="extension"):
        (tmp_path / "a.unknownext").write_text("x")
        read(tmp_path / "a.unknownext")


def test_read_file_without_triangles(tmp_path):
    m = meshio.Mesh(np.array([[0.0, 0, 0], [1, 0, 0]]), [("line", np.array([[0, 1]]))])
    m.write(tmp_path / "lines.vtu")
    with pytest.raises(MeshFileError, match="no triangles"):
        read(tmp_path / "lines.vtu")


def test_read_non_planar(tmp_path):
    m = meshio.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 1]]), [("triangle", np.array([[0, 1, 2]]))])
    m.write(tmp_path / "bent.vtu")
    with pytest.raises(MeshFileError, match="planar"):
        read(tmp_path / "bent.vtu")


def test_read_foreign_file_without_lines(tmp_path):
    """Clockwise triangles, an unused node, no boundary lines: all repaired on reading."""
    ring = Circle((0, 0), 1) - Circle((0, 0), 0.4)
    mesh = injmesh.generate(ring, 0.3)
    cw = mesh.triangles[:, [0, 2, 1]]
    pts = np.vstack([mesh.points, [[5.0, 5.0]]])  # an unused node
    meshio.Mesh(np.column_stack([pts, np.zeros(len(pts))]), [("triangle", cw)]).write(
        tmp_path / "foreign.vtu")
    back = read(tmp_path / "foreign.vtu")
    assert back.n_points == mesh.n_points
    assert back.areas().min() > 0
    assert_valid_mesh(back, ring)
    # Loops found from the edges: 0 is the outer circle, 1 the hole.
    r = np.hypot(*back.points[back.boundary_edges[:, 0]].T)
    np.testing.assert_allclose(r[back.boundary_tags == 0], 1.0, atol=1e-9)
    np.testing.assert_allclose(r[back.boundary_tags == 1], 0.4, atol=1e-9)


def test_read_untagged_lines_numbers_loops_by_area(tmp_path, holed):
    blocks = [("triangle", holed.triangles)]
    blocks += [("line", holed.boundary_edges[holed.boundary_tags == k]) for k in (0, 1, 2)]
    meshio.Mesh(np.column_stack([holed.points, np.zeros(holed.n_points)]), blocks).write(
        tmp_path / "plain.vtu")
    assert edge_tags(read(tmp_path / "plain.vtu")) == edge_tags(holed)


def test_npz_with_points_and_triangles_only(tmp_path):
    p = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float)
    np.savez(tmp_path / "min.npz", points=p, triangles=delaunay(p)[:, ::-1])
    back = read(tmp_path / "min.npz")
    assert back.areas().min() > 0 and len(back.boundary_edges) == 4
    np.savez(tmp_path / "nopoints.npz", triangles=np.zeros((1, 3), int))
    with pytest.raises(MeshFileError, match="points"):
        read(tmp_path / "nopoints.npz")


def by_coordinates(mesh: Mesh) -> tuple[np.ndarray, np.ndarray, set]:
    """Points sorted, triangles and tagged boundary edges renumbered to match: order-free."""
    order = np.lexsort(mesh.points.T[::-1])
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    tags = {(tuple(sorted(e)), t) for e, t in zip(rank[mesh.boundary_edges].tolist(),
                                                  mesh.boundary_tags.tolist(), strict=True)}
    return mesh.points[order], canonical_triangles(rank[mesh.triangles]), tags


@pytest.mark.parametrize(("ext", "fmt"), FORMATS)
def test_delaunay_mesh_round_trip(tmp_path, ext, fmt):
    """Any mesh, nodes in any order: the same mesh comes back (MSH 4.1 may renumber nodes)."""
    mesh = delaunay_mesh(np.random.default_rng(3).random((40, 2)))
    path = tmp_path / f"d{ext}"
    write(mesh, path, file_format=fmt)
    back = read(path)
    if ext != ".msh" or fmt == "gmsh22":
        np.testing.assert_array_equal(back.triangles, mesh.triangles)
    p0, t0, e0 = by_coordinates(mesh)
    p1, t1, e1 = by_coordinates(back)
    np.testing.assert_allclose(p1, p0, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(t1, t0)
    assert e1 == e0


def test_msh41_numbers_nodes_in_file_order(tmp_path):
    """The node tags in the file run 1..n in file order, so Gmsh and meshio agree."""
    mesh = delaunay_mesh(np.random.default_rng(4).random((30, 2)))
    write(mesh, tmp_path / "d.msh")
    lines = (tmp_path / "d.msh").read_text().splitlines()
    start = lines.index("$Nodes")
    n_blocks, n_nodes = (int(v) for v in lines[start + 1].split()[:2])
    tags, i = [], start + 2
    for _ in range(n_blocks):
        count = int(lines[i].split()[3])
        tags += [int(v) for v in lines[i + 1 : i + 1 + count]]
        i += 1 + 2 * count
    assert tags == list(range(1, n_nodes + 1))


def test_mesh_write_and_package_read_delegate(tmp_path, holed):
    holed.write(tmp_path / "m.vtu")
    holed.write(tmp_path / "m.msh", file_format="gmsh22")
    for name in ("m.vtu", "m.msh"):
        assert edge_tags(injmesh.read(tmp_path / name)) == edge_tags(holed)
