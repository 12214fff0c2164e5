"""Small vectorised helpers shared by several stages."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.intp]


def lower_wins(keep: BoolArray, lo: IntArray, hi: IntArray) -> BoolArray:
    """Greedy independent set in index order over conflict pairs ``(lo, hi)``, ``lo < hi``.

    A candidate (``keep`` True) survives unless a lower-numbered survivor conflicts with it
    (compiled: one pass in index order, :func:`injmesh.kernels.smooth.lower_wins`).

    Examples
    --------
    >>> import numpy as np
    >>> lower_wins(np.ones(3, bool), np.array([0, 1]), np.array([1, 2])).tolist()
    [True, False, True]
    """
    from .kernels.smooth import lower_wins as kernel

    out: BoolArray = kernel(np.ascontiguousarray(keep, dtype=np.bool_), np.asarray(lo, dtype=np.int64),
                            np.asarray(hi, dtype=np.int64))
    return out
