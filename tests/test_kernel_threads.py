"""The Euler step's kernels run on several threads (kernels/threads.py): the same numbers as the
serial loop, for any number of chunks; safe across fork and with concurrent callers."""

from __future__ import annotations

import multiprocessing
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from injmesh import Circle, Rectangle, generate
from injmesh.kernels import smooth as k
from injmesh.kernels import threads
from injmesh.smoothing import DT
from injmesh.triangulation import delaunay


@pytest.fixture
def many_chunks(monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    """Chunks of 8 nodes and up to ``n`` threads (the machine may have only 2 cores)."""
    def use(n: int) -> None:
        monkeypatch.setattr(threads, "MIN_CHUNK", 8)
        monkeypatch.setattr(threads, "threads", lambda: n)
    return use


def test_chunks_cover_the_range_in_order(many_chunks) -> None:  # type: ignore[no-untyped-def]
    many_chunks(5)
    parts = threads.chunks(103)
    assert len(parts) == min(threads.PER_THREAD * 5, 103 // 8)
    assert parts[0][0] == 0 and parts[-1][1] == 103
    assert all(a[1] == b[0] and a[0] < a[1] for a, b in zip(parts, parts[1:], strict=False))
    assert threads.chunks(20) == [(0, 10), (10, 20)]  # at least MIN_CHUNK nodes per chunk
    assert threads.each(103, lambda lo, hi: hi - lo) == [hi - lo for lo, hi in parts]


def test_limit_caps_this_thread_only() -> None:
    seen = []
    with threads.limit(1):
        assert threads.threads() == 1
        other = threading.Thread(target=lambda: seen.append(threads.threads()))
        other.start()
        other.join()
    assert seen[0] == threads.threads()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(40, 400), chunks=st.integers(2, 7),
       deep_share=st.floats(0.0, 1.0))
def test_threaded_step_equals_serial_bit_for_bit(seed: int, n: int, chunks: int,
                                                 deep_share: float) -> None:
    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    indptr, adj, eid, bars = k.adjacency(n, delaunay(p).astype(np.int32), 0)
    ld = 0.05 + 0.1 * rng.random(len(bars))
    hbar = k.mean_bar_size(indptr, eid, ld)
    moving = np.sort(rng.choice(n, size=n - 3, replace=False))
    deep = rng.random(n) < deep_share
    out = []
    for split in (False, True):
        with pytest.MonkeyPatch.context() as mp:
            if split:
                mp.setattr(threads, "MIN_CHUNK", 8)
                mp.setattr(threads, "threads", lambda: chunks)
            damp, total = np.ones(n), np.zeros((n, 2))
            k.threaded_stable_scale(p, moving, indptr, adj, eid, ld, DT * hbar, 1.0, damp)
            k.threaded_bar_forces(p, moving, indptr, adj, eid, ld, 0.0, total, damp)
            q = p.copy()
            cand, near = np.full((len(moving), 2), np.nan), np.full(len(moving), -1)
            res = k.threaded_advance(q, moving, total, hbar, DT, 0.05, deep, p, cand, near, 0.01)
            c = res[0]
            out.append((damp, total, q, cand[:c].copy(), near[:c].copy(), res))
    (d0, t0, q0, c0, n0, r0), (d1, t1, q1, c1, n1, r1) = out
    for a, b in ((d0, d1), (t0, t1), (q0, q1), (c0, c1), (n0, n1)):
        assert a.tobytes() == b.tobytes()
    assert r0 == r1
    if r0[0] < len(moving):  # the deep nodes moved, and the largest move's node is one of them
        assert deep[r0[2]]


_SIZE = 0.012


def _graded(p: np.ndarray) -> np.ndarray:
    return _SIZE * (1 + 4 * np.hypot(p[:, 0], p[:, 1]))


def _digest(mesh) -> bytes:  # type: ignore[no-untyped-def]
    return mesh.points.tobytes() + mesh.triangles.tobytes()


def _child(queue) -> None:  # type: ignore[no-untyped-def]
    threads.MIN_CHUNK = 64
    queue.put(_digest(generate(Circle((0, 0), 1), _graded)))


def test_threads_after_fork_and_with_concurrent_callers(monkeypatch: pytest.MonkeyPatch) -> None:
    """A forked child runs its own pool (the parent's threads do not exist there), and two
    threads meshing at once share the pool: every mesh equals the serial one."""
    with threads.limit(1):
        serial = _digest(generate(Circle((0, 0), 1), _graded))
    monkeypatch.setattr(threads, "MIN_CHUNK", 64)
    assert _digest(generate(Circle((0, 0), 1), _graded)) == serial  # the pool now runs
    if "fork" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("fork")
        queue = ctx.Queue()
        proc = ctx.Process(target=_child, args=(queue,))
        proc.start()
        try:
            got = queue.get(timeout=120)  # a child waiting on the parent's threads never answers
            proc.join(timeout=60)
        finally:
            if proc.is_alive():
                proc.kill()
        assert proc.exitcode == 0 and got == serial
    results: list[bytes] = []
    workers = [threading.Thread(target=lambda: results.append(
        _digest(generate(Circle((0, 0), 1), _graded)))) for _ in range(3)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=300)
    assert results == [serial] * 3


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(3, 300), chunks=st.integers(1, 6))
def test_drifted_lists_equal_the_plain_test(seed: int, n: int, chunks: int) -> None:
    rng = np.random.default_rng(seed)
    p = rng.random((n, 2))
    anchor = p + 0.01 * rng.standard_normal((n, 2)) * (rng.random((n, 1)) < 0.3)
    hbar = np.full(n, 0.02)
    tri = rng.integers(0, n, (2 * n, 3)).astype(np.int32)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "MIN_CHUNK", 4)
        mp.setattr(threads, "threads", lambda: chunks)
        moved, rows = k.drifted(p, anchor, hbar, 0.25, tri)
    mark = np.hypot(*(p - anchor).T) > 0.25 * hbar
    assert np.array_equal(moved, np.flatnonzero(mark))
    assert rows.dtype == np.int32 and np.array_equal(rows, np.flatnonzero(mark[tri].any(axis=1)))


def test_threads_stay_within_the_cores_this_process_may_use() -> None:
    import os
    import subprocess
    import sys
    from pathlib import Path

    if not hasattr(os, "sched_setaffinity"):
        pytest.skip("no CPU affinity on this platform")
    code = ("import os; os.sched_setaffinity(0, {min(os.sched_getaffinity(0))}); "
            "from injmesh.kernels import threads; assert threads.threads() == 1, threads.threads(); "
            "assert not threads.worth(10 ** 7)")
    env = dict(os.environ, NUMBA_NUM_THREADS="8",
               PYTHONPATH=str(Path(__file__).resolve().parents[1] / "src"))
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(16, 300), chunks=st.integers(2, 7))
def test_threaded_size_kernels_equal_serial(seed: int, n: int, chunks: int) -> None:
    # h's compiled parts (the corner cap's cones, a raster's bilinear values) split into
    # chunks give the serial numbers: each point's value depends on that point alone.
    from injmesh.kernels.interp import bilinear, threaded_bilinear
    from injmesh.kernels.outline import cone_index, corner_cones, threaded_corner_cones

    rng = np.random.default_rng(seed)
    corners = rng.random((max(3, n // 4), 2))
    spacing = 0.01 + 0.05 * rng.random(len(corners))
    p = rng.random((n, 2)) * 1.4 - 0.2
    hp = 0.02 + 0.2 * rng.random(n)
    index = cone_index(corners, spacing, 0.3, 4, 0.5, 2.0 * len(corners), 0.22)
    # A uniform x axis (cells found arithmetically) and an irregular y axis (bisection).
    x, y = np.linspace(0.0, 1.0, 7), np.sort(rng.random(5))
    values = 0.1 + rng.random((5, 7))
    inv = 6.0, 0.0
    serial = corner_cones(p, hp, index), bilinear(x, y, values, inv[0], inv[1], p)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "MIN_CHUNK", 8)
        mp.setattr(threads, "threads", lambda: chunks)
        assert threads.worth(n) == (n >= 16)
        split = threaded_corner_cones(p, hp, index), threaded_bilinear(x, y, values, inv[0], inv[1], p)
    for a, b in zip(serial, split, strict=True):
        assert a.tobytes() == b.tobytes()


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(16, 400), chunks=st.integers(2, 7))
def test_threaded_signed_distance_equals_serial(seed: int, n: int, chunks: int) -> None:
    # An outline's sdf splits its (Z-ordered) points into chunks whose first search starts
    # from the root: the least distance and its sign do not depend on where a search starts.
    # Points on vertices and edges (ties between pieces) included.
    from injmesh import Polygon
    from injmesh.kernels.brep import nearest, signed_distance

    rng = np.random.default_rng(seed)
    # One vertex per 30-degree sector: no gap between angles reaches 60 degrees, so every
    # edge stays further than 0.5 cos(30) = 0.43 from the origin and the hole (radius <= 0.2)
    # touches nothing (sorted uniform angles left a gap of 130 degrees now and then, and the
    # shell's edge crossed the hole: seed 5802).
    angles = (np.arange(12) + rng.uniform(0.1, 0.9, 12)) * (2 * np.pi / 12)
    ring = np.column_stack([np.cos(angles), np.sin(angles)]) * rng.uniform(0.5, 1.0, (12, 1))
    # A hole touching nothing, and a circle-minus-square: arcs and segments.
    poly = Polygon(ring, holes=[0.2 * ring[::-1]])
    origin, g = poly.kernel_data()
    arcs = (Circle((0, 0), 0.9) - Rectangle((-0.1, -0.1), (0.3, 0.3))).exact_brep()
    p = np.concatenate([rng.uniform(-1.2, 1.2, (n, 2)), ring, 0.2 * ring, 0.5 * (ring + np.roll(ring, 1, 0))])
    q = np.ascontiguousarray(p - origin)
    serial = nearest(q, g)[0]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "MIN_CHUNK", 8)
        mp.setattr(threads, "threads", lambda: chunks)
        split = signed_distance(q, g)
    assert serial.tobytes() == split.tobytes()
    assert np.array_equal(poly.sdf(p), serial)
    origin, g = arcs.kernel_data()
    q = np.ascontiguousarray(p - origin)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(threads, "MIN_CHUNK", 8)
        mp.setattr(threads, "threads", lambda: chunks)
        assert signed_distance(q, g).tobytes() == nearest(q, g)[0].tobytes()
