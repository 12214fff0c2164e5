"""Running a per-node kernel over a large node list on several threads, bit-identically.

The Euler step's kernels (``kernels.smooth.bar_forces``, ``stable_scale``, ``advance``) compute
each node from its own row only (gather form), so splitting the node list into consecutive
chunks and running the chunks at once gives exactly the serial numbers, whatever the number
of chunks; what a kernel reduces over the nodes (largest move, a count) its caller combines
in chunk order, with the same ties as the serial loop.  So do the per-point queries of h and
of the geometry (``outline.threaded_corner_cones``, ``interp.threaded_bilinear``,
``brep.signed_distance``), whose value at a point is that point's own whatever order the points
come in.  The kernels are compiled ``nogil=True`` and the chunks run on a small pool of Python
threads.

Why not numba's ``parallel=True``: its threading layers are each unsafe somewhere a mesher
runs.  The workqueue layer aborts when two threads launch kernels at once (a threaded batch),
and the GNU OpenMP layer is not safe after ``fork`` (a process pool).  Plain threads over
``nogil`` kernels are safe in both: concurrent callers share the pool (each chunk is
independent), and a forked child starts its own pool.

The number of threads is numba's ``NUMBA_NUM_THREADS`` (the machine's cores unless set), at
most the cores the process may run on, and capped by :func:`limit`; a list is cut into chunks
of at least :data:`MIN_CHUNK` nodes (a shorter one runs on the calling thread, where a
hand-off would cost more than it saves), a few per thread, which the threads take in turn as
they get to run.

Examples
--------
>>> from injmesh.kernels import threads
>>> threads.chunks(10)
[(0, 10)]
>>> with threads.limit(1):
...     threads.chunks(10 ** 6)
[(0, 1000000)]
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from numba import config

T = TypeVar("T")

#: Fewest nodes per chunk: a kernel takes ~5-40 ns per node, a chunk's hand-off to a thread
#: tens of microseconds.
MIN_CHUNK = 4096
#: Chunks per thread, so that a thread the machine does not schedule at once holds up little.
PER_THREAD = 4

_lock = threading.Lock()
_pool: ThreadPoolExecutor | None = None
_state = threading.local()


def _reset_after_fork() -> None:
    # The parent's worker threads do not exist in a forked child: start a new pool there.
    global _pool, _lock
    _pool = None
    _lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_after_fork)


@functools.lru_cache(maxsize=1)
def _usable_cores(pid: int) -> int:
    # The cores this process may run on (a container or taskset can allow fewer than the
    # machine has, which is what NUMBA_NUM_THREADS defaults to); per process, as after fork.
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def threads() -> int:
    """Threads a kernel may use now: ``NUMBA_NUM_THREADS``, at most the cores this process may
    use and :func:`limit`'s cap."""
    n = min(max(1, int(getattr(config, "NUMBA_NUM_THREADS", 1))), _usable_cores(os.getpid()))
    cap = getattr(_state, "cap", None)
    return n if cap is None else max(1, min(n, cap))


@contextlib.contextmanager
def limit(n: int) -> Iterator[None]:
    """Use at most ``n`` threads in this thread's kernels inside the block (a batch worker
    that already has one process per core uses 1)."""
    old = getattr(_state, "cap", None)
    _state.cap = int(n)
    try:
        yield
    finally:
        _state.cap = old


def worth(n: int) -> bool:
    """Would :func:`each` split a list of ``n`` nodes?  (Callers of small lists skip it.)"""
    return n >= 2 * MIN_CHUNK and threads() > 1


def chunks(n: int) -> list[tuple[int, int]]:
    """Consecutive ``(lo, hi)`` ranges covering ``range(n)``: up to :data:`PER_THREAD` per
    thread, each at least :data:`MIN_CHUNK` long (one range when threads cannot help)."""
    k = max(1, min(PER_THREAD * threads(), n // MIN_CHUNK)) if threads() > 1 else 1
    bounds = [n * c // k for c in range(k + 1)]
    return [(bounds[c], bounds[c + 1]) for c in range(k)]


def _get_pool(workers: int) -> ThreadPoolExecutor:
    global _pool
    with _lock:
        if _pool is None or _pool._max_workers < workers:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="injmesh")
        return _pool


def each(n: int, run: Callable[[int, int], T]) -> list[T]:
    """``[run(lo, hi) for (lo, hi) in chunks(n)]``, the chunks shared out among threads.

    ``run`` must touch only its own chunk's entries of any output (as the gather kernels do);
    the results come back in chunk order.  The calling thread takes chunks too, and the pool's
    threads take the next free chunk when they get to run: on a busy machine a thread that is
    not scheduled leaves its share to the others (with one fixed chunk per thread the caller
    would wait for it), and a pool thread that has not started by the time every chunk is
    taken is cancelled, not waited for.
    """
    parts = chunks(n)
    if len(parts) == 1:
        return [run(0, n)]
    results: list[T | None] = [None] * len(parts)
    taken = itertools.count()
    guard = threading.Lock()

    def work() -> None:
        while True:
            with guard:
                c = next(taken)
            if c >= len(parts):
                return
            results[c] = run(*parts[c])

    helpers = min(threads(), len(parts)) - 1
    pool = _get_pool(helpers)
    futures = [pool.submit(work) for _ in range(helpers)]
    try:
        work()
    finally:
        for f in futures:
            if not f.cancel():
                f.result()
    return results  # type: ignore[return-value]
