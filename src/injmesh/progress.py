"""Progress reporting: a callback hook and logging, never printing."""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

logger = logging.getLogger("injmesh")


@dataclass(frozen=True)
class Progress:
    """One progress event.

    Attributes
    ----------
    stage : str
        ``"boundary"``, ``"injection"``, ``"smoothing"`` or ``"distmesh"``.
    step : int
        Iteration or layer number within the stage (1-based); 0 marks the start of a stage
        whose set-up takes a while before its first step (smoothing: the first
        triangulation, seconds at a million nodes).
    total : int or None
        The stage's cap on ``step``, when known.
    info : dict
        Stage-specific figures: ``nodes``; for smoothing ``max_move`` (largest move of the
        step over hbar), ``moving`` (nodes that moved more than the stopping tolerance) and
        ``force``; for injection ``front``.
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
    if callback is not None:
        callback(Progress(stage, step, total, info))
