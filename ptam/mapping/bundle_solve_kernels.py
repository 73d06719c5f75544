"""Cholesky of the reduced camera system S of bundle adjustment inside its envelope (PTAM §6.3).

PTAM factors the dense 6N×6N system (TooN ``Cholesky<>``). Here S's lower triangle is stored as a skyline:
dense keeps whole rows; sparse first reorders the keyframes to reduce the bandwidth (reverse Cuthill–McKee,
done by the caller) so fill stays inside the envelope. Plain numba loops, GIL-free: scipy's ``cho_factor``
and ``splu`` held the GIL for 100–440 ms on PTAM-sized maps while the tracker waited. ``ba_gauged_solve`` solves
the same system with the map's scale held (``bundle_gauge``), its direction (``scale_direction``) and both solves
in one call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def ba_envelope(pair_rows, pair_cols, rank, dense):
    """Skyline layout of S's lower triangle with block r moved to position rank[r]: row i of L holds columns
    first[i]..i at env[ptr[i]:ptr[i + 1]]. ``dense`` keeps whole rows (first = 0)."""
    nb = rank.shape[0]
    fb = np.zeros(nb, np.int64) if dense else np.arange(nb)
    if not dense:
        for q in range(pair_rows.shape[0]):
            a = rank[pair_rows[q]]
            b = rank[pair_cols[q]]
            hi = max(a, b)
            lo = min(a, b)
            if lo < fb[hi]:
                fb[hi] = lo
    n = 6 * nb
    first = np.empty(n, np.int64)
    ptr = np.empty(n + 1, np.int64)
    ptr[0] = 0
    for i in range(n):
        first[i] = 6 * fb[i // 6]
        ptr[i + 1] = ptr[i] + i - first[i] + 1
    return first, ptr


@njit(nogil=True, cache=True, fastmath=True)
def _envelope_cholesky(env, first, ptr, n):
    """In-place L·Lᵀ of the envelope, six rows (one keyframe, one shared ``first``) at a time so each row of L
    already computed is read once per keyframe rather than once per row. False if not positive definite."""
    for r0 in range(0, n, 6):
        f = first[r0]
        o = np.empty(6, np.int64)
        for a in range(6):
            o[a] = ptr[r0 + a] - f
        o0, o1, o2, o3, o4, o5 = o[0], o[1], o[2], o[3], o[4], o[5]
        for j in range(f, r0):
            oj = ptr[j] - first[j]
            s0 = s1 = s2 = s3 = s4 = s5 = 0.0
            for k in range(max(f, first[j]), j):
                ljk = env[oj + k]
                s0 += env[o0 + k] * ljk
                s1 += env[o1 + k] * ljk
                s2 += env[o2 + k] * ljk
                s3 += env[o3 + k] * ljk
                s4 += env[o4 + k] * ljk
                s5 += env[o5 + k] * ljk
            d = env[oj + j]
            env[o0 + j] = (env[o0 + j] - s0) / d
            env[o1 + j] = (env[o1 + j] - s1) / d
            env[o2 + j] = (env[o2 + j] - s2) / d
            env[o3 + j] = (env[o3 + j] - s3) / d
            env[o4 + j] = (env[o4 + j] - s4) / d
            env[o5 + j] = (env[o5 + j] - s5) / d
        for a in range(6):
            i = r0 + a
            for j in range(r0, i + 1):
                oj = ptr[j] - f
                s = env[o[a] + j]
                for k in range(f, j):
                    s -= env[o[a] + k] * env[oj + k]
                if j < i:
                    env[o[a] + j] = s / env[oj + j]
                elif s > 0.0:
                    env[o[a] + i] = math.sqrt(s)
                else:
                    return False
    return True


@njit(nogil=True, cache=True, fastmath=True)
def ba_envelope_solve(blocks, pair_rows, pair_cols, rank, first, ptr, rhs):
    """Solve S x = rhs (n, k), k right-hand sides, by a Cholesky factorisation inside the envelope (fill-in never
    leaves it).

    Plain loops instead of LAPACK: OpenBLAS threads would compete with the tracker's thread (and are
    orders of magnitude slower on a loaded machine). Returns (x, ok); ok is False when S is not positive
    definite (PTAM code: Cholesky failure, "the map is probably corrupt").
    """
    n, k = rhs.shape
    env = np.zeros(ptr[n])
    for q in range(blocks.shape[0]):
        R = 6 * rank[pair_rows[q]]
        C = 6 * rank[pair_cols[q]]
        for a in range(6):
            for b in range(6):
                i, j = (R + a, C + b) if R >= C else (C + b, R + a)
                if j <= i:
                    env[ptr[i] + j - first[i]] = blocks[q, a, b]
    if not _envelope_cholesky(env, first, ptr, n):
        return np.zeros((n, k)), False
    y = np.empty(n)
    x = np.empty((n, k))
    for c in range(k):
        for r in range(rank.shape[0]):
            for a in range(6):
                y[6 * rank[r] + a] = rhs[6 * r + a, c]
        for i in range(n):
            oi = ptr[i] - first[i]
            s = y[i]
            for j in range(first[i], i):
                s -= env[oi + j] * y[j]
            y[i] = s / env[oi + i]
        for i in range(n - 1, -1, -1):
            oi = ptr[i] - first[i]
            y[i] /= env[oi + i]
            for j in range(first[i], i):
                y[j] -= env[oi + j] * y[i]
        for r in range(rank.shape[0]):
            for a in range(6):
                x[6 * r + a, c] = y[6 * rank[r] + a]
    return x, True


@njit(nogil=True, cache=True)
def scale_direction(poses, fixed, free):
    """g (6·len(free),): the pose updates (translation, rotation) of the keyframes ``free`` that scale the map about
    the centre c₀ of keyframe ``fixed`` by 1 + ε, per unit ε (T ← exp(μ) T: the translation moves by −R (C − c₀),
    C = −Rᵀ t; ``bundle_gauge``)."""
    F = poses[fixed]
    c = np.zeros(3)
    for i in range(3):
        for j in range(3):
            c[i] += F[j, i] * F[j, 3]  # Rᵀ t = −c₀
    g = np.zeros(6 * free.shape[0])
    for i in range(free.shape[0]):
        P = poses[free[i]]
        for r in range(3):
            g[6 * i + r] = P[r, 3] - (P[r, 0] * c[0] + P[r, 1] * c[1] + P[r, 2] * c[2])
    return g


@njit(nogil=True, cache=True)
def ba_gauged_solve(blocks, pair_rows, pair_cols, rank, first, ptr, rhs, poses, fixed, free):
    """δμ = S⁻¹b − S⁻¹g (gᵀS⁻¹b)/(gᵀS⁻¹g), the solution of S δμ = b (``rhs``) with gᵀ δμ = 0 (``bundle_gauge``),
    g = ``scale_direction``; both solves on one factorisation (``ba_envelope_solve``), in one call. Returns (δμ, ok).
    """
    g = scale_direction(poses, fixed, free)
    both = np.empty((rhs.shape[0], 2))
    both[:, 0] = rhs
    both[:, 1] = g
    xy, ok = ba_envelope_solve(blocks, pair_rows, pair_cols, rank, first, ptr, both)
    x = xy[:, 0].copy()
    gx = 0.0
    gy = 0.0
    for i in range(g.shape[0]):
        gx += g[i] * xy[i, 0]
        gy += g[i] * xy[i, 1]
    if ok and gy > 0.0:
        for i in range(g.shape[0]):
            x[i] -= xy[i, 1] * (gx / gy)
    return x, ok
