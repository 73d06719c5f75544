"""Kernel: structure-only Gauss–Newton on edgelets with the keyframe poses fixed (the edgelet blocks of
Agility §4.4's bundle adjustment), every iteration in one call.

Each iteration forms every edgelet's 4×4 normal equations (``edgelet_normal_equations``), solves those that are
solvable — at least two valid measurements and a condition number below 1/ε (extreme eigenvalues of the
symmetric H by cyclic Jacobi rotations) — by Gaussian elimination with partial pivoting, and applies
E_WE ← E_WE · exp(μ) re-orthonormalised (``frames_updated``); an unsolvable edgelet takes μ = 0. The mapper
calls it for every new edgelet on its source, target and check measurements, where numpy's per-call overheads
(batched eigenvalues, solve, frame rebuilds) had cost more than the arithmetic.
The numpy reference is ``tests/reference/edgelet_ba.py``'s ``refine_edgelets_ref``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .edgelet_ba_kernels import edgelet_normal_equations, frames_updated

_JACOBI_SWEEPS = 30  # cyclic Jacobi on a 4×4 converges quadratically: a handful of sweeps reach machine precision


@njit(nogil=True, cache=True)
def symmetric_eigenvalues(A, a):
    """The eigenvalues of the symmetric matrix A (n, n), left on the diagonal of the scratch ``a`` (n, n)."""
    n = A.shape[0]
    a[:, :] = A
    for _ in range(_JACOBI_SWEEPS):
        off = 0.0
        diag = 0.0
        for p in range(n):
            diag += a[p, p] * a[p, p]
            for q in range(p + 1, n):
                off += a[p, q] * a[p, q]
        if off <= np.finfo(np.float64).eps ** 2 * diag or off == 0.0:
            break
        for p in range(n - 1):
            for q in range(p + 1, n):
                if a[p, q] == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
                t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                if theta < 0.0:
                    t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):  # a ← a J, then a ← Jᵀ a: a[p, q] becomes 0
                    akp, akq = a[k, p], a[k, q]
                    a[k, p] = c * akp - s * akq
                    a[k, q] = s * akp + c * akq
                for k in range(n):
                    apk, aqk = a[p, k], a[q, k]
                    a[p, k] = c * apk - s * aqk
                    a[q, k] = s * apk + c * aqk


@njit(nogil=True, cache=True)
def solve_in_place(a, x):
    """Solve a y = x by Gaussian elimination with partial pivoting; y overwrites x, a is destroyed."""
    n = a.shape[0]
    for col in range(n):
        piv = col
        for r in range(col + 1, n):
            if abs(a[r, col]) > abs(a[piv, col]):
                piv = r
        if piv != col:
            for k in range(n):
                a[col, k], a[piv, k] = a[piv, k], a[col, k]
            x[col], x[piv] = x[piv], x[col]
        for r in range(col + 1, n):
            f = a[r, col] / a[col, col]
            for k in range(col, n):
                a[r, k] -= f * a[col, k]
            x[r] -= f * x[col]
    for r in range(n - 1, -1, -1):
        s = x[r]
        for k in range(r + 1, n):
            s -= a[r, k] * x[k]
        x[r] = s / a[r, r]


@njit(nogil=True, cache=True)
def solvable(H, count, a):
    """At least two measurements and |λ|min / ε > |λ|max: Gauss–Newton can take the step."""
    if count < 2:
        return False
    symmetric_eigenvalues(H, a)
    lo = np.inf
    hi = 0.0
    for i in range(H.shape[0]):
        v = abs(a[i, i])
        lo = min(lo, v)
        hi = max(hi, v)
    return lo * (1.0 / np.finfo(np.float64).eps) > hi


@njit(nogil=True, cache=True)
def refine_frames(cam, poses, frames, mkf, medg, line_a, line_n, along, iterations):
    """``iterations`` Gauss–Newton steps on the edgelet frames (E, 4, 4), updated in place, from measurements
    (keyframe ``mkf``, edgelet ``medg``) of lines (a, unit normal) with sample points at E-frame z = ``along``."""
    n = frames.shape[0]
    mu = np.zeros((n, 4))
    a = np.empty((4, 4))
    for _ in range(iterations):
        H, g, count = edgelet_normal_equations(cam, poses, frames, mkf, medg, line_a, line_n, along, n)
        for e in range(n):
            mu[e] = 0.0
            if solvable(H[e], count[e], a):
                a[:, :] = H[e]
                for i in range(4):
                    mu[e, i] = -g[e, i]
                solve_in_place(a, mu[e])
        frames_updated(frames, mu, frames)
