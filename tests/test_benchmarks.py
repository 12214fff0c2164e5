"""The benchmark scripts still run against the library.

Some of them call the library's private stages (``robustness.py`` and ``setup_stages.py`` call
``pipeline._clean``).  Each runs a few of its own cases here, in-process, so a changed private
signature shows in the suite and not only when someone reruns a study: ``robustness.py`` once
counted its 135 cleaned cases as crashed after ``_clean`` gained a return value.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))


@pytest.mark.parametrize("seed", [0, 3, 5, 770])  # a neck, a walk, near-duplicates (cleaned), a spike
def test_robustness_cases_are_valid(seed: int) -> None:
    import robustness

    res = robustness.run_case(robustness.Case(seed=seed))
    assert res.status == "valid", (seed, res.family, res.status, res.detail)
    assert res.lost == 0


def test_robustness_checker_passes_its_self_test() -> None:
    import robustness

    robustness.selftest()


def test_fuzz_cases_mesh_or_are_refused_by_name() -> None:
    import fuzz_csg

    for seed in range(4):
        res = fuzz_csg.run_case(seed)
        assert res["status"] in ("valid", "refused"), res


def test_setup_stages_runs(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import setup_stages

    monkeypatch.setattr(sys, "argv", ["setup_stages.py", "--sizes", "1e3", "--repeat", "1", "--skip-cases"])
    setup_stages.main()
    assert "unit square 1e3" in capsys.readouterr().out


def test_regions_runs(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    import regions

    monkeypatch.setattr(sys, "argv", ["regions.py", "--repeat", "1", "--large-nodes", "2e3", "4e3"])
    regions.main()
    out = capsys.readouterr().out
    # The six cases with an inclusion and as a hole, again without the feature size, a table
    # per size, then the ratios by size.
    assert out.count("| l_shape |") == 2 and "N (hole)" in out and "feature_layers=None" in out
    assert out.count("Time with / without regions") == 2
    assert "| 2e+03 |" in out and "| 4e+03 |" in out
