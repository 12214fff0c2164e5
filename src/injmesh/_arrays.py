"""Small vectorised helpers shared by several stages."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.intp]


def lower_wins(keep: BoolArray, lo: IntArray, hi: IntArray) -> BoolArray:
    """Greedy independent set in index order over conflict pairs ``(lo, hi)``, ``lo < hi``.

    A candidate (``keep`` True) survives unless a lower-numbered survivor conflicts with it.
    Computed in parallel rounds: a candidate is decided once all its lower partners are.

    Examples
    --------
    >>> import numpy as np
    >>> lower_wins(np.ones(3, bool), np.array([0, 1]), np.array([1, 2])).tolist()
    [True, False, True]
    """
    kept = np.zeros(len(keep), dtype=bool)
    undecided = keep.copy()
    while undecided.any():
        waiting = np.zeros(len(keep), dtype=bool)
        waiting[hi[undecided[lo]]] = True
        ready = undecided & ~waiting
        beaten = np.zeros(len(keep), dtype=bool)
        beaten[hi[kept[lo]]] = True
        kept |= ready & ~beaten
        undecided &= ~ready
    return kept
