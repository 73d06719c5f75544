"""A Cholesky solve of a small dense symmetric system inside numba kernels (the 6×6 pose update of PTAM §5.4,
the 3–4-parameter ESM of Agility §6), without calling LAPACK from a nogil loop."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def cholesky_solve(A, b, n, pivot_eps):
    """Solve A[:n, :n] x = b[:n]; returns (x (n,), ok). Not ok when a pivot falls to ``pivot_eps`` × the
    largest diagonal entry or below (0.0: only non-positive pivots fail)."""
    L = np.zeros((n, n))
    big = 0.0
    for i in range(n):
        big = max(big, A[i, i])
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if d <= 0.0 or d <= pivot_eps * big:
            return np.zeros(n), False
        L[j, j] = math.sqrt(d)
        for i in range(j + 1, n):
            e = A[i, j]
            for k in range(j):
                e -= L[i, k] * L[j, k]
            L[i, j] = e / L[j, j]
    z = np.zeros(n)
    for i in range(n):
        e = b[i]
        for k in range(i):
            e -= L[i, k] * z[k]
        z[i] = e / L[i, i]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        e = z[i]
        for k in range(i + 1, n):
            e -= L[k, i] * x[k]
        x[i] = e / L[i, i]
    return x, True
