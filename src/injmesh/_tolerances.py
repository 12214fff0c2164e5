"""Every tolerance of the mesher, in one place.

All tolerances are *relative*: multiples of the local or smallest target edge length h, or of
the domain's diameter.  None is an absolute length, so meshing a domain scaled by 1000 gives the
same mesh scaled by 1000.
"""

from __future__ import annotations

#: Step of the central difference that estimates grad d, as a fraction of the domain diameter.
GRADIENT_STEP = 1e-7

#: Newton projections onto the boundary (Eq. 3.2) stop when |d| is below this fraction of the
#: domain diameter, or after PROJECTION_ITERATIONS steps.
PROJECTION_TOL = 1e-10
PROJECTION_ITERATIONS = 8

#: A point is "on the boundary" when |d| is below this fraction of the domain diameter.
ON_BOUNDARY = 1e-6

#: Boundary tracing samples d on a grid of spacing min(h_min / TRACE_PER_H, diameter /
#: TRACE_MIN_CELLS), but never finer than diameter / TRACE_MAX_CELLS.
TRACE_PER_H = 2.0
TRACE_MIN_CELLS = 160
TRACE_MAX_CELLS = 1600

#: A boundary vertex whose direction turns by more than this (degrees) is a sharp corner: it is
#: kept fixed during boundary balancing (paper Section 3.1).
CORNER_ANGLE = 20.0

#: Algorithm 2 refines a boundary segment while its length exceeds this fraction of h (the
#: curve must be resolved before nodes are chosen on it).
BOUNDARY_REFINE = 0.25

#: Algorithm 3 stops when no node moves more than this fraction of its local h, or after
#: BALANCE_ITERATIONS sweeps.
BALANCE_TOL = 1e-4
BALANCE_ITERATIONS = 200

#: Rounds of splitting boundary segments encroached by other boundary nodes (see boundary.py).
ENCROACH_ROUNDS = 8

#: A boundary curve shorter than TINY_LOOP * h (integrated) is smaller than the elements and
#: is left out with a warning.
TINY_LOOP = 1.5

#: A polygon ring whose area is below this fraction of its extent squared has zero area.
ZERO_AREA = 1e-12

#: Set operations on boundary representations: points of different operands closer than this
#: fraction of the diameter are the same point (intersections, touching, shared edges), and
#: each piece of the result is classified by probing this fraction of the diameter to its
#: left and right.
CSG_SNAP = 1e-11
CSG_PROBE = 1e-8
