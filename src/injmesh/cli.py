"""The ``injmesh`` command line: ``generate``, ``quality``, ``plot`` and ``paper``.

Every failure is reported as one line ``injmesh: error: ...`` on stderr with a non-zero exit
status, never a traceback (``-v`` adds the traceback of unexpected errors), and no output file
is left behind: files are written atomically once everything else has succeeded.

Examples
--------
Shell usage::

    injmesh generate unit_disc -o disc.msh                  # a paper case with its own size
    injmesh generate shape.geojson --size 0.05 -o shape.vtu
    injmesh generate shape.wkt --size "0.02 + 0.1*hypot(x, y)" -o shape.msh
    injmesh generate shape.poly --size-min 0.02 --growth 0.3 --size-max 0.2 -o shape.xdmf
    injmesh generate shape.geojson --size depth.npz -o shape.msh   # a raster (x, y, values)
    injmesh generate shape.wkt --nodes 5000 --gradation 0.3 --feature-layers 3 -o shape.msh
    injmesh quality shape.msh --size 0.05
    injmesh plot shape.msh -o shape.png --color size-error --size 0.05
    injmesh paper --out paper-results --quick

From Python, ``main`` takes the arguments and returns the exit status:

>>> import contextlib, io
>>> with contextlib.redirect_stderr(io.StringIO()) as err:
...     status = main(["generate", "no_such_case", "-o", "out.msh"])
>>> status, err.getvalue().startswith("injmesh: error: unknown case 'no_such_case'")
(1, True)
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import signal
import sys
import threading
import time
import traceback
import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import IO, Any

import numpy as np

from .progress import Progress
from .sizing import SizeLike

PROG = "injmesh"
log = logging.getLogger(__name__)
PLOT_FORMATS = (".png", ".svg", ".pdf")
COMMANDS = ("generate", "quality", "plot", "paper", "batch")


class UsageError(Exception):
    """A command line that argparse rejected (exit status 2)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) arrived: unwind exactly as Ctrl-C does, so atomic writes clean up."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def _terminate_like_interrupt() -> Any:
    """While the command runs, SIGTERM and SIGHUP raise :class:`Terminated` (a KeyboardInterrupt).

    By default SIGTERM kills the process on the spot: a file being written stays behind as a
    hidden partial temporary file and nothing is said.  Raised as an exception instead, it unwinds
    through :func:`injmesh.io.atomic_path` (which removes the temporary file) to :func:`main`,
    which reports it.  Signal handlers can only be set from the main thread; elsewhere (main()
    called from a worker thread) the defaults stay.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    wanted = [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    previous = {}
    for sig in wanted:
        with contextlib.suppress(OSError, ValueError):
            previous[sig] = signal.signal(sig, _raise_terminated)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(sig, handler)


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing usage and exiting, so errors stay one line."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        raise UsageError(message)


# --- progress ---------------------------------------------------------------------------------


class ProgressBar:
    """A plain-text progress bar on a stream, fed by :class:`~injmesh.Progress` events.

    One line per stage (boundary, injection, smoothing), redrawn in place with ``\\r`` at most
    every ``interval`` seconds.  No dependency beyond the standard library.

    Parameters
    ----------
    stream : text stream
        Where to draw (stderr in the CLI).
    width : int
        Characters of the bar itself.
    interval : float
        Minimum seconds between redraws of the same stage.

    Examples
    --------
    >>> import io
    >>> from injmesh.progress import Progress
    >>> out = io.StringIO()
    >>> bar = ProgressBar(out, width=10, interval=0)
    >>> bar(Progress("smoothing", 5, 10, {"max_move": 0.01}))
    >>> bar.close()
    >>> "[#####.....]" in out.getvalue()
    True
    """

    def __init__(self, stream: IO[str], width: int = 30, interval: float = 0.1) -> None:
        self.stream = stream
        self.width = width
        self.interval = interval
        self._stage: str | None = None
        self._last = 0.0
        self._length = 0
        self._pending: Progress | None = None

    def __call__(self, event: Progress) -> None:
        now = time.monotonic()
        if event.stage == "compiling":
            # Kernels compiled on first use, in the middle of a stage: shown on that stage's
            # line (the next event of the stage redraws it), so no line per kernel.
            if now - self._last >= self.interval:
                self._last = now
                self._write(f"{self._stage or '':<10} compiling kernels, first run only: "
                            f"{event.step} ({event.info.get('kernel', '')})")
            return
        new_stage = event.stage != self._stage
        done = event.total is not None and event.step >= event.total
        if not (new_stage or done or now - self._last >= self.interval):
            self._pending = event
            return
        if new_stage and self._stage is not None:
            self._flush_pending()
            self.stream.write("\n")
            self._length = 0
        self._stage, self._last = event.stage, now
        self._pending = None
        self._draw(event)

    def _flush_pending(self) -> None:
        if self._pending is not None:
            self._draw(self._pending)
            self._pending = None

    def _draw(self, event: Progress) -> None:
        if event.total:
            frac = min(1.0, max(0.0, event.step / event.total))
            filled = int(round(frac * self.width))
            bar = f"[{'#' * filled}{'.' * (self.width - filled)}] {event.step}/{event.total}"
        else:
            bar = f"step {event.step}"
        extras = []
        for key in ("nodes", "max_move"):
            if key in event.info:
                value = event.info[key]
                extras.append(f"{key} {value:.3g}" if isinstance(value, float) else f"{key} {value}")
        self._write(f"{event.stage:<10} {bar}  {'  '.join(extras)}".rstrip())

    def _write(self, line: str) -> None:
        self.stream.write("\r" + line + " " * max(0, self._length - len(line)))
        self.stream.flush()
        self._length = len(line)

    def close(self) -> None:
        """Draw the last state and end the line."""
        if self._stage is not None:
            self._flush_pending()
            self.stream.write("\n")
            self.stream.flush()
            self._stage = None


class GroupProgress:
    """Progress of a long command made of groups of items (``injmesh paper``), on a stream.

    On a terminal each group (a table, a case, the figures) gets one bar, redrawn in place with
    ``\\r`` while its items run (with the running item's own stage and step) and left on screen
    when the group is done.  Elsewhere (a log file, a pipe) one plain line is written per item
    done, so the output stays readable.

    Parameters
    ----------
    stream : text stream
        Where to write (stderr in the CLI).
    bar : bool
        Draw bars redrawn in place (a terminal) rather than one line per step.
    width : int, optional
        Characters of each bar (default: 24, or 12 on a terminal narrower than 120 columns).
    interval : float
        Minimum seconds between redraws for events inside an item.

    A bar's line is cut to the terminal's width, since a line that wraps cannot be redrawn in
    place.

    Examples
    --------
    >>> import io
    >>> from injmesh.progress import Progress
    >>> out = io.StringIO()
    >>> lines = GroupProgress(out, bar=False)
    >>> lines(Progress("Table 1", 0, 2, {"item": "distmesh unit_disc h0=0.2"}))
    >>> lines(Progress("Table 1", 1, 2, {"item": "distmesh unit_disc h0=0.2", "result": "N 11"}))
    >>> out.getvalue().split("s ", 1)[1]
    'Table 1 1/2: distmesh unit_disc h0=0.2: N 11\\n'
    """

    def __init__(
        self, stream: IO[str], *, bar: bool, width: int | None = None, interval: float = 0.2
    ) -> None:
        import shutil

        self.stream = stream
        self.bar = bar
        self.columns = max(40, shutil.get_terminal_size((150, 24)).columns - 1)
        self.width = width if width is not None else (24 if self.columns >= 119 else 12)
        self.interval = interval
        self._start = time.monotonic()
        self._stage: str | None = None
        self._last = 0.0
        self._length = 0

    def __call__(self, event: Progress) -> None:
        now = time.monotonic()
        elapsed = f"{now - self._start:5.0f}s"
        info = event.info
        if not self.bar:
            if "result" in info:
                self.stream.write(f"{elapsed} {event.stage} {event.step}/{event.total}: "
                                  f"{info.get('item', '')}: {info['result']}\n")
                self.stream.flush()
            return
        inner = info.get("inner")
        if inner is not None and event.stage == self._stage and now - self._last < self.interval:
            return
        if event.stage != self._stage and self._stage is not None:
            self.stream.write("\n")
            self._length = 0
        self._stage, self._last = event.stage, now
        total = max(event.total or 1, 1)
        filled = int(round(self.width * min(event.step, total) / total))
        detail = str(info.get("item", ""))
        if inner is not None:
            steps = f"{inner.step}/{inner.total}" if inner.total else f"{inner.step}"
            detail += f" ({inner.stage} {steps})"
        elif "result" in info and event.step >= total:
            detail = "done"
        line = (f"{event.stage:<32.32} [{'#' * filled}{'.' * (self.width - filled)}] "
                f"{event.step}/{event.total} {elapsed}  {detail}")
        line = line[: self.columns]
        self.stream.write("\r" + line + " " * max(0, self._length - len(line)))
        self.stream.flush()
        self._length = len(line)

    def close(self) -> None:
        """End the last bar's line."""
        if self.bar and self._stage is not None:
            self.stream.write("\n")
            self.stream.flush()
            self._stage = None


# --- arguments --------------------------------------------------------------------------------


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {value}")
    return value


def _whole(text: str) -> int:
    value = _positive_int(text)
    if value < 3:
        raise argparse.ArgumentTypeError(f"must be 3 or more, got {value}")
    return value


def _rate(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (off) or positive, got {text!r}")
    return value


def _layers(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (off) or positive, got {text!r}")
    return value


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``injmesh`` command."""
    from . import __version__

    def add_noise(p: argparse.ArgumentParser, default: Any) -> None:
        group = p.add_mutually_exclusive_group()
        group.add_argument("-v", "--verbose", action="count", default=default,
                           help="log what the mesher does (-vv for more)")
        group.add_argument("-q", "--quiet", action="store_true", default=default,
                           help="print only errors and results")

    # On the subcommands too, without defaults, so "injmesh -v generate" keeps its -v.
    common = _Parser(add_help=False)
    add_noise(common, argparse.SUPPRESS)
    parser = _Parser(
        prog=PROG,
        description="2-D triangular meshes by Advancing Node Injection (an improved DistMesh).",
    )
    parser.set_defaults(verbose=0, quiet=False)
    add_noise(parser, argparse.SUPPRESS)
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    gen = sub.add_parser(
        "generate", parents=[common], help="mesh a domain and write the mesh",
        description="Mesh a domain and write the mesh; the format follows the extension of -o "
        "(.msh, .vtu, .xdmf, .mesh, .npz).",
    )
    gen.add_argument("input", metavar="INPUT",
                     help="a paper case (unit_disc, l_shape, ...), a .geojson/.json, .wkt or "
                     ".poly file, FILE.py:NAME, or POLYGON ((...)) text")
    gen.add_argument("-o", "--output", required=True, metavar="OUTPUT", help="the mesh file")
    gen.add_argument("--size", metavar="SIZE",
                     help="target edge length: a number, an expression in x and y "
                     "(\"0.02 + 0.1*hypot(x, y)\"), a case name, or a .npz file: a raster "
                     "(arrays x, y, values with values[j, i] at (x[i], y[j]); bilinear) or "
                     "samples (arrays points (n, 2), values; linear); overrides a case's own size")
    gen.add_argument("--size-min", type=_number, metavar="H",
                     help="graded size: H on the boundary, growing inward")
    gen.add_argument("--growth", type=_number, default=None, metavar="G",
                     help="graded size: increase of h per unit distance from the boundary "
                     "(default 0.2)")
    gen.add_argument("--size-max", type=_number, metavar="H", help="graded size: cap on h")
    gen.add_argument("--nodes", type=_whole, metavar="N",
                     help="about N nodes (within 3 %%): the size given (or a uniform one) is "
                     "scaled to meet the count")
    gen.add_argument("--gradation", type=_rate, metavar="RATE",
                     help="limit the growth of h to RATE per unit length, |grad h| <= RATE, so "
                     "a size that jumps still gives well-shaped triangles (default 0.2; 0: off)")
    gen.add_argument("--feature-layers", type=_layers, metavar="K",
                     help="at least K elements across thin parts (channels, necks, spikes): h "
                     "<= local thickness / K (default 2; 0: off)")
    gen.add_argument("--min-feature", type=_rate, metavar="W",
                     help="cut the outline where it comes within W of itself and drop the smaller "
                     "part beyond (a lobe on a neck, a pocket behind a narrow mouth), with a "
                     "warning naming each place (default 1 %% of the smallest h, and only parts "
                     "smaller than h^2; 0: off)")
    gen.add_argument("--method", choices=("injection", "distmesh"), default="injection",
                     help="the paper's algorithm (default) or the original DistMesh")
    gen.add_argument("--regions", metavar="FILE",
                     help="a GeoJSON file of regions (Polygon features, named by their 'region' or "
                          "'name' property) and curves (LineString features); an input "
                          "FeatureCollection's own 'region' and LineString features count too")
    gen.add_argument("--max-iterations", type=_positive_int, metavar="N",
                     help="cap on smoothing iterations")
    gen.add_argument("--progress", action="store_true",
                     help="draw a progress bar on stderr even when it is not a terminal")

    qual = sub.add_parser("quality", parents=[common], help="report on a mesh file",
                          description="Print nodes, triangles, element quality q (Eq. 5.1), "
                          "angles and, with --size, the size error Er.")
    qual.add_argument("mesh", metavar="MESH", help="a mesh file (.msh, .vtu, .xdmf, .mesh, .npz)")
    qual.add_argument("--size", metavar="SIZE",
                      help="the intended h (number, expression or case name) for Er")

    plot = sub.add_parser("plot", parents=[common], help="draw a mesh to an image",
                          description="Draw a mesh to a .png, .svg or .pdf (no display needed).")
    plot.add_argument("mesh", metavar="MESH", help="a mesh file")
    plot.add_argument("-o", "--output", required=True, metavar="FILE",
                      help="the image (.png, .svg, .pdf)")
    plot.add_argument("--color", choices=("quality", "size-error", "none"), default="quality",
                      help="fill triangles by quality q, colour edges by lc/h - 1, or neither")
    plot.add_argument("--size", metavar="SIZE", help="the intended h, for --color size-error")
    plot.add_argument("--histogram", action="store_true",
                      help="add the histogram of q beside the mesh (as in the paper)")
    plot.add_argument("--title", help="a title for the picture")
    plot.add_argument("--show", action="store_true", help="also open a window")

    paper = sub.add_parser("paper", parents=[common],
                           help="reproduce the paper's tables and figures",
                           description="Mesh the paper's six cases with both algorithms and "
                           "write tables and figures.")
    paper.add_argument("--out", default="paper-results", metavar="DIR",
                       help="output directory (default: paper-results)")
    paper.add_argument("--quick", action="store_true",
                       help="leave out the slowest DistMesh runs (h0 = 0.003 and 0.0086) and "
                       "repeat Tables 2-3 three times instead of six: about a minute instead "
                       "of several")
    paper.add_argument("--progress", action="store_true",
                       help="draw progress bars on stderr even when it is not a terminal (by "
                       "default: bars on a terminal, one line per run otherwise; -q: none)")
    _add_batch_parser(sub, common)
    return parser


# --- commands ---------------------------------------------------------------------------------


def _size(text: str) -> Any:
    """``--size``: a case name (its h), a ``.npz`` size file, a number or an expression."""
    from .cases import CASES
    from .inputs import parse_size

    if text.strip() in CASES:
        return CASES[text.strip()].size
    if text.strip().lower().endswith(".npz"):
        return load_size_file(text.strip())
    return parse_size(text)


def load_size_file(path: str | Path) -> Any:
    """A size field from a NumPy ``.npz`` file: a raster or scattered samples.

    Parameters
    ----------
    path : str or Path
        An ``.npz`` archive (``numpy.savez``) holding either ``x`` (nx,), ``y`` (ny,) and
        ``values`` (ny, nx), with ``values[j, i]`` the size at ``(x[i], y[j])`` (a
        :class:`~injmesh.sizing.GriddedSize`, bilinear), or ``points`` (n, 2) and ``values``
        (n,) (a :class:`~injmesh.sizing.ScatteredSize`, linear between the samples).

    Returns
    -------
    GriddedSize or ScatteredSize

    Raises
    ------
    FileNotFoundError
        No such file.
    SizeError
        Not an ``.npz`` archive, a missing array, NaN, an axis that is not strictly monotone, a
        size that is not positive: the message starts with the file's name.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> path = os.path.join(tempfile.mkdtemp(), "h.npz")
    >>> np.savez(path, x=[0.0, 1.0], y=[0.0, 1.0], values=[[0.1, 0.2], [0.1, 0.2]])
    >>> load_size_file(path)
    <GriddedSize: 2 x 2 grid on [0, 1] x [0, 1], h in [0.1, 0.2]>
    """
    import pickle
    import zipfile

    from .sizing import GriddedSize, ScatteredSize, SizeError

    where = f"size file {str(path)!r}"
    if not Path(path).is_file():
        raise FileNotFoundError(f"{where} does not exist")
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {name: archive[name] for name in archive.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, pickle.UnpicklingError) as exc:
        raise SizeError(f"{where}: not a NumPy .npz archive of plain arrays ({exc})") from None
    if not isinstance(arrays, dict) or not arrays:
        raise SizeError(f"{where}: holds no arrays")
    kinds = {"gridded": ("x", "y", "values"), "scattered": ("points", "values")}
    kind = "scattered" if "points" in arrays else "gridded"
    missing = [k for k in kinds[kind] if k not in arrays]
    if missing:
        raise SizeError(
            f"{where}: no array {', '.join(repr(k) for k in missing)} (a raster needs x, y and "
            f"values, scattered samples points and values; it holds {', '.join(sorted(arrays))})"
        )
    try:
        if kind == "scattered":
            return ScatteredSize(arrays["points"], arrays["values"])
        return GriddedSize(arrays["x"], arrays["y"], arrays["values"])
    except SizeError as exc:
        raise SizeError(f"{where}: {exc}") from None


def _check_target(path: Path) -> None:
    if not path.parent.is_dir():
        raise FileNotFoundError(f"output directory {str(path.parent)!r} does not exist")
    if path.is_dir():
        raise IsADirectoryError(f"output {str(path)!r} is a directory")


def _generate(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    import injmesh

    from .inputs import graded_size, load_domain
    from .io import format_for, write

    output = Path(args.output)
    format_for(output)  # an unknown extension fails before any meshing
    _check_target(output)
    graded = args.size_min is not None or args.growth is not None or args.size_max is not None
    if graded and args.size is not None:
        raise ValueError("give either --size or --size-min/--growth/--size-max, not both")
    if graded and args.size_min is None:
        raise ValueError("--growth and --size-max need --size-min")
    if graded and args.nodes is not None:
        raise ValueError("--nodes sets the scale of h, --size-min fixes it: give --size (the "
                         "shape of h) with --nodes")
    tuned = [f for f, v in (("--nodes", args.nodes), ("--gradation", args.gradation),
                            ("--feature-layers", args.feature_layers),
                            ("--min-feature", args.min_feature)) if v is not None]
    if args.method == "distmesh" and tuned:
        raise ValueError(f"{', '.join(tuned)} apply to --method injection only")

    spec, regions, curves = _constraints(args.input, args.regions)
    source = load_domain(spec)
    if spec != args.input:
        source = replace(source, name=Path(args.input).stem if len(args.input) < 256 else "geojson")
    if regions or curves:
        log.info("%d regions (%s), %d curves (%s)", len(regions), ", ".join(regions), len(curves),
                 ", ".join(curves))
    log.info("input %s: %r", source.name, source.domain)
    size: SizeLike
    if graded:
        growth = 0.2 if args.growth is None else args.growth
        size = graded_size(source.domain, args.size_min, growth, args.size_max)
    elif args.size is not None:
        size = _size(args.size)
    elif source.size is not None:
        size = source.size
    elif args.nodes is not None:
        size = 1.0  # uniform: --nodes sets its scale
    else:
        raise ValueError(
            f"{args.input!r} brings no size: give --size (a number or an expression in x and y) "
            "or --size-min"
        )

    show_bar = args.progress or (err.isatty() and not args.quiet)
    bar = ProgressBar(err) if show_bar else None
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            options: dict[str, Any] = {}
            if args.gradation is not None:
                options["gradation"] = args.gradation or None  # 0: off
            if args.feature_layers is not None:
                options["feature_layers"] = args.feature_layers or None
            if args.min_feature is not None:
                options["min_feature"] = args.min_feature
            mesh = injmesh.generate(
                source.domain, size, method=args.method, max_iterations=args.max_iterations,
                target_nodes=args.nodes, callback=bar, regions=regions or None,
                curves=curves or None, **options,
            )
        finally:
            if bar is not None:
                bar.close()
    log.info("%r; %s", mesh, ", ".join(f"{k} {v:.3f} s" for k, v in mesh.stats.seconds.items()))
    write(mesh, output)
    seconds = time.perf_counter() - start
    if not args.quiet:
        for w in caught:
            err.write(f"{PROG}: warning: {str(w.message).splitlines()[0]}\n")
        q = mesh.quality()
        target = ("" if args.nodes is None
                  else f" ({100 * (mesh.n_points / args.nodes - 1):+.1f} % of --nodes)")
        out.write(
            f"wrote {output}: {mesh.n_points} nodes{target}, {mesh.n_triangles} triangles, "
            f"q min {q.min():.4f}, q mean {q.mean():.4f}, {mesh.stats.iterations} iterations, "
            f"{seconds:.2f} s\n"
        )
    return 0


def _constraints(spec: str, regions_file: str | None) -> tuple[str, dict[str, Any], dict[str, Any]]:
    """The domain spec and the regions and curves of ``generate``'s input and ``--regions``.

    A GeoJSON FeatureCollection input (file or text) keeps its plain features as the domain;
    its features with a ``region`` property become regions and its LineStrings curves
    (:func:`injmesh.geometry.regions.split_geojson`).  In a ``--regions`` file every polygon is
    a region, named by its ``region`` or ``name`` property, else ``region k``.
    """
    from .geometry.regions import split_geojson

    regions: dict[str, Any] = {}
    curves: dict[str, Any] = {}
    obj = _geojson_object(spec)
    if obj is not None:
        rest, regions, curves = split_geojson(obj)
        if regions or curves:
            if rest is None:
                raise ValueError(f"{_short(spec)} has regions or curves but no domain feature "
                                 "(a feature without a 'region' property)")
            spec = json.dumps(rest)
    if regions_file is not None:
        path = Path(regions_file)
        if not path.is_file():
            raise FileNotFoundError(f"no such regions file: {regions_file!r}")
        try:
            obj = json.loads(path.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ValueError(f"cannot read {regions_file!r} as GeoJSON: {exc}") from None
        if isinstance(obj, dict) and obj.get("type") == "FeatureCollection":
            for k, f in enumerate(obj.get("features") or [], start=1):
                if isinstance(f, dict):
                    props = f.setdefault("properties", {}) or {}
                    f["properties"] = props
                    kind = (f.get("geometry") or {}).get("type")
                    if kind not in ("LineString", "MultiLineString") and props.get("region") is None:
                        props["region"] = props.get("name") or f"region {k}"
        elif isinstance(obj, dict) and obj.get("type") in ("Polygon", "MultiPolygon"):
            obj = {"type": "FeatureCollection", "features": [
                {"type": "Feature", "properties": {"region": path.stem}, "geometry": obj}]}
        else:
            raise ValueError(f"{regions_file!r} must hold a GeoJSON FeatureCollection or Polygon")
        _, more_regions, more_curves = split_geojson(obj)
        for name, r in more_regions.items():
            if name in regions:
                raise ValueError(f"region {name!r} is given twice")
            regions[name] = r
        for name, c in more_curves.items():
            if name in curves:
                raise ValueError(f"curve {name!r} is given twice")
            curves[name] = c
    return spec, regions, curves


def _geojson_object(spec: str) -> Any:
    """The parsed JSON of a GeoJSON input (text or a .geojson/.json file), else None."""
    text = spec.strip()
    if not text.startswith("{"):
        path = Path(text)
        if path.suffix.lower() not in (".geojson", ".json") or len(text) > 4096 or not path.is_file():
            return None
        text = path.read_text(encoding="utf-8", errors="replace")
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return None  # load_domain reports it


def _short(spec: str) -> str:
    return repr(spec if len(spec) < 60 else spec[:57] + "...")


def _text_histogram(q: np.ndarray, width: int = 40) -> list[str]:
    lo = min(math.floor(float(q.min()) * 20) / 20, 0.95)
    edges = np.linspace(lo, 1.0, int(round((1.0 - lo) * 20)) + 1)
    counts, _ = np.histogram(q, bins=edges)
    top = max(int(counts.max()), 1)
    rows = []
    for a, b, c in zip(edges[:-1], edges[1:], counts, strict=True):
        bar = "#" * int(math.ceil(width * c / top)) if c else ""
        rows.append(f"    {a:.2f}-{b:.2f} | {bar:<{width}} {c}")
    return rows


def _quality(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .io import boundary_names, read

    size = _size(args.size) if args.size is not None else None
    mesh = read(args.mesh)
    q = mesh.quality()
    angles = mesh.angles()
    names = boundary_names(mesh.boundary_edges, mesh.boundary_tags, mesh.points)
    lines = [
        f"{args.mesh}",
        f"  nodes            {mesh.n_points}",
        f"  triangles        {mesh.n_triangles}",
        f"  area             {mesh.areas().sum():.6g}",
        f"  q min / mean     {q.min():.4f} / {q.mean():.4f}",
        f"  angles           {angles.min():.1f} to {angles.max():.1f} degrees",
        f"  boundary         {len(mesh.boundary_edges)} edges in {len(names)} "
        f"loop{'s' if len(names) != 1 else ''} ({', '.join(names.values())})",
    ]
    if size is not None:
        r = mesh.size_report(size)
        lines += [
            f"  Er               {r.er:.4g}   (mean |lc - h|, lengths)",
            f"  relative Er      {r.relative:.4g}   (mean |lc/h - 1|)",
            f"  lc/h             {r.ratio_min:.3f} to {r.ratio_max:.3f}, mean {r.ratio_mean:.3f}",
        ]
    lines.append("  histogram of q")
    lines += _text_histogram(q)
    out.write("\n".join(lines) + "\n")
    return 0


def _plot(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .io import atomic_path, read
    from .plot import MISSING_MATPLOTLIB, plot_mesh, plot_mesh_with_histogram

    output = Path(args.output)
    ext = output.suffix.lower()
    if ext not in PLOT_FORMATS:
        raise ValueError(
            f"cannot tell the image format of {str(output)!r}; use {', '.join(PLOT_FORMATS)}"
        )
    _check_target(output)
    if args.color == "size-error" and args.size is None:
        raise ValueError("--color size-error needs --size")
    size = _size(args.size) if args.size is not None else None
    color = None if args.color == "none" else args.color
    mesh = read(args.mesh)
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise ImportError(MISSING_MATPLOTLIB) from exc

    if args.show:
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(11, 4.8) if args.histogram else (7, 6), layout="constrained")
    else:  # no pyplot: no backend, no display, no global state
        fig = Figure(figsize=(11, 4.8) if args.histogram else (7, 6), layout="constrained")
    if args.histogram:
        plot_mesh_with_histogram(mesh, title=args.title, figure=fig, color=color, size=size)
    else:
        ax = fig.add_subplot()
        plot_mesh(mesh, ax=ax, color=color, size=size)
        if args.title:
            ax.set_title(args.title)
    with atomic_path(output) as tmp:
        fig.savefig(tmp, format=ext[1:], dpi=150)
    if not args.quiet:
        out.write(f"wrote {output}\n")
    if args.show:
        plt.show()
    return 0


def _paper(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .paper import run

    progress = None
    if not args.quiet:
        progress = GroupProgress(err, bar=args.progress or err.isatty())
        err.write(f"{PROG} paper: meshing the paper's six domains with both algorithms"
                  f"{' (quick run)' if args.quick else ''} into {args.out}/\n")
        err.flush()
    try:
        result = run(Path(args.out), quick=args.quick, callback=progress)
    finally:
        if progress is not None:
            progress.close()
    if not args.quiet:
        out.write(f"wrote {result}\n")
        figures = sorted(result.parent.glob("fig0[13]_*.png"))
        if figures:
            out.write("first look: " + ", ".join(str(f) for f in figures) + "\n")
    return 0


def _add_batch_parser(sub: Any, common: argparse.ArgumentParser) -> None:
    from .batch import DEFAULT_FORMAT, FAMILIES, FORMATS

    batch = sub.add_parser(
        "batch", parents=[common], help="mesh many specs on a Dask cluster",
        description="Mesh every spec of a JSON Lines file (or a random family) into DIR, on an "
        "embedded Dask LocalCluster or on the cluster at --scheduler; DIR/summary.csv records "
        "each spec, and rerunning the same command skips what is done (see injmesh.batch).",
        epilog="exit status: 0 every mesh written; 1 invalid specs or another error; 3 the batch "
        "finished but some specs failed or timed out (see the summary); 130 interrupted by "
        "Ctrl-C, 143 by SIGTERM (rerun to resume).",
    )
    batch.add_argument("specs", nargs="?", metavar="SPECS.jsonl",
                       help="one spec a line: {\"name\": ..., \"domain\": ..., \"size\": ... | "
                       "\"nodes\": ..., \"format\": ...}")
    batch.add_argument("--out", required=True, metavar="DIR", help="output directory")
    batch.add_argument("--family", choices=list(FAMILIES), metavar="FAMILY",
                       help=f"instead of SPECS: random shapes of this family ({', '.join(FAMILIES)}; "
                       "see injmesh.shapes), written to DIR/specs.jsonl")
    batch.add_argument("--count", type=_positive_int, default=100, metavar="N",
                       help="with --family: number of shapes (default 100)")
    batch.add_argument("--seed", type=_positive_int, default=0, metavar="S",
                       help="with --family: seed (default 0)")
    batch.add_argument("--size", metavar="SIZE",
                       help="with --family: h for every shape (number or expression in x, y)")
    batch.add_argument("--nodes", type=_positive_int, metavar="N",
                       help="with --family: about N nodes per mesh")
    batch.add_argument("--format", choices=sorted(FORMATS), default=None,
                       help=f"format of specs that give none (default {DEFAULT_FORMAT})")
    batch.add_argument("--workers", type=_positive_int, metavar="N",
                       help="worker processes of the embedded cluster (default: one per core; "
                       "0: no Dask, one mesh after another in this process)")
    batch.add_argument("--scheduler", metavar="ADDRESS",
                       help="use the running Dask cluster at this scheduler (tcp://HOST:PORT)")
    batch.add_argument("--timeout", type=_number, metavar="S", help="seconds allowed per spec")
    batch.add_argument("--retry-failed", action="store_true",
                       help="mesh again the specs that failed in an earlier run")
    batch.add_argument("--progress", action="store_true",
                       help="draw a progress bar on stderr even when it is not a terminal")


def _batch(args: argparse.Namespace, out: IO[str], err: IO[str]) -> int:
    from .batch import (
        DEFAULT_FORMAT,
        BatchInterrupted,
        SpecError,
        load_specs,
        mesh_many,
        random_specs,
        write_specs,
    )

    if (args.specs is None) == (args.family is None):
        raise UsageError("give either SPECS.jsonl or --family")
    if args.family is None and (args.size is not None or args.nodes is not None):
        raise UsageError("--size and --nodes go with --family; a specs file gives them per spec")
    if args.workers is not None and args.scheduler is not None:
        raise UsageError("give either --workers (a new local cluster) or --scheduler, not both")
    if args.timeout is not None and args.timeout <= 0:
        raise UsageError(f"--timeout must be positive, got {args.timeout:g}")
    out_dir = Path(args.out)
    fmt = args.format or DEFAULT_FORMAT
    try:
        if args.family is not None:
            size: Any = args.size
            try:
                size = float(size)
            except (TypeError, ValueError):  # None, or an expression in x and y
                pass
            specs = random_specs(args.family, args.count, args.seed, size=size, nodes=args.nodes,
                                 format=fmt)
            out_dir.mkdir(parents=True, exist_ok=True)
            write_specs(specs, out_dir / "specs.jsonl")  # the record of what was meshed
        else:
            specs = load_specs(args.specs, default_format=fmt)
    except SpecError as exc:
        err.write("".join(f"{PROG}: error: {line.strip()}\n" for line in str(exc).splitlines()[1:]
                          or [str(exc)]))
        return 1

    show_bar = args.progress or (err.isatty() and not args.quiet)
    bar = ProgressBar(err) if show_bar else None
    try:
        summary = mesh_many(specs, out_dir, client=args.scheduler, workers=args.workers,
                            timeout=args.timeout, retry_failed=args.retry_failed, callback=bar)
    except BatchInterrupted as exc:
        if bar is not None:
            bar.close()
        s = exc.summary
        err.write(f"{PROG}: {exc.signal_name}: batch stopped; {len(s.rows)} of {s.total} specs "
                  f"finished, recorded in {s.path}; rerun the same command to resume\n")
        return 128 + int(getattr(signal, exc.signal_name, signal.SIGINT))
    finally:
        if bar is not None:
            bar.close()
    counts = summary.counts
    bad = [r for r in summary.rows if r.status != "ok"]
    if not args.quiet:
        for row in bad[:20]:
            err.write(f"{PROG}: {row.name}: {row.status}: {row.message}\n")
        if len(bad) > 20:
            err.write(f"{PROG}: ... and {len(bad) - 20} more; see {summary.path}\n")
        others = ", ".join(f"{n} {s}" for s, n in counts.items() if s != "ok")
        out.write(f"{counts.get('ok', 0)} of {summary.total} meshes in {out_dir}"
                  f"{f' ({others})' if others else ''}; {len(summary.computed)} meshed now, "
                  f"{len(summary.reused)} up to date; {summary.seconds:.1f} s; "
                  f"summary {summary.path}\n")
    return 0 if summary.ok else 3


_COMMANDS: dict[str, Callable[[argparse.Namespace, IO[str], IO[str]], int]] = {
    "generate": _generate,
    "quality": _quality,
    "plot": _plot,
    "paper": _paper,
    "batch": _batch,
}


def _message(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror and exc.filename is not None:
        return f"{exc.strerror}: {exc.filename!s}"
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``injmesh`` command with ``argv`` (default: ``sys.argv[1:]``).

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments, without the program name.

    Returns
    -------
    int
        0 on success, 1 on an error, 2 on a malformed command line, 130 when interrupted
        (Ctrl-C), 143 on SIGTERM (129 on SIGHUP); an interrupted command leaves no partial file.
    """
    out, err = sys.stdout, sys.stderr
    args_list = list(sys.argv[1:] if argv is None else argv)
    verbose = 0
    handler: logging.Handler | None = None
    logger = logging.getLogger("injmesh")
    try:
        parser = build_parser()
        args = parser.parse_args(args_list)
        verbose = getattr(args, "verbose", 0)
        if args.command is None:
            raise UsageError(f"choose a command: {', '.join(COMMANDS)} (see {PROG} --help)")
        if verbose:
            handler = logging.StreamHandler(err)
            handler.setFormatter(logging.Formatter("%(name)s: %(message)s"))
            logger.addHandler(handler)
            logger.setLevel(logging.DEBUG if verbose > 1 else logging.INFO)
        with _terminate_like_interrupt():
            return _COMMANDS[args.command](args, out, err)
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except UsageError as exc:
        err.write(f"{PROG}: error: {exc}\n")
        return 2
    except Terminated as exc:
        name = signal.Signals(exc.signum).name
        err.write(f"\n{PROG}: terminated by {name}; no partial file left behind\n")
        return 128 + exc.signum
    except KeyboardInterrupt:
        err.write(f"\n{PROG}: interrupted; no partial file left behind\n")
        return 130
    except (ValueError, TypeError, OSError, ImportError, RuntimeError, MemoryError) as exc:
        err.write(f"{PROG}: error: {_message(exc)}\n")
        if verbose:
            traceback.print_exc(file=err)
        return 1
    except Exception as exc:  # a bug: still one line, with the traceback under -v
        err.write(f"{PROG}: error: internal error: {type(exc).__name__}: {_message(exc)}"
                  f"{'' if verbose else ' (run with -v for details)'}\n")
        if verbose:
            traceback.print_exc(file=err)
        return 1
    finally:
        if handler is not None:
            logger.removeHandler(handler)
            logger.setLevel(logging.NOTSET)
