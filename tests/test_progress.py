"""Progress events for numba's first-use compilations (``injmesh.progress.compile_progress``)."""

from __future__ import annotations

import logging

import numpy as np
from numba import njit

import injmesh
from injmesh import progress
from injmesh.progress import Progress, compile_progress


def _fresh_kernel(module: str):  # type: ignore[no-untyped-def]
    """A kernel not compiled yet (no cache), as if defined in ``module``."""

    def kernel(x):  # type: ignore[no-untyped-def]
        return x + 1

    kernel.__module__ = module
    return njit(kernel)


def test_each_kernel_compiled_is_an_event_and_the_first_is_logged(caplog, monkeypatch):
    monkeypatch.setattr(progress, "_noted", False)
    events: list[Progress] = []
    first, second = _fresh_kernel("injmesh.kernels.fake"), _fresh_kernel("injmesh.kernels.fake")
    with caplog.at_level(logging.INFO, logger="injmesh"), compile_progress(events.append):
        first(1)
        second(np.float64(1.0))
        first(2)  # compiled already: no event
    assert [(e.stage, e.step) for e in events] == [("compiling", 1), ("compiling", 2)]
    assert events[0].info["kernel"].endswith("kernel")
    assert [r.message for r in caplog.records] == [progress.COMPILE_NOTE]


def test_other_code_and_nested_blocks_report_nothing_more():
    events: list[Progress] = []
    users = _fresh_kernel("someone_else")
    ours = _fresh_kernel("injmesh.kernels.fake")
    with compile_progress(events.append), compile_progress(events.append):
        users(1)  # the user's own numba code is not ours to report
        ours(1)  # one listener, however deep the blocks
    assert [(e.stage, e.step) for e in events] == [("compiling", 1)]
    later = _fresh_kernel("injmesh.kernels.fake")
    later(1)  # after the block: nobody listens
    assert len(events) == 1


def test_warm_generate_reports_its_stages_only():
    injmesh.generate(injmesh.Circle((0, 0), 1), 0.3)  # compiles (or loads) every kernel it needs
    events: list[Progress] = []
    injmesh.generate(injmesh.Circle((0, 0), 1), 0.3, callback=events.append)
    stages = {e.stage for e in events}
    assert "compiling" not in stages and {"boundary", "injection", "smoothing"} <= stages


def test_warnings_still_point_at_the_caller():
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        injmesh.generate(injmesh.Circle((0, 0), 1), 0.3, max_iterations=1, callback=lambda e: None)
    convergence = [w for w in caught if issubclass(w.category, injmesh.ConvergenceWarning)]
    assert convergence and all(w.filename == __file__ for w in convergence)


def test_what_the_callback_raises_while_compiling_comes_out_after_the_compiler():
    class Cancel(Exception):
        pass

    def cancel(event: Progress) -> None:
        if event.stage == "compiling":
            raise Cancel

    kernel = _fresh_kernel("injmesh.kernels.fake")
    try:
        with compile_progress(cancel):
            assert kernel(1) == 2  # the compile itself completes
            progress.report(None, "smoothing", 1)  # the next event raises it
        raise AssertionError("not raised")
    except Cancel:
        pass
    assert kernel(2) == 3 and len(kernel.signatures) == 1  # numba is left in order
    other = _fresh_kernel("injmesh.kernels.fake")
    try:
        with compile_progress(cancel):
            other(1)  # no event after it: raised when the block ends
        raise AssertionError("not raised")
    except Cancel:
        pass
