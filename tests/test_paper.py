"""injmesh.paper.run: a small, coarse regeneration of Section 5 into a temporary directory."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from injmesh.paper import run

KEYS = {"table", "case", "method", "h0", "seed", "N", "iterations", "q_min", "q_mean", "Er",
        "cpu_seconds"}
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:
    """One L-shape case, two repeated runs, every DistMesh h0 three times coarser."""
    out = tmp_path_factory.mktemp("paper") / "out"
    report = run(out, quick=True, cases=["l_shape"], runs=2, distmesh_h0_scale=3)
    return out, report, report.read_text()


def test_writes_only_into_out_dir(small_run):
    out, report, _ = small_run
    assert report == out / "report.md"
    names = {p.name for p in out.iterdir()}
    assert {"report.md", "results.json"} <= names
    for fig in ("fig01_initial_nodes.png", "fig02_initial_triangulation.png", "fig03_final_mesh.png",
                "fig12_l_shape_distmesh.png", "fig13_l_shape_injection.png"):
        assert fig in names
        assert (out / fig).read_bytes()[:8] == PNG
    assert not any(n.startswith(("fig04", "fig05", "fig10")) for n in names), "only l_shape ran"


def test_results_json_rows(small_run):
    out, _, _ = small_run
    rows = json.loads((out / "results.json").read_text())
    assert all(set(r) == KEYS for r in rows)
    assert {r["table"] for r in rows} == {1, 2, 3, 4, 9}
    assert all(r["method"] in ("injection", "distmesh") for r in rows)
    ours = [r for r in rows if r["method"] == "injection"]
    assert all(r["h0"] is None and r["seed"] is None for r in ours)
    t3 = [r for r in ours if r["table"] == 3]
    assert len(t3) == 2 and len({(r["N"], r["iterations"], r["q_min"]) for r in t3}) == 1
    t2 = [r for r in rows if r["table"] == 2]
    assert [r["seed"] for r in t2] == [1, 2] and all(r["h0"] == pytest.approx(0.03) for r in t2)
    skipped = [r for r in rows if r["h0"] == pytest.approx(0.009)]
    assert skipped and all(r["N"] is None and r["cpu_seconds"] is None for r in skipped)
    done = [r for r in rows if r["N"] is not None]
    assert all(r["N"] > 2 and 0 < r["q_min"] <= r["q_mean"] <= 1 and r["Er"] > 0 for r in done)
    assert all(r["cpu_seconds"] >= 0 for r in done)
    l_shape = {r["method"]: r for r in rows if r["table"] == 9}
    assert l_shape["distmesh"]["h0"] == pytest.approx(3 * 0.061)


def test_report_content(small_run):
    _, _, text = small_run
    for title in ("Table 1", "Table 2", "Table 3", "Table 4", "Table 9: L-shaped domain"):
        assert f"## {title}" in text
    assert "## Table 5" not in text
    assert "Quick run" in text and "skipped (quick)" in text
    assert "multiplied by 3" in text
    assert "Bit-identical meshes over the 2 runs" in text and "**yes**" in text
    assert "17222" in text and "0.7285" in text, "the paper's printed figures are shown"
    for claim in ("Fewer nodes", "Fewer smoothing iterations", "Less CPU time",
                  "Smaller edge-length error", "q_min preserved", "Robustness"):
        assert claim in text
    assert "disagree with the paper" in text


def test_progress_bar_only_when_asked(tmp_path, capsys):
    run(tmp_path / "quiet", quick=True, cases=[], runs=1, distmesh_h0_scale=4)
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
    run(tmp_path / "loud", quick=True, progress=True, cases=[], runs=1, distmesh_h0_scale=4)
    captured = capsys.readouterr()
    assert "done" in captured.err and captured.out == ""


def test_bad_arguments(tmp_path):
    with pytest.raises(ValueError, match="unknown case"):
        run(tmp_path, cases=["nope"])
    with pytest.raises(ValueError, match="Tables 5-9"):
        run(tmp_path, cases=["unit_disc"])
    with pytest.raises(ValueError, match="runs"):
        run(tmp_path, runs=0)
    with pytest.raises(ValueError, match="scale"):
        run(tmp_path, distmesh_h0_scale=0)
