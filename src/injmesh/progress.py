"""Progress reporting: a callback hook and logging, never printing."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

logger = logging.getLogger("injmesh")


@dataclass(frozen=True)
class Progress:
    """One progress event.

    Attributes
    ----------
    stage : str
        ``"boundary"``, ``"injection"``, ``"smoothing"`` or ``"distmesh"``; ``"compiling"``
        while numba compiles a kernel on its first use (see :func:`compile_progress`), in the
        middle of another stage.
    step : int
        Iteration or layer number within the stage (1-based); 0 marks the start of a stage
        whose set-up takes a while before its first step (smoothing: the first
        triangulation, seconds at a million nodes).
    total : int or None
        The stage's cap on ``step``, when known.
    info : dict
        Stage-specific figures: ``nodes``; for smoothing ``max_move`` (largest move of the
        step over hbar), ``moving`` (nodes that moved more than the stopping tolerance) and
        ``force``; for injection ``front``; for compiling ``kernel`` (its name).
    """

    stage: str
    step: int
    total: int | None = None
    info: dict[str, Any] = field(default_factory=dict)


Callback = Callable[[Progress], None]


def report(callback: Callback | None, stage: str, step: int, total: int | None = None, **info: Any) -> None:
    """Send a :class:`Progress` event to ``callback`` (if any) and to the debug log."""
    if logger.isEnabledFor(logging.DEBUG):
        logger.debug("%s %d/%s %s", stage, step, total, info)
    _raise_deferred()
    if callback is not None:
        callback(Progress(stage, step, total, info))


def _raise_deferred() -> None:
    """Raise what the callback raised on a ``"compiling"`` event (see :func:`compile_progress`)."""
    exc = getattr(_watching, "pending", None)
    if exc is not None:
        _watching.pending = None
        raise exc


#: Said once per process, at the first kernel compiled.
COMPILE_NOTE = ("compiling injmesh's numba kernels on first use; they are cached on disk, so "
                "this happens once per installation (about 2 minutes on 2 cores)")

_watching = threading.local()
_noted = False


@contextmanager
def compile_progress(callback: Callback | None) -> Iterator[None]:
    """Report numba's compilations of injmesh's kernels while the block runs.

    The first call after installation compiles every kernel it meets (numba caches them on
    disk afterwards): minutes with no other sign of life.  Each kernel compiled becomes a
    ``"compiling"`` :class:`Progress` event (``step``: kernels compiled so far, ``info``:
    ``kernel``), and the first one of the process is logged at INFO level
    (:data:`COMPILE_NOTE`).  A run that finds every kernel in the cache compiles nothing and
    reports nothing.  Nested blocks on one thread report once (a ``target_nodes`` search
    meshes several times); the listener is numba's documented event API, registered only
    while the block runs and only when somebody listens (a callback, or INFO logging).

    The callback is called from inside numba's compiler: what it raises there (a batch's
    time limit, a user's cancel) is kept and raised at the next progress event, or when the
    block ends, never through the compiler.
    """
    if getattr(_watching, "on", False) or (callback is None and not logger.isEnabledFor(logging.INFO)):
        yield
        return
    from numba.core import event

    class _Listener(event.Listener):  # type: ignore[misc]
        count = 0

        def on_start(self, ev: Any) -> None:
            global _noted
            dispatcher = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
            func = getattr(dispatcher, "py_func", None)
            if not getattr(func, "__module__", "").startswith("injmesh."):
                return  # numba's own overloads, or the user's code
            if threading.current_thread() is not owner:
                return  # another thread's mesh
            if not _noted:
                _noted = True
                logger.info(COMPILE_NOTE)
            self.count += 1
            if callback is not None and getattr(_watching, "pending", None) is None:
                name = getattr(func, "__qualname__", "")
                try:
                    callback(Progress("compiling", self.count, None, {"kernel": name}))
                except BaseException as exc:  # noqa: BLE001 - raised again outside the compiler
                    _watching.pending = exc

        def on_end(self, ev: Any) -> None:
            pass

    owner = threading.current_thread()
    listener = _Listener()
    _watching.on = True
    event.register("numba:compile", listener)
    try:
        yield
    finally:
        event.unregister("numba:compile", listener)
        _watching.on = False
    _raise_deferred()

