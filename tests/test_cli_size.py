"""The size-field flags of ``injmesh generate``: --size FILE.npz, --nodes, --gradation,
--feature-layers, through the CLI entry point."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import injmesh
from injmesh.cli import main

SQUARE = "POLYGON ((0 0, 1 0, 1 1, 0 1))"
CHANNEL = "POLYGON ((0 0, 2 0, 2 0.06, 0 0.06))"


def run(capsys, *argv) -> tuple[int, str, str]:
    status = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


def analytic(p: np.ndarray) -> np.ndarray:
    return 0.03 + 0.1 * np.hypot(p[:, 0] - 0.2, p[:, 1] - 0.3)


def raster(path: Path, spacing: float = 0.02) -> Path:
    x = np.arange(-spacing, 1 + 2 * spacing, spacing)
    y = np.arange(-spacing, 1 + 2 * spacing, spacing)
    X, Y = np.meshgrid(x, y)
    values = analytic(np.stack([X.ravel(), Y.ravel()], axis=1)).reshape(X.shape)
    np.savez(path, x=x, y=y, values=values)
    return path


def test_gridded_size_file_is_followed(tmp_path, capsys):
    out = tmp_path / "m.npz"
    status, stdout, err = run(capsys, "generate", SQUARE, "--size", raster(tmp_path / "h.npz"),
                              "-o", out)
    assert status == 0, err
    mesh = injmesh.read(out)
    assert mesh.quality().min() > 0.7
    # Follows the analytic h the raster samples, as well as the analytic h itself does.
    direct = injmesh.generate(injmesh.Rectangle((0, 0), (1, 1)), analytic)
    assert mesh.size_report(analytic).relative < direct.size_report(analytic).relative + 0.02
    assert stdout.startswith(f"wrote {out}")


def test_scattered_size_file_is_followed(tmp_path, capsys):
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.05, 1.05, (3000, 2))
    np.savez(tmp_path / "s.npz", points=points, values=analytic(points))
    out = tmp_path / "m.npz"
    status, _, err = run(capsys, "generate", SQUARE, "--size", tmp_path / "s.npz", "-o", out)
    assert status == 0, err
    mesh = injmesh.read(out)
    direct = injmesh.generate(injmesh.Rectangle((0, 0), (1, 1)), analytic)
    assert mesh.size_report(analytic).relative < direct.size_report(analytic).relative + 0.02


def test_size_file_for_quality(tmp_path, capsys):
    h = raster(tmp_path / "h.npz")
    out = tmp_path / "m.msh"
    assert run(capsys, "generate", SQUARE, "--size", h, "-o", out)[0] == 0
    status, stdout, _ = run(capsys, "quality", out, "--size", h)
    assert status == 0 and "relative Er" in stdout


def _bad_files(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    x, y = np.linspace(0, 1, 5), np.linspace(0, 1, 4)
    good = np.full((4, 5), 0.1)
    nan = good.copy()
    nan[2, 3] = np.nan
    files = {
        "missing key": ({"x": x, "y": y, "v": good}, "no array 'values'"),
        "NaN": ({"x": x, "y": y, "values": nan}, "values[2, 3] = nan"),
        "non-monotone axis": ({"x": [0, 0.5, 0.4, 0.8, 1], "y": y, "values": good},
                              "x must be strictly monotone"),
        "transposed": ({"x": x, "y": y, "values": good.T}, "looks transposed"),
        "negative sample": ({"points": [[0, 0], [1, 0], [0, 1]], "values": [0.1, -0.1, 0.1]},
                            "positive"),
    }
    out = {}
    for name, (arrays, match) in files.items():
        path = tmp_path / f"{name.replace(' ', '_')}.npz"
        np.savez(path, **arrays)
        out[name] = (path, match)
    junk = tmp_path / "junk.npz"
    junk.write_text("not a zip file")
    out["not npz"] = (junk, "not a NumPy .npz archive")
    out["missing file"] = (tmp_path / "absent.npz", "does not exist")
    return out


@pytest.mark.parametrize("case", ["missing key", "NaN", "non-monotone axis", "transposed",
                                  "negative sample", "not npz", "missing file"])
def test_bad_size_file_is_one_line_naming_the_file(tmp_path, capsys, case):
    path, match = _bad_files(tmp_path)[case]
    out = tmp_path / "m.msh"
    status, stdout, err = run(capsys, "generate", SQUARE, "--size", path, "-o", out)
    assert status == 1 and stdout == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("injmesh: error: size file "), err
    assert path.name in err and match in err, err
    assert not out.exists()


def test_nodes_with_and_without_a_size(tmp_path, capsys):
    out = tmp_path / "m.npz"
    status, stdout, err = run(capsys, "generate", SQUARE, "--nodes", 300, "-o", out)
    assert status == 0, err
    assert abs(injmesh.read(out).n_points / 300 - 1) <= 0.03
    assert "% of --nodes" in stdout
    # A case keeps the shape of its own h; a given --size likewise.
    status, _, err = run(capsys, "generate", "l_shape", "--nodes", 300, "-o", out)
    assert status == 0 and abs(injmesh.read(out).n_points / 300 - 1) <= 0.03, err
    status, _, err = run(capsys, "generate", SQUARE, "--size", "0.02 + 0.2*x", "--nodes", 300,
                         "-o", out)
    graded = injmesh.read(out)
    assert status == 0 and abs(graded.n_points / 300 - 1) <= 0.03, err
    assert (graded.points[:, 0] < 0.5).sum() > 2 * (graded.points[:, 0] >= 0.5).sum()


def test_feature_layers_and_gradation(tmp_path, capsys):
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    assert run(capsys, "generate", CHANNEL, "--size", 0.2, "--feature-layers", 4, "-o", a)[0] == 0
    assert run(capsys, "generate", CHANNEL, "--size", 0.2, "-o", b)[0] == 0
    # Four elements across the 0.06 channel rather than the default two: more nodes.
    assert injmesh.read(a).n_points > 1.5 * injmesh.read(b).n_points
    jump = "0.05 + 0.2*min(1, max(0, 1e6*(x - 0.5)))"  # 5:1 across x = 0.5
    off, on = tmp_path / "off.npz", tmp_path / "on.npz"
    status, _, err = run(capsys, "generate", SQUARE, "--size", jump, "--gradation", 0, "-o", off)
    assert status == 0, err
    status, _, err = run(capsys, "generate", SQUARE, "--size", jump, "--gradation", 0.2, "-o", on)
    assert status == 0, err
    assert injmesh.read(on).quality().min() >= 0.7 > injmesh.read(off).quality().min()


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--nodes", "2"], "must be 3 or more"),
        (["--nodes", "many"], "expected a whole number"),
        (["--gradation", "-0.1"], "0 (off) or positive"),
        (["--feature-layers", "nan"], "finite"),
        (["--size-min", "0.1", "--nodes", "100"], "--nodes sets the scale of h"),
        (["--method", "distmesh", "--gradation", "0.3"], "--gradation apply to --method injection"),
    ],
)
def test_bad_size_flags(tmp_path, capsys, argv, match):
    out = tmp_path / "m.msh"
    status, _, err = run(capsys, "generate", "unit_disc", *argv, "-o", out)
    assert status in (1, 2) and match in err and not out.exists(), err
    assert len(err.strip().splitlines()) == 1


def test_help_describes_the_size_flags(capsys):
    status, text, _ = run(capsys, "generate", "--help")
    assert status == 0
    for flag in ("--nodes", "--gradation", "--feature-layers", ".npz"):
        assert flag in text


def test_min_feature(tmp_path, capsys):
    # The unit square with a small square lobe on a neck 1e-4 wide (h/1000).
    lobe = ("POLYGON ((0 0, 1 0, 1 0.5, 1.1 0.5, 1.1 0.475, 1.15 0.475, 1.15 0.525, 1.1 0.525, "
            "1.1 0.5001, 1 0.5001, 1 1, 0 1, 0 0))")
    out = tmp_path / "m.npz"
    status, _, err = run(capsys, "generate", lobe, "--size", 0.1, "-o", out)
    assert status == 0 and "(1, 0.50005)" in err, err  # dropped by default, and said where
    assert injmesh.read(out).points[:, 0].max() <= 1 + 1e-9
    # A lobe larger than h^2 on the same neck: refused by default, naming the place; dropped
    # when --min-feature is given.
    big = ("POLYGON ((0 0, 1 0, 1 0.5, 1.1 0.5, 1.1 0.4, 1.3 0.4, 1.3 0.6, 1.1 0.6, 1.1 0.5001, "
           "1 0.5001, 1 1, 0 1, 0 0))")
    status, _, err = run(capsys, "generate", big, "--size", 0.1, "-o", out)
    assert status in (1, 2) and "(1, 0.50005)" in err and "min_feature" in err, err
    status, _, err = run(capsys, "generate", big, "--size", 0.1, "--min-feature", 1e-3, "-o", out)
    assert status == 0 and "(1, 0.50005)" in err, err
    assert injmesh.read(out).points[:, 0].max() <= 1 + 1e-9
    status, _, err = run(capsys, "generate", lobe, "--min-feature", 1e-3, "--method", "distmesh",
                         "--size", 0.1, "-o", out)
    assert status in (1, 2) and "--min-feature" in err, err
