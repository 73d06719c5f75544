"""Tukey's biweight M-estimator, shared by the robust fits: the pose update (PTAM §5.4), bundle adjustment (§6.3)
and the rotation estimator's image alignment against moving clutter (Agility §6, §9.3).

The cut-off c is Tukey's constant times a robust scale: the median of the squared errors taken as a normal
distribution's (the median absolute deviation times 1.4826), with a small-sample correction; a residual beyond c
gets no weight, one within it (1 − e²/c²)².
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MAD_TO_SIGMA = 1.4826  # median absolute deviation -> standard deviation of a normal distribution
TUKEY_C = 4.6851  # Tukey's constant for 95% efficiency under Gaussian noise


@njit(nogil=True, cache=True)
def tukey_sigma_sq(err_sq, min_sigma):
    """Tukey c² from scaled squared errors (n,), floored at min_sigma²."""
    n = err_sq.shape[0]
    if n == 0:
        return min_sigma * min_sigma
    med = np.partition(err_sq, n // 2)[n // 2]
    small_sample = 1.0 + 5.0 / max(2 * n - 6, 1)
    c = TUKEY_C * MAD_TO_SIGMA * small_sample * math.sqrt(med)
    return max(c * c, min_sigma * min_sigma)


@njit(nogil=True, cache=True)
def tukey_weight(e2, c2):
    """The biweight of a squared error ``e2`` under the cut-off ``c2``."""
    if e2 > c2:
        return 0.0
    q = 1.0 - e2 / c2
    return q * q
