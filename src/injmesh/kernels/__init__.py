"""Compiled kernels (numba).  Each module is imported lazily by the stage that needs it, so
``import injmesh`` does not import numba."""
