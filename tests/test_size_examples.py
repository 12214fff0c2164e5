"""The size-field examples in examples/ run and show what they claim (small settings)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

pytest.importorskip("matplotlib")


def load(name: str):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_size_from_raster(tmp_path, capsys):
    figures = load("size_from_raster").main(tmp_path)
    assert (tmp_path / "size_from_raster.png").stat().st_size > 10_000
    assert (tmp_path / "bay_size.npz").exists()
    assert figures["q_min"] > 0.7
    # The raster reproduces the formula it samples: size error within 0.02 of the formula's.
    assert abs(figures["size error (raster)"] - figures["size error (formula)"]) < 0.02


def test_size_scattered(tmp_path, capsys):
    figures = load("size_scattered").main(tmp_path)
    assert (tmp_path / "size_scattered.png").stat().st_size > 10_000
    assert figures["q_min"] > 0.65 and figures["size error (samples)"] < 0.1


def test_gradation(tmp_path, capsys):
    figures = load("gradation").main(tmp_path)
    assert (tmp_path / "gradation.png").stat().st_size > 10_000
    assert figures["q_min after"] >= 0.7 > 0.2 > figures["q_min before"]


def test_target_nodes(tmp_path, capsys):
    pairs = load("target_nodes").main(tmp_path, targets=(300,))
    assert (tmp_path / "target_nodes.png").stat().st_size > 10_000
    assert all(abs(got / n - 1) <= 0.03 for n, got in pairs)
