"""Compiled kernels (numba).

Each module here is imported lazily, by the stage that needs it, so that ``import injmesh`` stays
fast and numba is loaded only when a kernel runs.  Every kernel is the single implementation of
its algorithm (no NumPy twin) and is deterministic: same inputs, bit-identical output.

* :mod:`injmesh.kernels.predicates` -- adaptive-precision exact ``orient2d`` and ``incircle``.
* :mod:`injmesh.kernels.delaunay` -- incremental Delaunay triangulation with a live adjacency
  structure (flips, point location, local insertion and removal, edge recovery).
* :mod:`injmesh.kernels.mesh` -- loops over plain mesh arrays: distinct edges, neighbours and
  boundary edges without a global sort, areas, side lengths, quality, and the flood fill that
  tells inside from outside.
* :mod:`injmesh.kernels.smooth` -- Step 3's Euler step in gather form over node neighbour lists
  (bar forces, hbar, the capped step), k-rings and edge look-ups for local repair.
* :mod:`injmesh.kernels.repair` -- the repair rounds' bookkeeping: quality, chords and parts'
  minima of a round, the choice and application of its collapses and splits, the flips after
  them, and the cutting of a patch to relax.
* :mod:`injmesh.kernels.brep`, :mod:`injmesh.kernels.fastmarch`, :mod:`injmesh.kernels.interp`
  -- B-rep distance and projection (BVH), fast marching for gradation, size-field interpolation.
* :mod:`injmesh.kernels.inject` -- Advancing Node Injection: the proximity grid (nodes inserted
  layer by layer, nearest-node and wall tests) and the per-layer front geometry.
* :mod:`injmesh.kernels.outline` -- loops over boundary polylines: merging close vertices
  (polygon cleaning), walls facing each other within a width (the feature-size probe), and the
  corner cones of ``boundary.corner_size`` (exact: a k-d tree, and per grid cell the leaves
  that can hold the minimum).
* :mod:`injmesh.kernels.raster` -- inside/outside of background grid nodes by scanlines over
  an exact boundary, the nodes within a distance of it, and the inside test's cell lookup.
* :mod:`injmesh.kernels.gaps` -- the thinnest chord from each vertex of a region's wall to a
  facing wall (the regions' feature size).
* :mod:`injmesh.kernels.feature` -- the feature size's searches over boundary polylines: the
  k nearest vertices of the grid nodes (exact, on a grid of cells) and their nearest boundary
  points, the vertex pairs across a possible gap, and the feature grid's per-node steps.

Every kernel is ``@njit(cache=True)``: the first call compiles (tens of seconds for the whole
Delaunay module on a cold cache) and later processes load the machine code from
``__pycache__``.  Numba invalidates a cached function only when *its own* source file changes:
after editing ``predicates.py`` during development, delete ``kernels/__pycache__`` so that
``delaunay.py``'s kernels are recompiled against the new predicates.
"""
