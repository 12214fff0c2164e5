"""Compiled kernels (numba).

Each module here is imported lazily, by the stage that needs it, so that ``import injmesh`` stays
fast and numba is loaded only when a kernel runs.  Every kernel is the single implementation of
its algorithm (no NumPy twin) and is deterministic: same inputs, bit-identical output.
"""
