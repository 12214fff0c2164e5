"""injmesh.paper.run: a small, coarse regeneration of Section 5 into a temporary directory."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from injmesh.paper import run

KEYS = {"table", "case", "method", "h0", "seed", "N", "iterations", "q_min", "q_mean", "Er",
        "cpu_seconds"}
PNG = b"\x89PNG\r\n\x1a\n"


EVENTS: list = []


@pytest.fixture(scope="module")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, str]:
    """One L-shape case, two repeated runs, every DistMesh h0 three times coarser."""
    out = tmp_path_factory.mktemp("paper") / "out"
    EVENTS.clear()
    report = run(out, quick=True, cases=["l_shape"], runs=2, distmesh_h0_scale=3,
                 callback=EVENTS.append)
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


def test_progress_events_per_table_and_figure(small_run, tmp_path, capsys):
    events = EVENTS
    stages = list(dict.fromkeys(e.stage for e in events))
    assert stages == ["Table 1", "Table 2", "Table 3", "Table 4", "Table 9: l_shape", "Figures"]
    for stage in stages:
        outer = [e for e in events if e.stage == stage and "inner" not in e.info]
        steps = [e.step for e in outer]
        assert steps == sorted(steps) and steps[0] == 0 and steps[-1] == outer[-1].total
        assert all("item" in e.info for e in outer)
        assert sum("result" in e.info for e in outer) == outer[-1].total
    # The runs' own events come through, so a long run shows its iterations.
    inner = [e.info["inner"] for e in events if "inner" in e.info]
    assert {"distmesh", "smoothing"} <= {e.stage for e in inner}
    assert any(e.info.get("result") == "skipped (quick run)" for e in events)
    # The library never prints, with or without a callback.
    run(tmp_path / "quiet", quick=True, cases=[], runs=1, distmesh_h0_scale=4)
    run(tmp_path / "events", quick=True, cases=[], runs=1, distmesh_h0_scale=4,
        callback=lambda event: None)
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""


def test_report_states_h_and_explains_every_disagreement(small_run):
    _, _, text = small_run
    assert "**The h of our algorithm**" in text
    assert "Our algorithm: h = 0.03 + r / 7, r = distance to (1, 0)" in text
    assert "Our algorithm: h = 0.04 + 0.2 r" in text
    section = text.split("## Where the measurements disagree with the paper's printed figures")[1]
    lines = [line for line in section.splitlines() if line.startswith("- ")]
    assert lines, "this coarse run disagrees with the paper somewhere"
    for line in lines:
        head, _, reason = line.partition(". ")
        assert "measured" in head and "paper" in head and len(reason) > 30, line
    assert "only in part" not in text
    assert "**holds" in text or "**does not hold**" in text


def test_figures_1_to_3_have_one_colour_bar(small_run):
    """A colour bar is a vertical strip of many colours at the right edge of the figure."""
    out, _, _ = small_run
    from matplotlib.image import imread

    for name in ("fig01_initial_nodes.png", "fig02_initial_triangulation.png", "fig03_final_mesh.png"):
        image = imread(out / name)[:, :, :3]
        height, width = image.shape[:2]
        distinct = [len(np.unique(image[:, x].reshape(-1, 3), axis=0))
                    for x in range(int(0.9 * width), width)]
        assert max(distinct) > 100, f"{name}: no colour bar at the right edge"
        # One bar for both panels: the middle of the figure (between the panels) has none.
        middle = [len(np.unique(image[:, x].reshape(-1, 3), axis=0))
                  for x in range(int(0.44 * width), int(0.47 * width))]
        assert min(middle) < 100, f"{name}: a colour bar between the panels"
