"""Corners in a row, by the row look-up table (PTAM §6.5): the searches' common step, as a numba helper."""

from __future__ import annotations

from numba import njit


@njit(nogil=True, cache=True, inline="always")
def first_in_row(corners, row_lut, y, x_min):
    """Index of the first corner of row ``y`` at x >= ``x_min``, or the row's end, ``row_lut[y + 1]``: ``corners``
    (K, 2) (x, y) sorted by y, then x (``fast_corners``), ``row_lut`` from ``pyramid.row_lut``. Binary search, so a
    search of a few pixels' width need not walk rows of hundreds of corners."""
    lo = row_lut[y]
    hi = row_lut[y + 1]
    while lo < hi:
        mid = (lo + hi) >> 1
        if corners[mid, 0] < x_min:
            lo = mid + 1
        else:
            hi = mid
    return lo
