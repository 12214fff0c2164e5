"""Compiled kernels (numba) of injmesh's hot loops.

Nothing outside this package imports it at ``import injmesh`` time: numba and the compiled
functions load only when a kernel module is imported.

* :mod:`injmesh.kernels.predicates` -- adaptive-precision exact ``orient2d`` and ``incircle``.
* :mod:`injmesh.kernels.delaunay` -- incremental Delaunay triangulation with a live adjacency
  structure (flips, point location, local insertion and removal, edge recovery).
"""
