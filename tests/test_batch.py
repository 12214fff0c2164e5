"""injmesh.batch: specs validated up front, resumable summaries, timeouts, interrupts, Dask.

Most tests run the batch in this process (``workers=0``); the acceptance test runs a real
``LocalCluster`` of two worker processes and checks that one worker gives the same files.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import injmesh
from injmesh.batch import (
    FAMILIES,
    SUMMARY_COLUMNS,
    BatchInterrupted,
    MeshSpec,
    SpecError,
    family_member,
    load_specs,
    mesh_many,
    parse_spec,
    random_specs,
    read_summary,
    size_for_nodes,
)
from injmesh.cases import CASES
from injmesh.cli import main
from injmesh.io import read
from injmesh.shapes import FAMILIES as SHAPE_FAMILIES

SRC = Path(injmesh.__file__).resolve().parents[1]
BOWTIE = {"type": "Polygon", "coordinates": [[[0, 0], [3, 0], [0, 2], [2, 2.5], [0, 0]]]}
SQUARE = "POLYGON ((0 0, 1 0, 1 1, 0 1))"


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_jsonl(path: Path, specs: list[dict]) -> Path:
    path.write_text("".join(json.dumps(s) + "\n" for s in specs))
    return path


def summary_rows(out: Path) -> list[dict[str, str]]:
    with (out / "summary.csv").open(newline="") as fh:
        reader = csv.DictReader(fh)
        assert tuple(reader.fieldnames or ()) == SUMMARY_COLUMNS
        return list(reader)


def mesh_files(out: Path) -> dict[str, str]:
    """Every mesh file in ``out`` with its hash (no summary, no specs, no temporary files)."""
    # A temporary file (``.name.tmp.npz``) may be renamed between the listing and the reading.
    return {p.name: sha256(p) for p in sorted(out.iterdir())
            if p.suffix in (".npz", ".msh", ".vtu", ".xdmf", ".mesh") and not p.name.startswith(".")}


def no_temporary_files(out: Path) -> bool:
    return not [p for p in out.iterdir() if p.name.startswith(".")]


# --- specs ------------------------------------------------------------------------------------


def test_every_invalid_line_is_reported_with_its_line_and_field(tmp_path):
    lines = [
        json.dumps({"name": "ok", "domain": "unit_disc"}),
        "",                                                                     # blank: skipped
        json.dumps({"name": "a", "domain": "unit_disc", "sizes": 0.1}),          # 3 unknown field
        json.dumps({"domain": "unit_disc"}),                                     # 4 no name
        json.dumps({"name": "b", "domain": SQUARE, "size": "0.1 + import(x)"}),  # 5 bad expression
        json.dumps({"name": "c", "domain": SQUARE, "size": 0.1, "nodes": 50}),   # 6 both
        json.dumps({"name": "d", "domain": "unit_dics"}),                        # 7 unknown case
        json.dumps({"name": "e", "domain": SQUARE, "size": 0.1, "format": "stl"}),  # 8 format
        json.dumps({"name": "OK", "domain": "unit_disc"}),                       # 9 duplicate name
        "{not json",                                                             # 10
        json.dumps([1, 2]),                                                      # 11 not an object
        json.dumps({"name": "../evil", "domain": "unit_disc"}),                  # 12 unsafe name
        json.dumps({"name": "f", "domain": SQUARE}),                             # 13 no size
        json.dumps({"name": "g", "domain": {"family": "blobs", "seed": 1}}),     # 14 family
        json.dumps({"name": "h", "domain": {"family": "plates", "seed": 1,
                                            "params": {"holes": 3}}}),           # 15 parameter
        json.dumps({"name": "i", "domain": SQUARE, "size": -0.1}),               # 16 negative
        json.dumps({"name": "j", "domain": SQUARE, "nodes": 2.5}),               # 17 nodes
        json.dumps({"name": "k", "domain": "shape.stl", "size": 0.1}),           # 18 extension
        json.dumps({"name": "l", "domain": {"type": "Point", "coordinates": [0, 0]},
                    "size": 0.1}),                                               # 19 GeoJSON type
    ]
    path = tmp_path / "specs.jsonl"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(SpecError) as info:
        load_specs(path)
    expected = {
        3: "sizes", 4: "name", 5: "size", 6: "nodes", 7: "domain", 8: "format", 9: "name",
        10: None, 11: None, 12: "name", 13: "size", 14: "domain", 15: "domain", 16: "size",
        17: "nodes", 18: "domain", 19: "domain",
    }
    found = {int(where.rsplit(" ", 1)[1]): field for where, field, _ in info.value.errors}
    assert found == expected
    message = str(info.value)
    assert message.splitlines()[0].startswith("specs.jsonl line 3, field 'sizes': unknown field")
    assert "(and 16 more invalid specs)" in message.splitlines()[0]
    assert "line 9, field 'name': 'OK' is already used by specs.jsonl line 1" in message
    assert "line 7, field 'domain': 'unit_dics' is no paper case" in message
    assert "line 15, field 'domain': family 'plates' has no parameter 'holes'" in message


JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-10, 10**7) | st.floats(allow_nan=False)
    | st.text(max_size=30) | st.sampled_from(["unit_disc", SQUARE, "x.geojson", "0.1", "plates"]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


@settings(max_examples=150, deadline=None)
@given(st.dictionaries(st.sampled_from(["name", "domain", "size", "nodes", "format", "extra"]), JSON)
       | JSON)
def test_validation_accepts_or_names_the_problem(obj):
    """Whatever JSON a line holds, validation returns a spec or raises SpecError, nothing else."""
    try:
        spec = parse_spec(obj, where="line 1")
    except SpecError as exc:
        assert str(exc).startswith("line 1")
    else:
        assert parse_spec(json.loads(spec.to_json())) == spec


def test_nothing_is_written_when_a_spec_is_invalid(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(SpecError, match=r"spec 2, field 'format'"):
        mesh_many([{"name": "a", "domain": "unit_disc"},
                   {"name": "b", "domain": "unit_disc", "format": "png"}], out, workers=0)
    assert not out.exists()


def test_spec_round_trip_and_defaults():
    spec = parse_spec({"name": "w", "domain": {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [0, 1]]]},
                       "size": "0.1 + 0.05*x", "format": "VTU"})
    assert spec.format == "vtu" and spec.filename == "w.vtu"
    again = parse_spec(json.loads(spec.to_json()))
    assert again == spec
    assert parse_spec({"name": "d", "domain": "unit_disc"}).format == "npz"
    assert parse_spec({"name": "d", "domain": "unit_disc", "size": 1}).size == 1.0
    with pytest.raises(SpecError, match="field 'domain': must be plain JSON"):
        parse_spec({"name": "d", "domain": {"type": "Polygon", "coordinates": [[[0, float("inf")]]]}})
    with pytest.raises(TypeError):
        mesh_many({"name": "d", "domain": "unit_disc"}, "out", workers=0)  # one dict, not a list


@pytest.mark.parametrize("name", ["unit_disc", "l_shape", "square_with_four_holes"])
def test_nodes_gives_about_that_many_nodes(name):
    domain = CASES[name].geometry
    for target in (150, 600):
        n = injmesh.generate(domain, size_for_nodes(domain, target)).n_points
        assert abs(n / target - 1) < 0.15, (target, n)


def test_random_specs_are_reproducible_and_extend():
    five = random_specs("plates", 5, seed=10, nodes=80)
    three = random_specs("plates", 3, seed=10, nodes=80)
    assert five[:3] == three
    assert [s.name for s in three] == ["plates-000010", "plates-000011", "plates-000012"]
    assert five[4].domain == {"family": "plates", "seed": 14}
    assert {"polygons", "plates", "airfoils"} <= set(FAMILIES)
    assert set(FAMILIES.values()) == set(SHAPE_FAMILIES)  # every shapes family, once
    # A member is the shape of injmesh.shapes with that seed, as a domain.
    domain, h = family_member("airfoils", 3)
    shape = SHAPE_FAMILIES["airfoil"](3)
    p = np.random.default_rng(0).uniform(-1, 2, (200, 2))
    assert np.array_equal(domain.sdf(p), shape.domain().sdf(p)) and h == shape.size
    with pytest.raises(SpecError, match="unknown family 'blobs'"):
        random_specs("blobs", 2)
    with pytest.raises(SpecError, match="count"):
        random_specs("plates", -1)


# --- running in this process -----------------------------------------------------------------


def small_batch(tmp_path: Path) -> list[dict]:
    (tmp_path / "shapes").mkdir(exist_ok=True)
    (tmp_path / "shapes" / "l.wkt").write_text("POLYGON ((0 0, 2 0, 2 1, 1 1, 1 2, 0 2))")
    (tmp_path / "shapes" / "h.txt").write_text("0.2 + 0.1 * x\n")
    return [
        {"name": "disc", "domain": "unit_disc", "size": 0.3},
        {"name": "square", "domain": SQUARE, "nodes": 40, "format": "msh"},
        {"name": "ell", "domain": "shapes/l.wkt", "size": "shapes/h.txt"},
        {"name": "missing", "domain": "shapes/none.geojson", "size": 0.2},
        {"name": "bowtie", "domain": BOWTIE, "size": 0.3},
    ]


def test_serial_batch_summary_and_resume(tmp_path):
    specs = write_jsonl(tmp_path / "specs.jsonl", small_batch(tmp_path))
    out = tmp_path / "out"
    events = []
    summary = mesh_many(specs, out, workers=0, callback=events.append)
    assert summary.counts == {"ok": 3, "failed": 2} and not summary.ok
    assert [e.step for e in events] == [1, 2, 3, 4, 5] and {e.total for e in events} == {5}
    assert sorted(mesh_files(out)) == ["disc.npz", "ell.npz", "square.msh"]
    rows = {r["name"]: r for r in summary_rows(out)}
    assert list(rows) == ["disc", "square", "ell", "missing", "bowtie"]  # the specs' order
    assert "no such file" in rows["missing"]["message"] and "none.geojson" in rows["missing"]["message"]
    assert "not simple" in rows["bowtie"]["message"]
    for name, file in (("disc", "disc.npz"), ("square", "square.msh"), ("ell", "ell.npz")):
        row = rows[name]
        mesh = read(out / file)
        assert row["status"] == "ok" and row["file"] == file and row["sha256"] == sha256(out / file)
        assert int(row["N"]) == mesh.n_points and int(row["triangles"]) == mesh.n_triangles
        assert float(row["q_min"]) == pytest.approx(mesh.quality().min())
        assert 0 <= float(row["size_error"]) < 0.5 and row["worker"] == "local"
    assert 25 <= int(rows["square"]["N"]) <= 55
    # The size file was used: h grows with x, so the right of the L has the longer edges.
    assert summary["ell"].N is not None and summary["ell"].N < injmesh.generate(
        injmesh.Polygon([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]]), 0.2).n_points

    # Rerun: nothing to do, nothing rewritten; the failed specs are not tried again.
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    again = mesh_many(specs, out, workers=0)
    assert again.computed == [] and len(again.reused) == 5
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != "summary.csv"} == {
        k: v for k, v in stamps.items() if k != "summary.csv"}
    assert [r.to_csv() for r in again.rows] == [r.to_csv() for r in summary.rows]

    # Fixing an input changes the spec's hash: only that spec is meshed again.
    (tmp_path / "shapes" / "none.geojson").write_text(json.dumps(
        {"type": "Polygon", "coordinates": [[[0, 0], [2, 0], [2, 1], [0, 1], [0, 0]]]}))
    (tmp_path / "shapes" / "h.txt").write_text("0.25")
    third = mesh_many(specs, out, workers=0)
    assert sorted(third.computed) == ["ell", "missing"]
    assert third["missing"].status == "ok" and third["ell"].sha256 != summary["ell"].sha256
    # retry_failed tries the failed spec again (and it fails again, the same way).
    fourth = mesh_many(specs, out, workers=0, retry_failed=True)
    assert fourth.computed == ["bowtie"] and fourth["bowtie"].message == summary["bowtie"].message
    assert no_temporary_files(out)


def test_timeouts_and_errors_are_tried_again_but_never_stop_the_batch(tmp_path):
    specs = [{"name": "slow", "domain": "unit_disc", "size": 0.002},  # 900 000 nodes
             {"name": "fast", "domain": "unit_disc", "size": 0.5}]
    out = tmp_path / "out"
    summary = mesh_many(specs, out, workers=0, timeout=1)
    assert summary["slow"].status == "timeout" and "stopped after 1 s" in summary["slow"].message
    assert summary["fast"].status == "ok" and sorted(mesh_files(out)) == ["fast.npz"]
    assert summary["slow"].seconds < 10  # stopped at the deadline, not at the end of meshing

    # A timeout (and an "error" row) is retried by the next run; a changed timeout is not a
    # changed spec.
    rows = summary_rows(out)
    rows[1]["status"] = "error"  # as if the worker had died
    with (out / "summary.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=SUMMARY_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    (out / "fast.npz").unlink()  # an "error" row has no file
    again = mesh_many(specs, out, workers=0, timeout=1)
    assert sorted(again.computed) == ["fast", "slow"] and again["fast"].status == "ok"


def test_interrupt_leaves_complete_files_and_a_summary_then_resumes(tmp_path):
    specs = [{"name": f"disc-{k}", "domain": "unit_disc", "size": 0.3 + 0.01 * k} for k in range(6)]
    out = tmp_path / "out"

    def stop_after_three(event):
        if event.step == 3:
            raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted) as info:
        mesh_many(specs, out, workers=0, callback=stop_after_three)
    summary = info.value.summary
    assert isinstance(info.value, KeyboardInterrupt) and summary.interrupted
    assert len(summary.rows) == 3 and summary.total == 6
    assert set(read_summary(out / "summary.csv")) == {"disc-0", "disc-1", "disc-2"}
    assert sorted(mesh_files(out)) == ["disc-0.npz", "disc-1.npz", "disc-2.npz"]
    assert no_temporary_files(out)
    resumed = mesh_many(specs, out, workers=0)
    assert resumed.computed == ["disc-3", "disc-4", "disc-5"] and resumed.ok


def test_arguments_are_checked(tmp_path):
    specs = [{"name": "d", "domain": "unit_disc"}]
    for kwargs, match in (({"timeout": 0}, "timeout"), ({"workers": -1}, "workers"),
                          ({"workers": 1, "client": "tcp://127.0.0.1:1"}, "not both"),
                          ({"client": 42}, "client")):
        with pytest.raises((ValueError, TypeError), match=match):
            mesh_many(specs, tmp_path / "out", **kwargs)


def test_import_injmesh_does_not_import_dask():
    code = ("import sys, injmesh, injmesh.batch, injmesh.cli; "
            "injmesh.cli.build_parser(); "
            "assert not {'dask', 'distributed'} & set(sys.modules), 'dask imported'")
    env = dict(os.environ, PYTHONPATH=str(SRC))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)


# --- the command line --------------------------------------------------------------------------


def test_cli_batch_in_process(tmp_path, capsys):
    specs = write_jsonl(tmp_path / "specs.jsonl", small_batch(tmp_path))
    out = tmp_path / "out"
    status = main(["batch", str(specs), "--out", str(out), "--workers", "0"])
    stdout, stderr = capsys.readouterr()
    assert status == 3  # finished, with failed specs
    assert "3 of 5 meshes" in stdout and "2 failed" in stdout
    assert "injmesh: bowtie: failed: " in stderr and "injmesh: missing: failed: " in stderr
    assert main(["batch", str(specs), "--out", str(out), "--workers", "0", "-q"]) == 3
    assert "0 meshed now" not in capsys.readouterr().out  # -q: quiet

    bad = write_jsonl(tmp_path / "bad.jsonl", [{"name": "x", "domain": "unit_disc", "size": "y**"},
                                               {"name": "y", "domain": "nowhere"}])
    assert main(["batch", str(bad), "--out", str(tmp_path / "o2"), "--workers", "0"]) == 1
    stderr = capsys.readouterr().err.splitlines()
    assert stderr[0].startswith("injmesh: error: bad.jsonl line 1, field 'size'")
    assert stderr[1].startswith("injmesh: error: bad.jsonl line 2, field 'domain'")
    assert not (tmp_path / "o2").exists()

    assert main(["batch", "--out", str(out)]) == 2                    # neither specs nor family
    assert main(["batch", str(specs), "--family", "plates", "--out", str(out)]) == 2
    assert main(["batch", str(specs), "--size", "0.1", "--out", str(out)]) == 2
    capsys.readouterr()


def test_cli_family_writes_its_specs(tmp_path, capsys):
    out = tmp_path / "star"
    argv = ["batch", "--family", "star", "--count", "2", "--seed", "5", "--nodes", "40",
            "--format", "vtu", "--out", str(out), "--workers", "0"]
    assert main(argv) == 0, capsys.readouterr().err
    assert sorted(mesh_files(out)) == ["star-000005.vtu", "star-000006.vtu"]
    written = load_specs(out / "specs.jsonl")
    assert written == random_specs("star", 2, 5, nodes=40, format="vtu")
    assert main(argv) == 0 and "0 meshed now, 2 up to date" in capsys.readouterr().out


@pytest.mark.parametrize(("signum", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_cli_signal_stops_cleanly(tmp_path, signum, status):
    specs = write_jsonl(tmp_path / "specs.jsonl",
                        [{"name": f"disc-{k}", "domain": "unit_disc", "size": 0.05 + 0.001 * k}
                         for k in range(40)])
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(SRC))
    # ``python -m injmesh batch ...`` with SIGINT handled as a terminal's Ctrl-C is: a test run
    # in the background of a non-interactive shell (nohup, ``cmd &``) starts its children with
    # SIGINT ignored, and they rightly keep ignoring it.
    run_cli = ("import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
               "sys.argv[0] = 'injmesh'; runpy.run_module('injmesh', run_name='__main__', alter_sys=True)")
    proc = subprocess.Popen([sys.executable, "-c", run_cli, "batch", str(specs), "--out", str(out),
                             "--workers", "0"], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (out.is_dir() and mesh_files(out)) and time.monotonic() < deadline:
            time.sleep(0.05)
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == status, err
    assert f"{signal.Signals(signum).name}: batch stopped" in err
    assert "rerun the same command to resume" in err
    rows = read_summary(out / "summary.csv")
    files = mesh_files(out)
    assert 1 <= len(rows) < 40 and sorted(files) == sorted(r.file for r in rows.values())
    assert all(rows[Path(name).stem].sha256 == digest for name, digest in files.items())
    assert no_temporary_files(out)


# --- on a Dask cluster -------------------------------------------------------------------------


def acceptance_specs(tmp_path: Path) -> Path:
    """40 specs of mixed inputs and formats, two of them bad."""
    shapes = tmp_path / "shapes"
    shapes.mkdir()
    (shapes / "plate.geojson").write_text(json.dumps({"type": "Feature", "geometry": {
        "type": "Polygon", "coordinates": [[[0, 0], [3, 0], [3, 1], [0, 1], [0, 0]],
                                           [[1, 0.3], [1.4, 0.3], [1.4, 0.7], [1, 0.7], [1, 0.3]]]}}))
    (shapes / "t.wkt").write_text("POLYGON ((0 0, 2 0, 1 1.5))")
    (shapes / "ring.poly").write_text(
        "8 2 0 0\n1 0 0\n2 2 0\n3 2 2\n4 0 2\n5 0.8 0.8\n6 1.2 0.8\n7 1.2 1.2\n8 0.8 1.2\n"
        "8 0\n1 1 2\n2 2 3\n3 3 4\n4 4 1\n5 5 6\n6 6 7\n7 7 8\n8 8 5\n1\n1 1 1\n")
    (shapes / "h.txt").write_text("0.15 + 0.05 * y")
    (shapes / "broken.geojson").write_bytes(b"\xff\xfe\x00 not text")
    formats = ["npz", "msh", "vtu", "xdmf", "mesh"]
    specs: list[dict] = []
    for case in sorted(CASES):
        specs.append({"name": f"case-{case}", "domain": case, "size": 0.25})
        specs.append({"name": f"nodes-{case}", "domain": case, "nodes": 60})
    specs.append({"name": "disc-own-size", "domain": "unit_disc"})
    specs.append({"name": "disc-case-size", "domain": "unit_disc", "size": "unit_disc"})
    for k in range(12):
        w = 1 + 0.25 * k
        specs.append({"name": f"wkt-{k}", "domain": f"POLYGON ((0 0, {w} 0, {w} 1, 0 1))",
                      "size": 0.2})
    for k in range(8):
        n = 5 + k
        ring = [[float(np.cos(2 * np.pi * j / n)), float(np.sin(2 * np.pi * j / n))] for j in range(n)]
        specs.append({"name": f"geojson-{n}gon", "domain": {"type": "Polygon",
                      "coordinates": [ring + ring[:1]]}, "size": "0.2 + 0.1 * hypot(x, y)"})
    specs += [
        {"name": "file-geojson", "domain": "shapes/plate.geojson", "size": 0.2},
        {"name": "file-wkt", "domain": "shapes/t.wkt", "size": "shapes/h.txt"},
        {"name": "file-poly", "domain": "shapes/ring.poly", "size": 0.25},
        {"name": "family-star", "domain": {"family": "star", "seed": 3}, "nodes": 40},
        {"name": "bad-unreadable", "domain": "shapes/broken.geojson", "size": 0.2},
        {"name": "bad-self-intersecting", "domain": BOWTIE, "size": 0.3},
    ]
    for k, spec in enumerate(specs):
        spec.setdefault("format", formats[k % len(formats)])
    assert len(specs) == 40
    return write_jsonl(tmp_path / "specs.jsonl", specs)


@pytest.fixture(scope="module")
def two_workers():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:
        with distributed.Client(cluster) as client:
            yield client


def test_acceptance_on_a_local_cluster(tmp_path, two_workers):
    distributed = pytest.importorskip("distributed")
    specs = acceptance_specs(tmp_path)
    out = tmp_path / "two"
    summary = mesh_many(specs, out, client=two_workers, timeout=120)

    # 38 meshes, 2 failed rows with their messages, the summary complete.
    assert summary.counts == {"ok": 38, "failed": 2}, [(r.name, r.message) for r in summary.rows]
    rows = {r["name"]: r for r in summary_rows(out)}
    assert len(rows) == 40 and list(rows) == [s.name for s in load_specs(specs)]
    assert "not a UTF-8 text file" in rows["bad-unreadable"]["message"]
    assert "broken.geojson" in rows["bad-unreadable"]["message"]
    assert "not simple" in rows["bad-self-intersecting"]["message"]
    files = mesh_files(out)
    assert len(files) == 38
    workers = set(two_workers.scheduler_info()["workers"])
    for row in rows.values():
        if row["status"] != "ok":
            assert row["file"] == "" and row["sha256"] == ""
            continue
        assert files[row["file"]] == row["sha256"] and row["worker"] in workers
        assert int(row["N"]) > 10 and 0 < float(row["q_min"]) <= float(row["q_mean"]) <= 1
        assert float(row["seconds"]) > 0 and len(row["spec_hash"]) == 64
    assert len({rows[n]["worker"] for n in rows if rows[n]["status"] == "ok"}) == 2  # both worked
    mesh = read(out / rows["file-poly"]["file"])
    assert len(set(mesh.boundary_tags.tolist())) == 2  # the .poly hole is kept

    # Rerun: no work at all.
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != "summary.csv"}
    rerun = mesh_many(specs, out, client=two_workers)
    assert rerun.computed == [] and len(rerun.reused) == 40
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.name != "summary.csv"} == stamps

    # Delete one output: only it is rebuilt, bit for bit.
    victim = rows["wkt-3"]["file"]
    (out / victim).unlink()
    rebuilt = mesh_many(specs, out, client=two_workers)
    assert rebuilt.computed == ["wkt-3"] and mesh_files(out) == files
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()
            if p.name not in ("summary.csv", victim)} == {k: v for k, v in stamps.items() if k != victim}

    # One worker, reached by its scheduler's address: the same files, bit for bit.
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as one:
        single = mesh_many(specs, tmp_path / "one", client=one.scheduler_address)
    assert single.counts == {"ok": 38, "failed": 2}
    assert mesh_files(tmp_path / "one") == files
    assert len({r.worker for r in single.rows if r.status == "ok"}) == 1
    assert no_temporary_files(out) and no_temporary_files(tmp_path / "one")


def test_mesh_spec_is_validated_again(tmp_path):
    with pytest.raises(SpecError, match="field 'nodes'"):
        mesh_many([MeshSpec("a", "unit_disc", size=0.2, nodes=30)], tmp_path, workers=0)


def test_cli_scheduler_and_progress_bar(tmp_path, two_workers, capsys):
    specs = write_jsonl(tmp_path / "specs.jsonl", [
        {"name": f"disc-{k}", "domain": "unit_disc", "size": 0.3 + 0.05 * k} for k in range(3)])
    address = two_workers.scheduler.address
    argv = ["batch", str(specs), "--out", str(tmp_path / "out"), "--scheduler", address, "--progress"]
    assert main(argv) == 0
    stdout, stderr = capsys.readouterr()
    assert "3 of 3 meshes" in stdout and "3 meshed now" in stdout
    assert "batch      [" in stderr and "] 3/3" in stderr  # the ProgressBar of `generate`
    assert len(two_workers.scheduler_info()["workers"]) == 2  # the cluster is left running
    assert main(["batch", str(specs), "--out", str(tmp_path / "o"), "--scheduler", address,
                 "--workers", "1"]) == 2


def test_an_interrupt_inside_a_compiled_kernel_stops_the_task(monkeypatch):
    """Ctrl-C or SIGTERM during a numba kernel reaches Python as ``SystemError: ... returned a
    result with an exception set``, caused by the KeyboardInterrupt: that is a stop, not a
    failed spec (seen once in CI as a spec recorded with status "error")."""
    import injmesh.batch as batch
    import injmesh.pipeline as pipeline

    def interrupted(*args, **kwargs):
        try:
            raise KeyboardInterrupt("SIGTERM")
        except KeyboardInterrupt as stop:
            raise SystemError("CPUDispatcher(adjacency) returned a result with an exception set") from stop

    monkeypatch.setattr(pipeline, "generate", interrupted)
    task = {"name": "disc", "hash": "x", "domain": ["case", "unit_disc"], "size": ["number", 0.2],
            "nodes": None, "format": "msh"}
    with pytest.raises(KeyboardInterrupt, match="SIGTERM"):
        batch.run_task(task)
    # Other errors are still recorded, not raised.
    monkeypatch.setattr(pipeline, "generate", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("boom")))
    assert batch.run_task(task)["status"] == "error"
