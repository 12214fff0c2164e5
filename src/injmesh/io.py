"""Reading and writing meshes: Gmsh, VTK, XDMF and Medit through meshio, and a native ``.npz``.

The format follows the file's extension:

========  ===================  ==========================================================
``.msh``  Gmsh 4.1 (ASCII)     nodes grouped by entity (see below); ``file_format="gmsh22"``
                               writes the older MSH 2.2 instead
``.vtu``  VTK XML unstructured
``.xdmf`` XDMF                 data inline (XML), so no companion HDF5 file is needed
``.mesh`` Medit
``.npz``  injmesh native       ``points``, ``triangles``, ``boundary_edges``,
                               ``boundary_tags``; needs only NumPy
========  ===================  ==========================================================

Boundary components
-------------------
Besides the triangles, every file carries the boundary edges as ``line`` cells, one cell block
per boundary component, tagged with ``boundary_tags + 1``: 1 is the outer boundary, ``k + 1``
the k-th further loop.  The triangles are tagged ``max(boundary_tags) + 2``, so every tag is
distinct across dimensions.  In ``.msh`` files the tags are Gmsh physical groups named
``"domain"``, ``"outer boundary"``, ``"hole 1"``, ``"hole 2"``, ... (a further loop running
counter-clockwise, the outside of another component, is named ``"outer boundary k"``); VTU and
XDMF files store them as the integer cell data ``cell_tags``, Medit files as ``medit:ref``.

MSH 4.1 stores nodes entity by entity (each boundary component's nodes, then the interior), and
readers such as meshio number nodes in file order; so the file numbers nodes in that order.  A
mesh from :func:`injmesh.generate` already has its boundary nodes first and keeps its numbering;
any other mesh reads back from ``.msh`` with the same points and triangles, renumbered.

Writes are atomic: the file is written under a temporary name in the target directory and
renamed over the target, so a failed write leaves nothing behind and never a half-written file.

Examples
--------
>>> import tempfile, pathlib
>>> import numpy as np
>>> from injmesh import Mesh
>>> from injmesh.io import read, write
>>> from injmesh.triangulation import boundary_edges, delaunay
>>> p = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float)
>>> t = delaunay(p)
>>> e = boundary_edges(t)
>>> mesh = Mesh(p, t, e, np.zeros(len(e), int))
>>> with tempfile.TemporaryDirectory() as tmp:
...     write(mesh, pathlib.Path(tmp) / "square.npz")
...     back = read(pathlib.Path(tmp) / "square.npz")
>>> back.n_triangles
4
"""

from __future__ import annotations

import contextlib
import os
import secrets
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .quality import signed_areas
from .triangulation import boundary_edges as _boundary_edges

if TYPE_CHECKING:
    from .mesh import Mesh

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

MISSING_MESHIO = "reading and writing this format needs meshio: pip install 'injmesh[io]'"

#: Extension -> format written by default.
EXTENSIONS: dict[str, str] = {
    ".msh": "gmsh",
    ".vtu": "vtu",
    ".xdmf": "xdmf",
    ".mesh": "medit",
    ".npz": "npz",
}

#: Formats accepted by ``write(..., file_format=...)``.
FORMATS: tuple[str, ...] = ("gmsh", "gmsh22", "vtu", "xdmf", "medit", "npz")


class MeshFileError(ValueError):
    """A file cannot be read as a triangular mesh, or a format is not supported."""


def _meshio() -> Any:
    try:
        import meshio
    except ImportError as exc:
        raise ImportError(MISSING_MESHIO) from exc
    return meshio


def format_for(path: str | os.PathLike[str], file_format: str | None = None) -> str:
    """The format :func:`write` uses for ``path``: one of :data:`FORMATS`.

    Raises
    ------
    MeshFileError
        Unknown ``file_format``, or an extension not in :data:`EXTENSIONS`.

    Examples
    --------
    >>> format_for("out.msh"), format_for("out.msh", "gmsh22"), format_for("out.vtu")
    ('gmsh', 'gmsh22', 'vtu')
    """
    path = Path(path)
    if file_format is not None:
        if file_format not in FORMATS:
            raise MeshFileError(
                f"unknown file_format {file_format!r}; choose one of {', '.join(FORMATS)}"
            )
        return file_format
    ext = path.suffix.lower()
    if ext not in EXTENSIONS:
        raise MeshFileError(
            f"cannot tell the mesh format of {str(path)!r} from its extension {ext or '(none)'!r}; "
            f"supported: {', '.join(EXTENSIONS)}"
        )
    return EXTENSIONS[ext]


def boundary_names(
    boundary_edges: IntArray, boundary_tags: IntArray, points: FloatArray
) -> dict[int, str]:
    """Name each boundary component: ``"outer boundary"``, ``"hole 1"``, ...

    A tag is a hole when its edges run clockwise (negative enclosed area, since edges keep the
    domain on their left) and an outer boundary when they run counter-clockwise.  Both kinds are
    numbered in tag order, which ``generate`` makes stable (outer boundaries by decreasing area,
    each followed by its holes): ``"outer boundary"``, ``"outer boundary 2"``, ... and
    ``"hole 1"``, ``"hole 2"``, ...

    Parameters
    ----------
    boundary_edges : (k, 2) int array
        Oriented boundary edges.
    boundary_tags : (k,) int array
        Component of each edge.
    points : (n, 2) float array
        Node coordinates.

    Returns
    -------
    dict
        Tag -> name, for every tag present.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.array([[0, 0], [4, 0], [4, 4], [0, 4], [1, 1], [1, 2], [2, 2], [2, 1]], float)
    >>> e = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4]])
    >>> boundary_names(e, np.repeat([0, 1], 4), p)
    {0: 'outer boundary', 1: 'hole 1'}
    """
    tags = np.asarray(boundary_tags, dtype=np.intp)
    if len(tags) == 0:
        return {}
    a, b = points[boundary_edges[:, 0]], points[boundary_edges[:, 1]]
    area = np.bincount(tags, weights=0.5 * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]))
    names = {}
    outers = holes = 0
    for tag in np.unique(tags).tolist():
        if area[tag] < 0:
            holes += 1
            names[tag] = f"hole {holes}"
        else:
            outers += 1
            names[tag] = "outer boundary" if outers == 1 else f"outer boundary {outers}"
    return names


def write(mesh: Mesh, path: str | os.PathLike[str], *, file_format: str | None = None) -> None:
    """Write a mesh, choosing the format from the extension (see the module notes).

    Parameters
    ----------
    mesh : Mesh
        The mesh.
    path : str or path-like
        Target file; it is replaced atomically if it exists.
    file_format : {"gmsh", "gmsh22", "vtu", "xdmf", "medit", "npz"}, optional
        Overrides the extension: ``"gmsh"`` is MSH 4.1, ``"gmsh22"`` MSH 2.2.

    Raises
    ------
    MeshFileError
        Unknown extension or format (a ``ValueError``).
    ImportError
        meshio is needed for the format and missing.
    OSError
        The directory does not exist or is not writable.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> from injmesh import Mesh
    >>> mesh = Mesh(np.array([[0, 0], [1, 0], [0, 1]], float), np.array([[0, 1, 2]]),
    ...             np.array([[0, 1], [1, 2], [2, 0]]), np.zeros(3, int))
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     write(mesh, pathlib.Path(tmp) / "triangle.msh")
    ...     sorted(p.name for p in pathlib.Path(tmp).iterdir())
    ['triangle.msh']
    """
    path = Path(path)
    fmt = format_for(path, file_format)
    meshio = None if fmt == "npz" else _meshio()
    with atomic_path(path) as tmp:
        if fmt == "npz":
            with open(tmp, "xb") as fh:
                arrays: dict[str, Any] = {
                    "points": np.asarray(mesh.points, dtype=float),
                    "triangles": np.asarray(mesh.triangles, dtype=np.int64),
                    "boundary_edges": np.asarray(mesh.boundary_edges, dtype=np.int64),
                    "boundary_tags": np.asarray(mesh.boundary_tags, dtype=np.int64),
                    **_region_arrays(mesh),
                }
                np.savez_compressed(fh, **arrays)
        else:
            _write_meshio(meshio, mesh, tmp, fmt)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path beside ``path``, renamed over ``path`` when the block succeeds.

    The temporary file is a hidden sibling with the same extension (writers that look at the
    extension still work); if the block raises, it is removed and ``path`` is left untouched.

    Raises
    ------
    FileNotFoundError
        The directory of ``path`` does not exist.
    IsADirectoryError
        ``path`` is a directory.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     with atomic_path(pathlib.Path(tmp) / "notes.txt") as part:
    ...         _ = part.write_text("done")
    ...     sorted(p.name for p in pathlib.Path(tmp).iterdir())
    ['notes.txt']
    """
    path = Path(path)
    if not path.parent.is_dir():
        raise FileNotFoundError(f"directory {str(path.parent)!r} does not exist")
    if path.is_dir():
        raise IsADirectoryError(f"{str(path)!r} is a directory")
    tmp = path.parent / f".{path.stem}.{secrets.token_hex(6)}.tmp{path.suffix}"
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _write_meshio(meshio: Any, mesh: Mesh, tmp: Path, fmt: str) -> None:
    points = np.asarray(mesh.points, dtype=np.float64)
    triangles = np.asarray(mesh.triangles, dtype=np.int64)
    edges = np.asarray(mesh.boundary_edges, dtype=np.int64).reshape(-1, 2)
    tags = np.asarray(mesh.boundary_tags, dtype=np.int64).reshape(-1)
    names = boundary_names(edges, tags, points)
    loop_tags = sorted(names)
    domain_tag = (max(loop_tags) + 2) if loop_tags else 1

    cells: list[tuple[str, NDArray[np.int64]]] = [("triangle", triangles)]
    block_tags = [domain_tag]
    for tag in loop_tags:
        cells.append(("line", edges[tags == tag]))
        block_tags.append(tag + 1)
    # Regions: one triangle block each (tag domain_tag + k), interior curves one line block each
    # (after the regions' tags); the blocks' names go to the .msh physical groups.
    region_names, curve_names = tuple(mesh.region_names), tuple(mesh.curve_names)
    group_names: dict[int, tuple[str, int]] = {}
    tri_tags = np.asarray(mesh.triangle_tags, dtype=np.int64)
    if len(region_names) > 1 and len(tri_tags) == len(triangles):
        cells[0] = ("triangle", triangles[tri_tags == 0])
        for k in range(1, len(region_names)):
            cells.append(("triangle", triangles[tri_tags == k]))
            block_tags.append(domain_tag + k)
            group_names[domain_tag + k] = (region_names[k], 2)
    curve_edges = np.asarray(mesh.curve_edges, dtype=np.int64).reshape(-1, 2)
    curve_tags = np.asarray(mesh.curve_tags, dtype=np.int64)
    for c, name in enumerate(curve_names):
        tag = domain_tag + len(region_names) + c
        cells.append(("line", curve_edges[curve_tags == c]))
        block_tags.append(tag)
        group_names[tag] = (name, 1)
    # Empty blocks are left out (meshio's MSH 4.1 and VTU writers fail on them): a line block
    # with no edge, or the rest of a domain that regions partition.  The domain's own triangle
    # block is the one tagged ``domain_tag``, wherever it is.
    keep = [i for i, (_, data) in enumerate(cells) if len(data)]
    cells, block_tags = [cells[i] for i in keep], [block_tags[i] for i in keep]
    per_cell = [
        np.full(len(c), t, dtype=np.int64) for (_, c), t in zip(cells, block_tags, strict=True)
    ]

    if fmt in ("gmsh", "gmsh22"):
        # Entities: the 2-D surface 1 and one 1-D curve per boundary component.
        geometrical = [np.full(len(c[1]), 1 if c[0] == "triangle" and t == domain_tag else t, dtype=np.int64)
                       for c, t in zip(cells, block_tags, strict=True)]
        field_data = {"domain": np.array([domain_tag, 2])}
        field_data.update({names[t]: np.array([t + 1, 1]) for t in loop_tags})
        field_data.update({name: np.array([t, dim]) for t, (name, dim) in group_names.items()
                           if t in block_tags})
        cell_data = {"gmsh:physical": per_cell, "gmsh:geometrical": geometrical}
        point_data = {}
        if fmt == "gmsh":
            # MSH 4 groups nodes by entity: interior nodes on the surface, the others on a curve.
            dim_tags = np.tile(np.array([2, 1], dtype=np.int64), (len(points), 1))
            if len(edges):
                dim_tags[edges[:, 0], 0] = 1
                dim_tags[edges[:, 0], 1] = tags + 1
            # Interior nodes of a region lie on its own surface.
            for (kind, data), tag in zip(cells, block_tags, strict=True):
                if kind == "triangle" and tag != domain_tag:
                    inner = np.unique(data)
                    inner = inner[dim_tags[inner, 0] == 2]
                    dim_tags[inner, 1] = tag
            # meshio writes an entity's physical group only if some node lies on the entity.
            # (A block with no cell has no node to give: the rest of a domain that regions
            # partition, whose triangle block is kept empty.)
            for (_, data), tag in zip(cells, block_tags, strict=True):
                dim = 2 if data.shape[1] == 3 else 1
                entity = 1 if dim == 2 and tag == domain_tag else tag
                if len(data) and not np.any((dim_tags[:, 0] == dim) & (dim_tags[:, 1] == entity)):
                    dim_tags[data[0, 0]] = (dim, entity)
            # Nodes are stored entity by entity; number them in that order so that the node
            # tags in the file run 1, 2, 3, ... and every reader agrees on the numbering.  For
            # a mesh from generate() (boundary nodes first, loop by loop) this keeps the order.
            order = np.lexsort((dim_tags[:, 1], dim_tags[:, 0]))
            if np.any(order != np.arange(len(order))):
                new = np.empty_like(order)
                new[order] = np.arange(len(order))
                points, dim_tags = points[order], dim_tags[order]
                cells = [(kind, new[data]) for kind, data in cells]
            point_data["gmsh:dim_tags"] = dim_tags
        out = meshio.Mesh(points, cells, point_data=point_data, cell_data=cell_data,
                          field_data=field_data)
        meshio.write(tmp, out, file_format=fmt, binary=False)
    elif fmt == "medit":
        out = meshio.Mesh(points, cells, cell_data={"medit:ref": per_cell})
        meshio.write(tmp, out, file_format="medit")
    elif fmt == "xdmf":
        _write_xdmf(tmp, points, cells, np.concatenate(per_cell), _named_groups(group_names, block_tags,
                                                                               domain_tag, names))
    else:
        # VTK wants 3-D points; pad here rather than let meshio warn on stderr.
        points3 = np.column_stack([points, np.zeros(len(points))])
        # meshio's VTU writer drops field data: regions keep their tags, not their names.
        out = meshio.Mesh(points3, cells, cell_data={"cell_tags": per_cell})
        meshio.write(tmp, out, file_format=fmt)


# XDMF is written here, not by meshio: meshio's XDMF writer and reader import h5py even for
# data stored inline as XML, and h5py is not a dependency.  The layout is meshio's (XDMF 3,
# "Mixed" topology when lines accompany the triangles), so meshio, ParaView and VisIt read it.
_XDMF_TRIANGLE, _XDMF_POLYLINE = 4, 2


def _xml_numbers(a: NDArray[Any]) -> str:
    """Rows of ``a`` as text, one row a line; floats in their shortest round-trip form."""
    rows = np.atleast_2d(a).astype(str).tolist()
    return "\n" + "\n".join(map(" ".join, rows)) + "\n"


def _write_xdmf(
    tmp: Path,
    points: FloatArray,
    cells: list[tuple[str, NDArray[np.int64]]],
    tags: NDArray[np.int64],
    groups: dict[str, tuple[int, int]] | None = None,
) -> None:
    import xml.etree.ElementTree as ET

    root = ET.Element("Xdmf", Version="3.0")
    grid = ET.SubElement(ET.SubElement(root, "Domain"), "Grid", Name="Grid")
    # Region and curve names: <Information Name="name" Value="tag dimension"/>.
    for name, (tag, dim) in (groups or {}).items():
        ET.SubElement(grid, "Information", Name=name, Value=f"{tag} {dim}")
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XY")
    item = ET.SubElement(geometry, "DataItem", DataType="Float", Dimensions=f"{len(points)} 2",
                         Format="XML", Precision="8")
    item.text = _xml_numbers(points)
    n_cells = sum(len(c) for _, c in cells)
    # Each triangle is "4 a b c" and each line "2 2 i j": four integers per cell either way.
    stream = np.concatenate([
        np.column_stack([np.full(len(c), _XDMF_TRIANGLE), c]) if kind == "triangle"
        else np.column_stack([np.full((len(c), 2), _XDMF_POLYLINE), c])
        for kind, c in cells
    ])
    topology = ET.SubElement(grid, "Topology", TopologyType="Mixed", NumberOfElements=str(n_cells))
    item = ET.SubElement(topology, "DataItem", DataType="Int", Dimensions=str(stream.size),
                         Format="XML", Precision="8")
    item.text = _xml_numbers(stream)
    attribute = ET.SubElement(grid, "Attribute", Name="cell_tags", AttributeType="Scalar",
                              Center="Cell")
    item = ET.SubElement(attribute, "DataItem", DataType="Int", Dimensions=str(n_cells),
                         Format="XML", Precision="8")
    item.text = _xml_numbers(tags[:, None])
    ET.ElementTree(root).write(tmp, encoding="utf-8", xml_declaration=True)


def _read_xdmf(path: Path, extras: dict[str, Any] | None = None
               ) -> tuple[FloatArray, IntArray, IntArray | None, IntArray | None] | None:
    """Read an XDMF 3 file whose data is inline XML; ``None`` if it needs meshio (HDF5 data)."""
    import xml.etree.ElementTree as ET

    root = ET.parse(path).getroot()
    grid = root.find(".//Grid")
    if root.tag != "Xdmf" or grid is None:
        raise MeshFileError(f"{str(path)!r} is not an XDMF file with a Grid")
    items = grid.findall(".//DataItem")
    if any(i.get("Format", "XML") != "XML" or "Reference" in i.attrib for i in items):
        return None

    def numbers(parent: ET.Element | None, dtype: type) -> NDArray[Any]:
        item = None if parent is None else parent.find("DataItem")
        if item is None:
            raise MeshFileError(f"{str(path)!r}: missing DataItem")
        return np.array((item.text or "").split(), dtype=dtype)

    geometry = grid.find("Geometry")
    kind = "XYZ" if geometry is None else geometry.get("GeometryType", "XYZ")
    if kind not in ("XY", "XYZ"):
        return None
    points = numbers(geometry, float).reshape(-1, len(kind))
    topology = grid.find("Topology")
    ttype = "" if topology is None else topology.get("TopologyType", "").lower()
    if ttype == "triangle":
        return points, numbers(topology, int).reshape(-1, 3), None, None
    if ttype != "mixed":
        raise MeshFileError(f"{str(path)!r}: topology {ttype or '(none)'!r} is not triangles")
    stream = numbers(topology, int)
    if stream.size % 4 or not np.all(np.isin(stream[::4], (_XDMF_TRIANGLE, _XDMF_POLYLINE))):
        return None  # other cell kinds: leave the general case to meshio
    rows = stream.reshape(-1, 4)
    is_tri = rows[:, 0] == _XDMF_TRIANGLE
    if np.any(rows[~is_tri, 1] != 2):
        return None
    tags = None
    for attribute in grid.findall("Attribute"):
        if attribute.get("Center") == "Cell" and attribute.get("Name") in _TAG_KEYS:
            values = numbers(attribute, float)
            if len(values) == len(rows) and np.all(values == np.round(values)):
                tags = values.astype(np.intp)[~is_tri]
                if extras is not None:
                    extras["triangle_values"] = values.astype(np.intp)[is_tri]
                    extras["line_cells"] = rows[~is_tri, 2:]
                    extras["line_values"] = tags
                break
    if extras is not None:
        groups = {}
        for info in grid.findall("Information"):
            value = (info.get("Value") or "").split()
            if info.get("Name") and len(value) == 2 and all(v.lstrip("-").isdigit() for v in value):
                groups[(int(value[0]), int(value[1]))] = str(info.get("Name"))
        extras["group_names"] = groups
    lines = rows[~is_tri, 2:]
    if tags is None:
        tags = np.zeros(len(lines), dtype=np.intp)
    return points, rows[is_tri, 1:], lines, tags


def read(path: str | os.PathLike[str]) -> Mesh:
    """Read a triangular mesh from any file meshio reads, or from injmesh's ``.npz``.

    Triangles are reoriented counter-clockwise and nodes no triangle uses are dropped.  Boundary
    edges are recomputed from the triangles (oriented with the domain on their left) unless a
    ``.npz`` carries them.  Boundary tags come from the file's ``line`` cells when it has integer
    tags for them (``gmsh:physical``, ``cell_tags``, ``medit:ref``, ``gmsh:geometrical``): the
    distinct values in increasing order become 0, 1, 2, ... (boundary edges without a line cell
    get one more tag), so a file written by :func:`write` reads back with its tags.  Without
    tagged line cells the boundary loops are numbered from the edges: 0 is the loop enclosing the
    largest area, then the others by decreasing enclosed area.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    Mesh
        With ``size=None``.

    Raises
    ------
    FileNotFoundError
        No such file.
    MeshFileError
        The file cannot be parsed, has no triangles, or is not planar (a ``ValueError``).
    ImportError
        meshio is needed and missing.

    Examples
    --------
    See the module example.
    """
    from .mesh import Mesh

    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such file: {str(path)!r}")
    if path.is_dir():
        raise IsADirectoryError(f"{str(path)!r} is a directory")
    lines: IntArray | None = None
    line_tags: IntArray | None = None
    extras: dict[str, Any] = {}
    if path.suffix.lower() == ".npz":
        points, triangles, edges, tags = _read_npz(path, extras)
    else:
        points, triangles, lines, line_tags = _read_meshio(path, extras)
        edges, tags = None, None

    _validate(path, points, triangles)
    points, triangles, index = _compact(points, triangles)
    flip = signed_areas(points, triangles) < 0
    triangles[flip] = triangles[flip][:, [0, 2, 1]]

    if edges is not None and tags is not None and len(edges) == len(tags) and len(edges):
        edges = index[edges]
        if np.any(edges < 0):
            raise MeshFileError(f"{str(path)!r}: boundary_edges refer to nodes no triangle uses")
    else:
        edges = _boundary_edges(triangles)
        if lines is not None and line_tags is not None and len(lines):
            ok = np.all((lines >= 0) & (lines < len(index)), axis=1)
            tags = _tags_from_lines(edges, index[lines[ok]], line_tags[ok])
        else:
            tags = _loop_tags(points, edges)
    regions = _restore_regions(extras, index, len(triangles))
    return Mesh(points=points, triangles=triangles, boundary_edges=edges, boundary_tags=tags, **regions)


def _read_npz(path: Path, extras: dict[str, Any] | None = None
              ) -> tuple[FloatArray, IntArray, IntArray | None, IntArray | None]:
    try:
        with np.load(path, allow_pickle=False) as data:
            if extras is not None:
                for key in _REGION_KEYS:
                    if key in data.files:
                        extras[key] = np.asarray(data[key])
            missing = {"points", "triangles"} - set(data.files)
            if missing:
                raise MeshFileError(
                    f"{str(path)!r} has no {' or '.join(sorted(missing))} array; "
                    "an injmesh .npz holds points, triangles, boundary_edges, boundary_tags"
                )
            points = np.asarray(data["points"], dtype=float)
            triangles = np.asarray(data["triangles"])
            edges = np.asarray(data["boundary_edges"]) if "boundary_edges" in data.files else None
            tags = np.asarray(data["boundary_tags"]) if "boundary_tags" in data.files else None
    except MeshFileError:
        raise
    except (ValueError, OSError, EOFError, KeyError, zipfile.BadZipFile) as exc:
        if isinstance(exc, (FileNotFoundError, PermissionError)):
            raise
        raise MeshFileError(f"cannot read {str(path)!r} as a .npz mesh: {exc}") from None
    if not np.issubdtype(triangles.dtype, np.integer):
        raise MeshFileError(f"{str(path)!r}: triangles must be integers, got {triangles.dtype}")
    if edges is not None:
        edges = edges.astype(np.intp).reshape(-1, 2)
    if tags is not None:
        tags = tags.astype(np.intp).reshape(-1)
    return points, triangles.astype(np.intp), edges, tags


_TAG_KEYS = ("gmsh:physical", "cell_tags", "medit:ref", "gmsh:geometrical")


#: Formats meshio should try for an extension, in order (before meshio's own list).
_READ_FORMATS = {".msh": ["gmsh", "ansys"], ".mesh": ["medit"], ".vtu": ["vtu"], ".vtk": ["vtk"]}
#: meshio submodules whose name differs from the format's.
_READER_MODULES = {"gmsh22": "gmsh", "dolfin-xml": "dolfin"}


def _read_meshio(path: Path, extras: dict[str, Any] | None = None
                 ) -> tuple[FloatArray, IntArray, IntArray | None, IntArray | None]:
    ext = path.suffix.lower()
    if ext in (".xdmf", ".xmf"):
        try:
            inline = _read_xdmf(path, extras)
        except (ValueError, SyntaxError) as exc:  # ElementTree's ParseError is a SyntaxError
            raise MeshFileError(f"cannot read {str(path)!r} as XDMF: {exc}") from None
        if inline is not None:
            return inline
    meshio = _meshio()
    candidates = list(_READ_FORMATS.get(ext, []))
    candidates += [f for f in meshio.extension_to_filetypes.get(ext, []) if f not in candidates]
    if not candidates:
        raise MeshFileError(
            f"cannot tell the mesh format of {str(path)!r} from its extension {ext or '(none)'!r}; "
            f"injmesh reads .npz and what meshio reads (.msh, .vtu, .vtk, .xdmf, .mesh, ...)"
        )
    # Call each format's own reader: meshio.read prints a failed reader's error and then calls
    # sys.exit, which a library must not do.
    m, errors = None, []
    for fmt in candidates:
        module = getattr(meshio, _READER_MODULES.get(fmt, fmt.replace("-", "_")), None)
        reader = getattr(module, "read", None)
        if not callable(reader):
            errors.append(f"meshio has no {fmt} reader")
            continue
        try:
            m = reader(str(path))
            break
        except (FileNotFoundError, PermissionError, IsADirectoryError):
            raise
        except ImportError as exc:
            raise ImportError(f"reading {str(path)!r} needs a package meshio uses: {exc}") from None
        except Exception as exc:  # meshio raises many kinds of errors on malformed input
            if str(exc).strip():
                errors.append(str(exc).strip().splitlines()[0])
    if m is None:
        detail = "; ".join(dict.fromkeys(errors)) or "unrecognised content"
        raise MeshFileError(f"cannot read {str(path)!r} as {' or '.join(candidates)}: {detail}")
    points = np.asarray(m.points, dtype=float)
    blocks = [(i, c) for i, c in enumerate(m.cells) if c.type == "triangle"]
    if not blocks:
        kinds = ", ".join(sorted({c.type for c in m.cells})) or "none"
        raise MeshFileError(f"{str(path)!r} has no triangles (cell types: {kinds})")
    triangles = np.concatenate([np.asarray(c.data) for _, c in blocks]).astype(np.intp)
    if extras is not None:
        _region_extras(m, blocks, extras)
    line_blocks = [(i, c) for i, c in enumerate(m.cells) if c.type == "line"]
    if not line_blocks:
        return points, triangles, None, None
    lines = np.concatenate([np.asarray(c.data) for _, c in line_blocks]).astype(np.intp)
    for key in _TAG_KEYS:
        data = m.cell_data.get(key)
        if data is None:
            continue
        values = [np.asarray(data[i]).reshape(-1) for i, _ in line_blocks]
        if all(np.issubdtype(v.dtype, np.integer) and len(v) == len(c.data)
               for v, (_, c) in zip(values, line_blocks, strict=True)):
            return points, triangles, lines, np.concatenate(values).astype(np.intp)
    return points, triangles, None, None  # lines without tags: number the loops instead


def _validate(path: Path, points: FloatArray, triangles: IntArray) -> None:
    name = str(path)
    if points.ndim != 2 or points.shape[1] not in (2, 3) or len(points) == 0:
        raise MeshFileError(f"{name!r}: points must be (n, 2) or (n, 3), not {points.shape}")
    if not np.all(np.isfinite(points)):
        raise MeshFileError(f"{name!r}: points are not all finite")
    if triangles.ndim != 2 or triangles.shape[1] != 3 or len(triangles) == 0:
        raise MeshFileError(f"{name!r}: triangles must have shape (m, 3), got {triangles.shape}")
    if triangles.min() < 0 or triangles.max() >= len(points):
        raise MeshFileError(f"{name!r}: triangles refer to nodes outside 0..{len(points) - 1}")
    if points.shape[1] == 3:
        scale = float(np.ptp(points[:, :2], axis=0).max()) or 1.0
        if np.abs(points[:, 2]).max() > 1e-9 * scale:
            raise MeshFileError(f"{name!r}: the mesh is not planar (z is not 0)")


def _compact(points: FloatArray, triangles: IntArray) -> tuple[FloatArray, IntArray, IntArray]:
    """Drop unused nodes; return points, renumbered triangles and the old -> new index (-1)."""
    used = np.zeros(len(points), dtype=bool)
    used[triangles.ravel()] = True
    index = np.full(len(points), -1, dtype=np.intp)
    index[used] = np.arange(int(used.sum()))
    return np.ascontiguousarray(points[used, :2]), index[triangles], index


def _tags_from_lines(edges: IntArray, lines: IntArray, values: IntArray) -> IntArray:
    """Tag boundary edges by the rank of their line cell's value; unmatched edges get one more."""
    if np.any(lines < 0):
        keep = np.all(lines >= 0, axis=1)
        lines, values = lines[keep], values[keep]
    distinct, rank = np.unique(values, return_inverse=True)
    n = int(max(edges.max(initial=0), lines.max(initial=0))) + 1
    line_key = np.sort(lines, axis=1) @ np.array([n, 1])
    edge_key = np.sort(edges, axis=1) @ np.array([n, 1])
    order = np.argsort(line_key)
    pos = np.clip(np.searchsorted(line_key[order], edge_key), 0, max(len(order) - 1, 0))
    found = line_key[order][pos] == edge_key if len(order) else np.zeros(len(edges), bool)
    tags = np.full(len(edges), len(distinct), dtype=np.intp)
    tags[found] = rank.reshape(-1)[order][pos[found]]
    if not np.any(tags == len(distinct)):
        return tags
    return np.unique(tags, return_inverse=True)[1].reshape(-1).astype(np.intp)


def _loop_tags(points: FloatArray, edges: IntArray) -> IntArray:
    """Number the boundary loops: 0 encloses the largest area, then by decreasing |area|."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(edges) == 0:
        return np.zeros(0, dtype=np.intp)
    n = len(points)
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    comp = np.unique(label[edges[:, 0]], return_inverse=True)[1].reshape(-1)
    a, b = points[edges[:, 0]], points[edges[:, 1]]
    area = np.bincount(comp, weights=0.5 * (a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]))
    order = np.lexsort((-np.abs(area), -area))  # largest positive area first
    first, rest = order[:1], order[1:]
    rest = rest[np.argsort(-np.abs(area[rest]), kind="stable")]
    rank = np.empty(len(area), dtype=np.intp)
    rank[np.concatenate([first, rest])] = np.arange(len(area))
    return rank[comp]


# --- regions and interior curves ---------------------------------------------------------------

_REGION_KEYS = ("triangle_tags", "region_names", "curve_edges", "curve_tags", "curve_names")


def _region_arrays(mesh: Mesh) -> dict[str, NDArray[Any]]:
    """The region and curve arrays a ``.npz`` stores (nothing for a mesh without them)."""
    if len(mesh.region_names) <= 1 and len(mesh.curve_names) == 0:
        return {}
    return {
        "triangle_tags": np.asarray(mesh.triangle_tags, dtype=np.int64),
        "region_names": np.asarray(mesh.region_names, dtype=str),
        "curve_edges": np.asarray(mesh.curve_edges, dtype=np.int64).reshape(-1, 2),
        "curve_tags": np.asarray(mesh.curve_tags, dtype=np.int64),
        "curve_names": np.asarray(mesh.curve_names, dtype=str),
    }


def _region_extras(m: Any, blocks: list[tuple[int, Any]], extras: dict[str, Any]) -> None:
    """Triangle tags, named groups and line cells of a meshio mesh, for :func:`_restore_regions`.

    In a ``.msh`` file written by :func:`write`, every triangle block is a region named by a
    2-D physical group ("domain" the rest) and every line block not on the boundary a curve
    named by a 1-D group.  Other formats give integer tags without names.
    """
    for key in _TAG_KEYS:
        data = m.cell_data.get(key)
        if data is None:
            continue
        values = [np.asarray(data[i]).reshape(-1) for i, _ in blocks]
        if all(np.issubdtype(v.dtype, np.integer) for v in values):
            extras["triangle_values"] = np.concatenate(values).astype(np.intp)
            line_blocks = [(i, c) for i, c in enumerate(m.cells) if c.type == "line"]
            if line_blocks:
                extras["line_cells"] = np.concatenate([np.asarray(c.data) for _, c in line_blocks])
                extras["line_values"] = np.concatenate(
                    [np.asarray(data[i]).reshape(-1) for i, _ in line_blocks]).astype(np.intp)
            break
    names: dict[tuple[int, int], str] = {}
    for name, value in (getattr(m, "field_data", None) or {}).items():
        v = np.asarray(value).reshape(-1)
        if len(v) >= 2:
            names[(int(v[0]), int(v[1]))] = str(name)
    extras["group_names"] = names


def _restore_regions(extras: dict[str, Any], index: IntArray, n_triangles: int) -> dict[str, Any]:
    """Mesh keyword arguments for the regions and curves a file carries (none if it has none)."""
    if "triangle_tags" in extras:  # injmesh's .npz
        edges = np.asarray(extras.get("curve_edges", np.zeros((0, 2))), dtype=np.intp).reshape(-1, 2)
        ok = np.all(index[edges] >= 0, axis=1) if len(edges) else np.zeros(0, dtype=bool)
        return {
            "triangle_tags": np.asarray(extras["triangle_tags"], dtype=np.intp),
            "region_names": tuple(str(s) for s in extras.get("region_names", ("domain",))),
            "curve_edges": index[edges[ok]],
            "curve_tags": np.asarray(extras.get("curve_tags", np.zeros(len(edges))), dtype=np.intp)[ok],
            "curve_names": tuple(str(s) for s in extras.get("curve_names", ())),
        }
    values = extras.get("triangle_values")
    if values is None or len(values) != n_triangles:
        return {}
    names = extras.get("group_names", {})
    distinct = np.unique(values)
    if len(distinct) <= 1 and not any(dim == 1 and name not in _BOUNDARY_PREFIXES and
                                      not name.startswith(_BOUNDARY_PREFIXES)
                                      for (_, dim), name in names.items()):
        return {}
    # The rest of the domain is tag 0: the group named "domain", else the smallest value.
    domain_value = next((t for (t, dim), n in names.items() if dim == 2 and n == "domain"), int(distinct[0]))
    order = [domain_value] + [int(v) for v in distinct if v != domain_value]
    rank = {v: k for k, v in enumerate(order)}
    out: dict[str, Any] = {
        "triangle_tags": np.array([rank[int(v)] for v in values], dtype=np.intp),
        "region_names": tuple(names.get((v, 2), "domain" if k == 0 else f"region {k}")
                              for k, v in enumerate(order)),
    }
    lines, line_values = extras.get("line_cells"), extras.get("line_values")
    if lines is not None and line_values is not None:
        curve_groups = sorted({t for (t, dim), n in names.items()
                               if dim == 1 and not n.startswith(_BOUNDARY_PREFIXES)})
        sel = np.isin(line_values, curve_groups)
        edges = index[np.asarray(lines, dtype=np.intp)[sel]]
        ok = np.all(edges >= 0, axis=1)
        pos = {t: k for k, t in enumerate(curve_groups)}
        out["curve_edges"] = edges[ok]
        out["curve_tags"] = np.array([pos[int(v)] for v in line_values[sel][ok]], dtype=np.intp)
        out["curve_names"] = tuple(names[(t, 1)] for t in curve_groups)
    return out


#: Names :func:`boundary_names` gives boundary components: those 1-D groups are no curves.
_BOUNDARY_PREFIXES = ("outer boundary", "hole ")


def _named_groups(group_names: dict[int, tuple[str, int]], block_tags: list[int], domain_tag: int,
                  boundary: dict[int, str]) -> dict[str, tuple[int, int]]:
    """Name -> (tag, dimension) of every block, for formats without physical groups; empty for
    a mesh without regions or curves (its files stay as they were)."""
    if not group_names:
        return {}
    out = {"domain": (domain_tag, 2)}
    out.update({name: (t + 1, 1) for t, name in boundary.items()})
    out.update({name: (t, dim) for t, (name, dim) in group_names.items() if t in block_tags})
    return out
