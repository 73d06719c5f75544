"""Bundle-adjustment kernels: the per-iteration loops of PTAM's Levenberg–Marquardt (PTAM §6.3, eq. 10).

The structure is Hartley & Zisserman's sparse LM (MVG 2nd ed., A6.4), as PTAM's ``Bundle.cc`` does it:

* ``ba_residuals`` / ``ba_robust_cost``: normalised reprojection errors e = (û − CamProj(E·p)) / σ with
  σ = 2^level px, and the summed Tukey objective.
* ``tukey_cutoff_sq``: the Tukey cut-off c² from the median of the squared errors (PTAM code, MEstimator.h).
* ``ba_linearise``: per measurement the Jacobians A = ∂/∂μ (2×6, pose update exp(μ)·E) and B = ∂/∂p (2×3),
  both scaled by the square root of the Tukey weight, accumulated into camera blocks U (6×6), point
  blocks V (3×3), camera-point blocks W = AᵀB (6×3) and the gradients ε_a, ε_b.
* ``ba_schur``: S = U* − Σ W V*⁻¹ Wᵀ over every camera pair that shares a point (the O(N²M)
  camera-point-camera products of §6.3) and the reduced right-hand side; * means the diagonal × (1 + λ).
* the Cholesky of S is in ``ba_solve.py``.
* ``ba_backsub``: the point updates δp = V*⁻¹ (ε_b − Σ Wᵀ δμ).

Measurements are sorted by point (``order``, ``pt_start``) and the camera pairs of each point are
enumerated once per solve by ``ba_pair_script``; ``ba_schur`` walks them in the same order. ``*_ref``
functions are plain numpy references for the tests.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project, project_jac

# Tukey biweight constant for 95% efficiency and the median-absolute-deviation → σ factor for a Gaussian
# (PTAM code, MEstimator.h ``Tukey::FindSigmaSquared``: σ = 1.4826·(1 + 5/(2n − 6))·√median(e²), c = 4.6851σ).
TUKEY_C = 4.6851
MAD_TO_SIGMA = 1.4826


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
def tukey_cutoff_sq(e2, use, bad, min_cutoff):
    """Tukey cut-off c² from the (upper) median of e² over ``use & ~bad``, at least ``min_cutoff``²."""
    n = 0
    for k in range(e2.shape[0]):
        if use[k] and not bad[k]:
            n += 1
    floor = min_cutoff * min_cutoff
    if n == 0:
        return floor
    buf = np.empty(n)
    n = 0
    for k in range(e2.shape[0]):
        if use[k] and not bad[k]:
            buf[n] = e2[k]
            n += 1
    med = np.partition(buf, n // 2)[n // 2]
    # The small-sample factor 1 + 5/(2n − 6) is undefined for n ≤ 3; PTAM never meets that case.
    small = 1.0 + 5.0 / (2.0 * n - 6.0) if 2 * n > 6 else 1.0
    c = TUKEY_C * MAD_TO_SIGMA * small * math.sqrt(med)
    return max(c * c, floor)


# ---------------------------------------------------------------------------------------------------------
# Linearisation and block accumulation
# ---------------------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True)
def ba_linearise(cam, poses, points, mcam, mpt, uv, inv_sigma, use, c2, cam_row, U, ea, V, eb, W, live):
    """Accumulate U, ε_a (free cameras), V, ε_b (points) and W (per measurement); returns the robust cost.

    ``cam_row[c]`` is camera c's block row or −1 when fixed. ``live`` (out) marks measurements in the
    system this iteration: in ``use``, in front of the camera and inside Tukey's non-zero-weight region.
    The others count 1 in the cost, as in PTAM (they are PTAM's ``bBad`` measurements).
    """
    U[:] = 0.0
    ea[:] = 0.0
    V[:] = 0.0
    eb[:] = 0.0
    J = np.empty((2, 3))
    A = np.empty((2, 6))
    B = np.empty((2, 3))
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
            for b in range(3):
                W[k, a, b] = A[0, a] * B[0, b] + A[1, a] * B[1, b]
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


# ---------------------------------------------------------------------------------------------------------
# Schur complement on the points
# ---------------------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True)
def ba_pair_script(pt_start, order, mrow, n_free):
    """Every pair of free cameras sharing a point, as ``ba_schur`` walks them (PTAM code: GenerateOffDiagScripts).

    ``order`` lists the measurements by point, and within a point by ascending camera row. Returns, per entry
    of that walk, the index of its camera pair (r_a > r_b), and each pair's rows (r_a) and columns (r_b).
    """
    n = 0
    for p in range(pt_start.shape[0] - 1):
        c = 0
        for i in range(pt_start[p], pt_start[p + 1]):
            if mrow[order[i]] >= 0:
                c += 1
        n += c * (c - 1) // 2
    ra = np.empty(n, np.int64)
    rb = np.empty(n, np.int64)
    n = 0
    for p in range(pt_start.shape[0] - 1):
        for ia in range(pt_start[p], pt_start[p + 1]):
            a = mrow[order[ia]]
            if a < 0:
                continue
            for ib in range(pt_start[p], ia):
                b = mrow[order[ib]]
                if b >= 0:
                    ra[n] = a
                    rb[n] = b
                    n += 1
    # Bucket the entries by r_a, then number the distinct r_b of each bucket: O(n + n_free), no sort.
    start = np.zeros(n_free + 1, np.int64)
    for e in range(n):
        start[ra[e] + 1] += 1
    for r in range(n_free):
        start[r + 1] += start[r]
    fill = start[:-1].copy()
    bucket = np.empty(n, np.int64)
    for e in range(n):
        bucket[fill[ra[e]]] = e
        fill[ra[e]] += 1
    seen = np.full(n_free, -1, np.int64)
    slot = np.empty(n_free, np.int64)
    pair_id = np.empty(n, np.int64)
    rows = np.empty(n, np.int64)
    cols = np.empty(n, np.int64)
    n_pairs = 0
    for r in range(n_free):
        for t in range(start[r], start[r + 1]):
            e = bucket[t]
            b = rb[e]
            if seen[b] != r:
                seen[b] = r
                slot[b] = n_pairs
                rows[n_pairs] = r
                cols[n_pairs] = b
                n_pairs += 1
            pair_id[e] = slot[b]
    return pair_id, rows[:n_pairs].copy(), cols[:n_pairs].copy()


@njit(nogil=True, cache=True)
def inv_sym3(M, lam, out):
    """out = (M with its diagonal × (1 + λ))⁻¹, or zeros when that is not positive definite (PTAM code)."""
    a = M[0, 0] * (1.0 + lam)
    d = M[1, 1] * (1.0 + lam)
    f = M[2, 2] * (1.0 + lam)
    b = M[0, 1]
    c = M[0, 2]
    e = M[1, 2]
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    det = a * c00 + b * c01 + c * c02
    if a * d * f == 0.0 or det <= 0.0:
        out[:] = 0.0
        return
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[0, 1] = c01 * inv
    out[0, 2] = c02 * inv
    out[1, 0] = c01 * inv
    out[1, 1] = (a * f - c * c) * inv
    out[1, 2] = (b * c - a * e) * inv
    out[2, 0] = c02 * inv
    out[2, 1] = (b * c - a * e) * inv
    out[2, 2] = (a * d - b * b) * inv


@njit(nogil=True, cache=True)
def _sub_wvwt(blocks, q, WVa, W, kb):
    """blocks[q] −= WVa · W[kb]ᵀ (6×3 · 3×6); the innermost product of the O(N²M) pair walk, written out: a loop
    over the three columns there costs global BA ~30 %."""
    for a in range(6):
        w0 = WVa[a, 0]
        w1 = WVa[a, 1]
        w2 = WVa[a, 2]
        for b in range(6):
            blocks[q, a, b] -= w0 * W[kb, b, 0] + w1 * W[kb, b, 1] + w2 * W[kb, b, 2]


@njit(nogil=True, cache=True)
def eliminate(Vinv, eb, W, live, mrow, start, order, pair_id, blocks, rhs):
    """Subtract Σ W V*⁻¹ Wᵀ of every point from the reduced system's ``blocks`` and W V*⁻¹ ε_b from ``rhs``.
    ``order`` lists the measurements by point (``start``), then camera row; ``pair_id`` numbers the camera pairs
    in that walk (``ba_pair_script``; edgelets continue it in ``bundle_edgelet_kernels.ba_edgelet_schur``)."""
    d = W.shape[2]
    WVa = np.empty((6, d))
    q = 0
    for p in range(start.shape[0] - 1):
        Vi = Vinv[p]
        for ia in range(start[p], start[p + 1]):
            ka = order[ia]
            ra = mrow[ka]
            if ra < 0:
                continue
            if live[ka]:
                for a in range(6):
                    for b in range(d):
                        s = 0.0
                        for c in range(d):
                            s += W[ka, a, c] * Vi[c, b]
                        WVa[a, b] = s
                    s = 0.0
                    for b in range(d):
                        s += WVa[a, b] * eb[p, b]
                    rhs[6 * ra + a] -= s
                _sub_wvwt(blocks, ra, WVa, W, ka)
            for ib in range(start[p], ia):
                kb = order[ib]
                if mrow[kb] < 0:
                    continue
                pid = pair_id[q]
                q += 1
                if live[ka] and live[kb]:
                    _sub_wvwt(blocks, pid, WVa, W, kb)


@njit(nogil=True, cache=True)
def ba_schur(U, ea, V, eb, W, live, lam, mrow, pt_start, order, pair_id, blocks, rhs, Vinv):
    """Reduced camera system S δμ = rhs as blocks, and V*⁻¹ (M, 3, 3) for the back-substitution.

    blocks[r] (r < n_free) is the diagonal block of camera row r; the off-diagonal block (r_a, r_b),
    r_a > r_b, of the k-th entry of ``ba_pair_script``'s walk is blocks[pair_id[k]].
    """
    nf = U.shape[0]
    blocks[:] = 0.0
    for r in range(nf):
        for a in range(6):
            for b in range(6):
                blocks[r, a, b] = U[r, a, b]
            blocks[r, a, a] *= 1.0 + lam
            rhs[6 * r + a] = ea[r, a]
    for p in range(pt_start.shape[0] - 1):
        inv_sym3(V[p], lam, Vinv[p])
    eliminate(Vinv, eb, W, live, mrow, pt_start, order, pair_id, blocks, rhs)


@njit(nogil=True, cache=True)
def ba_backsub(Vinv, eb, W, live, mrow, pt_start, order, dcam):
    """Point updates δp = V*⁻¹ (ε_b − Σ_j W_jᵀ δμ_j) (M, 3) from the camera updates dcam (6·n_free,)."""
    m = pt_start.shape[0] - 1
    d = W.shape[2]
    dp = np.zeros((m, d))
    v = np.empty(d)
    for p in range(m):
        for b in range(d):
            v[b] = eb[p, b]
        for i in range(pt_start[p], pt_start[p + 1]):
            k = order[i]
            r = mrow[k]
            if r < 0 or not live[k]:
                continue
            for a in range(6):
                dc = dcam[6 * r + a]
                for b in range(d):
                    v[b] -= W[k, a, b] * dc
        for a in range(d):
            s = 0.0
            for b in range(d):
                s += Vinv[p, a, b] * v[b]
            dp[p, a] = s
    return dp
