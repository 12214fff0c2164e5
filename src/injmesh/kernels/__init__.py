"""Compiled kernels (numba) of injmesh's hot loops.

Nothing outside this package imports it at ``import injmesh`` time: numba and the compiled
functions load only when a kernel module is imported.

* :mod:`injmesh.kernels.predicates` -- adaptive-precision exact ``orient2d`` and ``incircle``.
* :mod:`injmesh.kernels.delaunay` -- incremental Delaunay triangulation with a live adjacency
  structure (flips, point location, local insertion and removal, edge recovery).

Every kernel is ``@njit(cache=True)``: the first call compiles (tens of seconds for the whole
Delaunay module on a cold cache) and later processes load the machine code from
``__pycache__``.  Numba invalidates a cached function only when *its own* source file changes:
after editing ``predicates.py`` during development, delete ``kernels/__pycache__`` so that
``delaunay.py``'s kernels are recompiled against the new predicates.
"""
