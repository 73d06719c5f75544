"""Numba kernels for the per-frame and per-iteration hot loops.

Every kernel is ``@njit(nogil=True, cache=True)`` so the tracker and mapper threads run in parallel,
and each has a plain numpy reference that its test compares against.
"""
