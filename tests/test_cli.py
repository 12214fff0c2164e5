"""The injmesh command: main([...]) in-process, files and exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
import types
from pathlib import Path

import meshio
import numpy as np
import pytest

import injmesh
from injmesh import Polygon
from injmesh.cli import ProgressBar, main
from injmesh.progress import Progress

SHELL = [[0, 0], [4, 0], [4, 3], [0, 3], [0, 0]]
HOLE_A = [[1, 1], [1, 2], [2, 2], [2, 1], [1, 1]]
HOLE_B = [[2.5, 0.5], [3.5, 0.5], [3, 1.5], [2.5, 0.5]]
BOWTIE = [[0, 0], [3, 0], [0, 2], [2, 2.5], [0, 0]]
MESH_EXTENSIONS = [".msh", ".vtu", ".xdmf", ".mesh", ".npz"]


def polygon_file(tmp_path: Path, rings, name: str = "shape.geojson") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps({"type": "Feature", "properties": {},
                                "geometry": {"type": "Polygon", "coordinates": rings}}))
    return path


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture(scope="module")
def disc_msh(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("disc") / "disc.msh"
    assert main(["generate", "unit_disc", "--size", "0.2", "-o", str(path), "-q"]) == 0
    return path


def test_geojson_with_two_holes_to_msh(tmp_path, capsys):
    src = polygon_file(tmp_path, [SHELL, HOLE_A, HOLE_B])
    out = tmp_path / "shape.msh"
    status, stdout, err = run(capsys, "generate", src, "--size", "0.25", "-o", out)
    assert status == 0, err
    assert "wrote" in stdout and "triangles" in stdout

    m = meshio.read(out, file_format="gmsh")
    triangles = m.cells_dict["triangle"]
    assert len(triangles) > 100 and len(m.cells_dict["line"]) > 30
    names = {name: int(v[0]) for name, v in m.field_data.items()}
    assert set(names) == {"domain", "outer boundary", "hole 1", "hole 2"}
    line_tags = m.cell_data_dict["gmsh:physical"]["line"]
    assert set(line_tags.tolist()) == {names["outer boundary"], names["hole 1"], names["hole 2"]}
    assert len(set(names.values())) == 4
    # Every line of a group lies on that group's ring.
    lines = m.cells_dict["line"]
    rings = {"shell": Polygon(SHELL), "A": Polygon(HOLE_A), "B": Polygon(HOLE_B)}

    def rings_of(group: str) -> list[str]:
        nodes = m.points[lines[line_tags == names[group]].ravel(), :2]
        return [k for k, ring in rings.items() if np.abs(ring.sdf(nodes)).max() < 1e-9]

    assert rings_of("outer boundary") == ["shell"]
    assert sorted(rings_of("hole 1") + rings_of("hole 2")) == ["A", "B"]

    p = m.points[:, :2][triangles]
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    area = 0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum()
    assert area == pytest.approx(12 - 1 - 0.5, rel=0.01)


@pytest.mark.parametrize("ext", MESH_EXTENSIONS)
def test_every_output_format_round_trips(tmp_path, capsys, ext):
    out = tmp_path / f"ring{ext}"
    status, _, err = run(capsys, "generate", "circle_with_hole", "--size", "0.3", "-o", out, "-q")
    assert status == 0, err
    mesh = injmesh.read(out)
    assert mesh.n_triangles > 20
    assert sorted(set(mesh.boundary_tags.tolist())) == [0, 1]
    assert mesh.areas().sum() == pytest.approx(np.pi * (1 - 0.04), rel=0.03)
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_size_overrides_a_cases_own_size(tmp_path, capsys):
    own, coarse = tmp_path / "own.npz", tmp_path / "coarse.npz"
    assert run(capsys, "generate", "unit_disc", "-o", own)[0] == 0
    assert run(capsys, "generate", "unit_disc", "--size", "0.4", "-o", coarse)[0] == 0
    n_own, n_coarse = injmesh.read(own).n_points, injmesh.read(coarse).n_points
    assert n_coarse < 60 < n_own


def test_size_expression_and_graded_size(tmp_path, capsys):
    src = polygon_file(tmp_path, [SHELL])
    expr = tmp_path / "expr.npz"
    status, _, err = run(capsys, "generate", src, "--size", "0.1 + 0.1*hypot(x, y)", "-o", expr)
    assert status == 0, err
    graded = tmp_path / "graded.npz"
    status, _, err = run(capsys, "generate", src, "--size-min", "0.1", "--growth", "0.5",
                         "--size-max", "0.5", "-o", graded)
    assert status == 0, err
    m = injmesh.read(graded)
    e = m.edges
    lengths = np.hypot(*(m.points[e[:, 0]] - m.points[e[:, 1]]).T)
    on_boundary = np.isin(e, m.boundary_nodes).all(axis=1)
    assert lengths[on_boundary].mean() < 0.6 * lengths[~on_boundary].max()


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--size", "0.1", "--size-min", "0.1"], "either --size or"),
        (["--growth", "0.3"], "need --size-min"),
    ],
)
def test_conflicting_size_options(tmp_path, capsys, argv, match):
    out = tmp_path / "m.msh"
    status, _, err = run(capsys, "generate", "unit_disc", *argv, "-o", out)
    assert status == 1 and match in err and not out.exists()


def test_other_inputs(tmp_path, capsys):
    (tmp_path / "s.wkt").write_text("POLYGON ((0 0, 2 0, 2 1, 0 1), (0.5 0.25, 1 0.25, 1 0.75))")
    (tmp_path / "s.poly").write_text(
        "4 2 0 0\n0 0 0\n1 2 0\n2 2 1\n3 0 1\n4 0\n0 0 1\n1 1 2\n2 2 3\n3 3 0\n0\n")
    (tmp_path / "s.py").write_text(
        "import injmesh\nshape = injmesh.Rectangle((0, 0), (2, 1))\nshape_size = 0.25\n")
    for spec in (tmp_path / "s.wkt", tmp_path / "s.poly", f"{tmp_path / 's.py'}:shape",
                 "POLYGON ((0 0, 2 0, 2 1, 0 1))"):
        out = tmp_path / "out.npz"
        extra = [] if str(spec).endswith(":shape") else ["--size", "0.25"]
        status, _, err = run(capsys, "generate", spec, *extra, "-o", out)
        assert status == 0, (spec, err)
        out.unlink()


def test_input_without_size_needs_one(tmp_path, capsys):
    src = polygon_file(tmp_path, [SHELL])
    status, _, err = run(capsys, "generate", src, "-o", tmp_path / "m.msh")
    assert status == 1 and "--size" in err


def bad_cases(tmp_path: Path) -> dict[str, list[str]]:
    unreadable = tmp_path / "unreadable.geojson"
    unreadable.write_bytes(b"\x00\xff{not json")
    bowtie = polygon_file(tmp_path, [BOWTIE], "bowtie.geojson")
    good = polygon_file(tmp_path, [SHELL], "good.geojson")
    out = str(tmp_path / "out.msh")
    return {
        "missing file": ["generate", str(tmp_path / "missing.geojson"), "--size", "0.1", "-o", out],
        "unreadable file": ["generate", str(unreadable), "--size", "0.1", "-o", out],
        "self-intersecting": ["generate", str(bowtie), "--size", "0.1", "-o", out],
        "unknown case": ["generate", "no_such_case", "-o", out],
        "size zero": ["generate", str(good), "--size", "0", "-o", out],
        "size negative": ["generate", "unit_disc", "--size", "-0.1", "-o", out],
        "size import": ["generate", "unit_disc", "--size", "__import__('os')", "-o", out],
        "size attribute": ["generate", "unit_disc", "--size", "x.real", "-o", out],
        "unknown extension": ["generate", "unit_disc", "-o", str(tmp_path / "out.stl")],
        "missing directory": ["generate", "unit_disc", "-o", str(tmp_path / "no" / "out.msh")],
        "size-min zero": ["generate", "unit_disc", "--size-min", "0", "-o", out],
        "bad number": ["generate", "unit_disc", "--size-min", "abc", "-o", out],
        "missing output": ["generate", "unit_disc"],
        "quality missing": ["quality", str(tmp_path / "none.msh")],
        "quality garbage": ["quality", str(unreadable)],
        "plot extension": ["plot", str(good), "-o", str(tmp_path / "p.gif")],
        "no command": [],
        "unknown command": ["mesh", "unit_disc"],
    }


BAD_CASES = ("missing file", "unreadable file", "self-intersecting", "unknown case", "size zero",
             "size negative", "size import", "size attribute", "unknown extension",
             "missing directory", "size-min zero", "bad number", "missing output",
             "quality missing", "quality garbage", "plot extension", "no command",
             "unknown command")


def test_bad_cases_cover_the_list(tmp_path):
    assert tuple(bad_cases(tmp_path)) == BAD_CASES


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_input_one_line_nonzero_nothing_written(tmp_path, capsys, case):
    argv = bad_cases(tmp_path)[case]
    before = {p.name for p in tmp_path.rglob("*")}
    status, out, err = run(capsys, *argv)
    assert status != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("injmesh: error: ")
    assert "Traceback" not in err and out == ""
    assert {p.name for p in tmp_path.rglob("*")} == before


def test_error_messages_name_the_problem(tmp_path, capsys):
    cases = bad_cases(tmp_path)
    expect = {
        "missing file": "no such file",
        "self-intersecting": "not simple",
        "unknown case": "unknown case 'no_such_case'",
        "size zero": "positive",
        "size import": "'__import__' not allowed",
        "size attribute": "attribute access not allowed",
        "unknown extension": ".msh, .vtu, .xdmf, .mesh, .npz",
    }
    for case, text in expect.items():
        _, _, err = run(capsys, *cases[case])
        assert text in err, (case, err)


def test_failure_while_writing_leaves_nothing(tmp_path, capsys, monkeypatch):
    import injmesh.io as io_module

    def broken(meshio_, mesh, tmp, fmt):
        Path(tmp).write_text("half")
        raise OSError(28, "No space left on device", str(tmp))

    monkeypatch.setattr(io_module, "_write_meshio", broken)
    status, _, err = run(capsys, "generate", "unit_disc", "--size", "0.3", "-o", tmp_path / "m.msh")
    assert status == 1 and "No space left on device" in err
    assert list(tmp_path.iterdir()) == []


def test_unexpected_exception_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(injmesh, "generate", lambda *a, **k: 1 / 0)
    status, _, err = run(capsys, "generate", "unit_disc", "-o", tmp_path / "m.msh")
    assert status == 1 and err.count("\n") == 1 and "ZeroDivisionError" in err
    status, _, err = run(capsys, "generate", "unit_disc", "-o", tmp_path / "m.msh", "-v")
    assert "Traceback" in err
    assert list(tmp_path.iterdir()) == []


def test_version_and_help(capsys):
    status, out, _ = run(capsys, "--version")
    assert status == 0 and out.strip() == f"injmesh {injmesh.__version__}"
    status, out, _ = run(capsys, "--help")
    assert status == 0 and "generate" in out and "paper" in out
    status, out, _ = run(capsys, "generate", "--help")
    assert status == 0 and "--size-min" in out


def test_python_dash_m(tmp_path):
    out = subprocess.run([sys.executable, "-m", "injmesh", "--version"], capture_output=True,
                         text=True)
    assert out.returncode == 0 and out.stdout.startswith("injmesh ")
    bad = subprocess.run([sys.executable, "-m", "injmesh", "generate", "nope", "-o",
                          str(tmp_path / "x.msh")], capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stderr.count("\n") == 1


def test_quality_report(disc_msh, capsys):
    status, out, err = run(capsys, "quality", disc_msh)
    assert status == 0, err
    mesh = injmesh.read(disc_msh)
    assert f"nodes            {mesh.n_points}" in out
    assert f"triangles        {mesh.n_triangles}" in out
    assert f"{mesh.quality().min():.4f} / {mesh.quality().mean():.4f}" in out
    assert "degrees" in out and "histogram of q" in out and "outer boundary" in out
    bars = [line for line in out.splitlines() if " | " in line]
    assert sum(int(line.split()[-1]) for line in bars) == mesh.n_triangles
    assert "Er" not in out

    status, out, _ = run(capsys, "quality", disc_msh, "--size", "0.2")
    r = mesh.size_report(0.2)
    assert status == 0 and f"{r.er:.4g}" in out and f"{r.relative:.4g}" in out
    status, out, _ = run(capsys, "quality", disc_msh, "--size", "unit_disc")
    assert status == 0 and "relative Er" in out


@pytest.mark.parametrize("ext", [".png", ".svg"])
def test_plot(disc_msh, tmp_path, capsys, ext):
    out = tmp_path / f"disc{ext}"
    status, _, err = run(capsys, "plot", disc_msh, "-o", out)
    assert status == 0, err
    head = out.read_bytes()[:200]
    assert head.startswith(b"\x89PNG") if ext == ".png" else b"<svg" in out.read_bytes()[:2000]
    for extra in (["--color", "size-error", "--size", "0.2"], ["--color", "none", "--histogram",
                                                               "--title", "disc"]):
        status, _, err = run(capsys, "plot", disc_msh, "-o", out, *extra)
        assert status == 0, err
    assert [p.name for p in tmp_path.iterdir()] == [out.name]


def test_plot_size_error_needs_size(disc_msh, tmp_path, capsys):
    status, _, err = run(capsys, "plot", disc_msh, "-o", tmp_path / "p.png", "--color", "size-error")
    assert status == 1 and "--size" in err and not (tmp_path / "p.png").exists()


def test_progress_bar(tmp_path, capsys):
    status, _, err = run(capsys, "generate", "unit_disc", "--size", "0.2", "-o",
                         tmp_path / "m.msh", "--progress")
    assert status == 0
    for stage in ("boundary", "injection", "smoothing"):
        assert stage in err
    assert "\r" in err and "[" in err
    status, _, err = run(capsys, "generate", "unit_disc", "--size", "0.2", "-o",
                         tmp_path / "m.msh")
    assert err == ""  # not a terminal and no --progress: no bar


def test_progress_bar_rendering():
    import io

    stream = io.StringIO()
    bar = ProgressBar(stream, width=10, interval=3600)
    bar(Progress("smoothing", 1, 10, {"nodes": 5, "max_move": 0.5}))
    bar(Progress("smoothing", 4, 10, {"nodes": 5}))  # throttled, drawn on close
    bar(Progress("injection", 2, None, {}))
    bar.close()
    text = stream.getvalue()
    assert "[#.........] 1/10" in text and "[####......] 4/10" in text
    assert "injection  step 2" in text and text.endswith("\n")
    assert "nodes 5" in text and "max_move 0.5" in text


def test_paper_subcommand(tmp_path, capsys, monkeypatch):
    calls = []

    def fake_run(out_dir, *, quick, callback):
        calls.append((out_dir, quick))
        if callback is not None:
            callback(Progress("Table 1", 0, 1, {"item": "distmesh unit_disc h0=0.2 seed=1"}))
            callback(Progress("Table 1", 1, 1, {"item": "distmesh unit_disc h0=0.2 seed=1",
                                                "result": "N 11"}))
        out_dir.mkdir()
        (out_dir / "report.md").write_text("# report\n")
        return out_dir / "report.md"

    monkeypatch.setitem(sys.modules, "injmesh.paper", types.SimpleNamespace(run=fake_run))
    status, out, err = run(capsys, "paper", "--out", tmp_path / "res", "--quick")
    assert status == 0, err
    assert calls == [(tmp_path / "res", True)]
    assert "report.md" in out
    # Not a terminal: one plain line per step, no carriage returns.
    assert "Table 1 1/1: distmesh unit_disc h0=0.2 seed=1: N 11" in err and "\r" not in err
    status, out, err = run(capsys, "paper", "--out", tmp_path / "res2", "-q")
    assert status == 0 and out == "" and err == ""


def test_paper_progress_from_the_real_run(tmp_path, capsys, monkeypatch):
    """Progress of a real (tiny) paper run: a line per table and per figure, or bars."""
    import functools

    import injmesh.paper

    tiny = functools.partial(injmesh.paper.run, cases=[], runs=1, distmesh_h0_scale=4)
    monkeypatch.setattr(injmesh.paper, "run", tiny)
    status, out, err = run(capsys, "paper", "--out", tmp_path / "plain", "--quick")
    assert status == 0, err
    lines = err.splitlines()
    assert lines[0].startswith("injmesh paper: meshing")
    for group in ("Table 1 1/4:", "Table 2 1/1:", "Table 4 1/2:", "Figures 3/3:"):
        assert any(group in line for line in lines), group
    assert "skipped (quick run)" in err and "first look:" in out
    status, _, err = run(capsys, "paper", "--out", tmp_path / "bars", "--quick", "--progress")
    assert status == 0
    assert "\r" in err and "[####" in err and "done" in err
    bars = [line for line in err.split("\n") if line.strip()]
    assert any(b.rsplit("\r", 1)[-1].startswith("Table 2 ") for b in bars)


WKT_300 = "POLYGON ((" + ", ".join(
    f"{2 + 1.5 * np.cos(a):.6f} {1 + 1.5 * np.sin(a):.6f}"
    for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)
) + ", 3.500000 1.000000))"


def test_wkt_longer_than_a_file_name(tmp_path, capsys):
    assert len(WKT_300) > 300
    out = tmp_path / "wkt.npz"
    status, stdout, err = run(capsys, "generate", WKT_300, "--size", "0.4", "-o", out)
    assert status == 0, err
    mesh = injmesh.read(out)
    expected = injmesh.generate(WKT_300, 0.4)
    assert mesh.n_points == expected.n_points and np.allclose(mesh.points, expected.points)
    # GeoJSON text too, and an invalid long WKT is a WKT error, not "File name too long".
    geojson = json.dumps({"type": "Polygon", "coordinates": [SHELL]})
    status, _, err = run(capsys, "generate", geojson, "--size", "0.5", "-o", tmp_path / "g.npz")
    assert status == 0, err
    status, _, err = run(capsys, "generate", WKT_300.replace("))", ")"), "--size", "0.4", "-o",
                         tmp_path / "bad.npz")
    assert status == 1 and "WKT" in err and "too long" not in err


SLOW_WRITE = """
import pathlib, signal, sys, time
# A child started with SIGINT ignored (a test run in the background of a non-interactive
# shell: nohup, ``cmd &``) keeps ignoring it, as it should; a user's Ctrl-C is what is tested.
signal.signal(signal.SIGINT, signal.default_int_handler)
import injmesh.io as io

original = io._write_meshio


def slow(meshio, mesh, tmp, fmt):
    original(meshio, mesh, tmp, fmt)      # the temporary file exists, the target not yet
    pathlib.Path(sys.argv[1]).write_text("writing")
    time.sleep(120)


io._write_meshio = slow
from injmesh.cli import main
sys.exit(main(["generate", "unit_disc", "--size", "0.3", "-o", sys.argv[2]]))
"""


@pytest.mark.parametrize(("signame", "status"), [("SIGTERM", 143), ("SIGINT", 130)])
def test_signal_while_writing_leaves_nothing(tmp_path, signame, status):
    import os
    import signal
    import time

    out_dir = tmp_path / "out"
    out_dir.mkdir()
    marker = tmp_path / "marker"
    env = {**os.environ, "PYTHONPATH": str(Path(injmesh.__file__).parents[1])}
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_WRITE, str(marker), str(out_dir / "disc.msh")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        deadline = time.monotonic() + 120
        while not marker.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marker.exists(), proc.communicate(timeout=5)
        assert any(out_dir.iterdir()), "the temporary file should exist while writing"
        proc.send_signal(getattr(signal, signame))
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == status, err
    assert "no partial file left behind" in err and "Traceback" not in err
    assert list(out_dir.iterdir()) == [], "no partial or hidden temporary file"


def test_verbose_logs_to_stderr(tmp_path, capsys):
    status, _, err = run(capsys, "-v", "generate", "unit_disc", "--size", "0.3", "-o",
                         tmp_path / "m.msh")
    assert status == 0 and "injmesh.cli: input unit_disc" in err
    status, out, err = run(capsys, "generate", "unit_disc", "--size", "0.3", "-o",
                           tmp_path / "m.msh", "-q")
    assert status == 0 and out == "" and err == ""


def test_progress_bar_shows_compiling_on_the_stage_line():
    import io

    stream = io.StringIO()
    bar = ProgressBar(stream, width=10, interval=0)
    bar(Progress("smoothing", 1, 10, {}))
    bar(Progress("compiling", 3, None, {"kernel": "relink"}))
    bar(Progress("smoothing", 2, 10, {}))
    bar.close()
    text = stream.getvalue()
    assert "smoothing  compiling kernels, first run only: 3 (relink)" in text
    assert text.count("\n") == 1  # no line of its own: the stage's line is redrawn
