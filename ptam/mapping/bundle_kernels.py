"""Bundle-adjustment kernels: the per-iteration loops of PTAM's Levenberg–Marquardt (PTAM §6.3, eq. 10).

The structure is Hartley & Zisserman's sparse LM (MVG 2nd ed., A6.4), as PTAM's ``Bundle.cc`` does it:

* ``ba_residuals`` / ``ba_robust_cost``: normalised reprojection errors e = (û − CamProj(E·p)) / σ with
  σ = 2^level px, and the summed Tukey objective.
* ``tukey_cutoff_sq`` (``gather_errors``, ``cutoff_sq_of``): the Tukey cut-off c² from the median of the squared
  errors (PTAM code, MEstimator.h).
* ``ba_linearise``: per measurement the Jacobians A = ∂/∂μ (2×6, pose update exp(μ)·E) and B = ∂/∂p (2×3),
  both scaled by the square root of the Tukey weight, accumulated into camera blocks U (6×6), point
  blocks V (3×3) and the gradients ε_a, ε_b; A and B are kept, their product W = AᵀB (6×3) is never formed.
* the Schur complement and the back-substitution are in ``bundle_schur_kernels.py``, the Cholesky of the reduced
  system in ``bundle_solve_kernels.py``.

``*_ref`` functions are plain numpy references for the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project, project_jac

# PTAM code, MEstimator.h ``Tukey::FindSigmaSquared``: σ = 1.4826·(1 + 5/(2n − 6))·√median(e²), c = 4.6851σ.
from ..geometry.tukey_kernels import MAD_TO_SIGMA, TUKEY_C


# ---------------------------------------------------------------------------------------------------------
# Residuals, Tukey
# ---------------------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True, inline="always")
def _to_camera(T, points, p):
    """Point p of ``points`` in the frame of pose T (4×4 world-to-camera)."""
    X = points[p, 0]
    Y = points[p, 1]
    Z = points[p, 2]
    return (
        T[0, 0] * X + T[0, 1] * Y + T[0, 2] * Z + T[0, 3],
        T[1, 0] * X + T[1, 1] * Y + T[1, 2] * Z + T[1, 3],
        T[2, 0] * X + T[2, 1] * Y + T[2, 2] * Z + T[2, 3],
    )


@njit(nogil=True, cache=True, inline="always")
def clear_residual(k, err, e2, bad):
    """Measurement k's error, squared error and bad flag before it is (re)computed, or when it is not in use."""
    err[k, 0] = 0.0
    err[k, 1] = 0.0
    e2[k] = 0.0
    bad[k] = False


@njit(nogil=True, cache=True)
def ba_residuals(cam, poses, points, mcam, mpt, uv, inv_sigma, use, err, e2, bad):
    """Normalised errors err (K, 2), |err|² e2 (K,), bad (K,) = behind the camera, for measurements in ``use``."""
    for k in range(mcam.shape[0]):
        clear_residual(k, err, e2, bad)
        if not use[k]:
            continue
        T = poses[mcam[k]]
        p = mpt[k]
        xc, yc, zc = _to_camera(T, points, p)
        if zc <= 0.0:
            bad[k] = True
            continue
        u, v, _ = project(cam, xc, yc, zc)
        ex = (uv[k, 0] - u) * inv_sigma[k]
        ey = (uv[k, 1] - v) * inv_sigma[k]
        err[k, 0] = ex
        err[k, 1] = ey
        e2[k] = ex * ex + ey * ey


@njit(nogil=True, cache=True)
def tukey_objective(r2, c2):
    """PTAM's unscaled Tukey objective: 1 − (1 − r²/c²)³ inside the cut-off, 1 beyond it."""
    if r2 >= c2:
        return 1.0
    d = 1.0 - r2 / c2
    return 1.0 - d * d * d


@njit(nogil=True, cache=True)
def ba_robust_cost(e2, bad, use, c2):
    """Σ Tukey objective over ``use``; measurements behind the camera score 1 (PTAM code)."""
    cost = 0.0
    for k in range(e2.shape[0]):
        if use[k]:
            cost += 1.0 if bad[k] else tukey_objective(e2[k], c2)
    return cost


@njit(nogil=True, cache=True)
def gather_errors(e2, use, bad, out, start):
    """Copy e² of the measurements in ``use & ~bad`` into ``out`` from index ``start``; return the new end."""
    n = start
    for k in range(e2.shape[0]):
        if use[k] and not bad[k]:
            out[n] = e2[k]
            n += 1
    return n


@njit(nogil=True, cache=True)
def select_kth(a, n, k):
    """The k-th smallest of a[:n], which is reordered in place (Hoare's quickselect, median-of-three pivots).
    ``np.partition`` allocates a copy and took 1.4-1.8x as long on a bundle adjustment's 10-20 000 errors."""
    lo, hi = 0, n - 1
    while hi > lo:
        x, y, z = a[lo], a[(lo + hi) // 2], a[hi]
        p = max(min(x, y), min(max(x, y), z))
        i, j = lo, hi
        while i <= j:
            while a[i] < p:
                i += 1
            while a[j] > p:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            break
    return a[k]


@njit(nogil=True, cache=True)
def cutoff_sq_of(errs, n, min_cutoff):
    """Tukey cut-off c² from the (upper) median of the squared errors errs[:n] (reordered), at least
    ``min_cutoff``². When more than half of them lie below the error whose cut-off is the floor, so does the
    median, and the answer is the floor without the selection: a counting pass, the usual case on a converged
    low-noise map (a tenth of the cut-off's time in sync runs of the bundled scenes, 5-7 % of their BA time)."""
    floor = min_cutoff * min_cutoff
    if n == 0:
        return floor
    # The small-sample factor 1 + 5/(2n − 6) is undefined for n ≤ 3; PTAM never meets that case.
    scale = TUKEY_C * MAD_TO_SIGMA * (1.0 + 5.0 / (2.0 * n - 6.0) if 2 * n > 6 else 1.0)
    below = floor / (scale * scale) * (1.0 - 1e-9)  # the margin keeps rounding out of the comparison
    under = 0
    for k in range(n):
        if errs[k] < below:
            under += 1
    if under > n // 2:
        return floor
    c = scale * math.sqrt(select_kth(errs, n, n // 2))
    return max(c * c, floor)


@njit(nogil=True, cache=True)
def tukey_cutoff_sq(e2, use, bad, min_cutoff):
    """Tukey cut-off c² from the (upper) median of e² over ``use & ~bad``, at least ``min_cutoff``²."""
    buf = np.empty(e2.shape[0])
    return cutoff_sq_of(buf, gather_errors(e2, use, bad, buf, 0), min_cutoff)


# ---------------------------------------------------------------------------------------------------------
# Linearisation and block accumulation
# ---------------------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True)
def ba_linearise(cam, poses, points, mcam, mpt, uv, inv_sigma, use, c2, cam_row, U, ea, V, eb, Aw, Bw, live):
    """Accumulate U, ε_a (free cameras), V, ε_b (points) and keep the weighted rows Aw (M, 2, 6), Bw (M, 2, 3) of
    the live measurements (W = AᵀB, never formed: ``bundle_schur_kernels.eliminate``); returns the robust cost.

    ``cam_row[c]`` is camera c's block row or −1 when fixed. ``live`` (out) marks measurements in the
    system this iteration: in ``use``, in front of the camera and inside Tukey's non-zero-weight region.
    The others count 1 in the cost, as in PTAM (they are PTAM's ``bBad`` measurements).
    """
    U[:] = 0.0
    ea[:] = 0.0
    V[:] = 0.0
    eb[:] = 0.0
    J = np.empty((2, 3))
    cost = 0.0
    for k in range(mcam.shape[0]):
        live[k] = False
        if not use[k]:
            continue
        T = poses[mcam[k]]
        p = mpt[k]
        xc, yc, zc = _to_camera(T, points, p)
        if zc <= 0.0:
            cost += 1.0
            continue
        u, v, _ = project_jac(cam, xc, yc, zc, J)
        s = inv_sigma[k]
        ex = (uv[k, 0] - u) * s
        ey = (uv[k, 1] - v) * s
        r2 = ex * ex + ey * ey
        if r2 >= c2:
            cost += 1.0
            continue
        live[k] = True
        cost += tukey_objective(r2, c2)
        # Square root of the Tukey weight on both the error and the Jacobians (PTAM code), so that
        # AᵀA and Aᵀε carry the full weight w = (1 − r²/c²)².
        sw = 1.0 - r2 / c2
        ex *= sw
        ey *= sw
        g = sw * s
        A = Aw[k]
        B = Bw[k]
        for i in range(2):
            j0 = g * J[i, 0]
            j1 = g * J[i, 1]
            j2 = g * J[i, 2]
            # ∂(exp(μ)·Xc)/∂μ = [I | −[Xc]×] for μ = (translation, rotation), PTAM §5.2.
            A[i, 0] = j0
            A[i, 1] = j1
            A[i, 2] = j2
            A[i, 3] = -j1 * zc + j2 * yc
            A[i, 4] = j0 * zc - j2 * xc
            A[i, 5] = -j0 * yc + j1 * xc
            for m in range(3):
                B[i, m] = j0 * T[0, m] + j1 * T[1, m] + j2 * T[2, m]
        for a in range(3):
            for b in range(a + 1):
                V[p, a, b] += B[0, a] * B[0, b] + B[1, a] * B[1, b]
            eb[p, a] += B[0, a] * ex + B[1, a] * ey
        r = cam_row[mcam[k]]
        if r < 0:
            continue
        for a in range(6):
            for b in range(a + 1):
                U[r, a, b] += A[0, a] * A[0, b] + A[1, a] * A[1, b]
            ea[r, a] += A[0, a] * ex + A[1, a] * ey
    # Accumulated as lower triangles (PTAM's BundleTriangle_Update*); mirror them.
    for r in range(U.shape[0]):
        for a in range(6):
            for b in range(a):
                U[r, b, a] = U[r, a, b]
    for p in range(V.shape[0]):
        for a in range(3):
            for b in range(a):
                V[p, b, a] = V[p, a, b]
    return cost
