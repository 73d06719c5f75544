"""numpy references for ``ptam.mapping.bundle_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.geometry import se3
from ptam.geometry.tukey_kernels import MAD_TO_SIGMA, TUKEY_C


# ---------------------------------------------------------------------------------------------------------
# numpy references (tests only)
# ---------------------------------------------------------------------------------------------------------
def ba_residuals_ref(camera, poses, points, mcam, mpt, uv, inv_sigma, use):
    Xc = np.einsum("kij,kj->ki", poses[mcam, :3, :3], points[mpt]) + poses[mcam, :3, 3]
    bad = use & (Xc[:, 2] <= 0.0)
    ok = use & ~bad
    err = np.zeros((len(mcam), 2))
    err[ok] = (uv[ok] - camera.project(Xc[ok])) * inv_sigma[ok, None]
    return err, (err**2).sum(axis=1), bad


def tukey_cutoff_sq_ref(e2, use, bad, min_cutoff):
    v = np.sort(e2[use & ~bad])
    n = len(v)
    if n == 0:
        return min_cutoff**2
    small = 1.0 + 5.0 / (2.0 * n - 6.0) if 2 * n > 6 else 1.0
    c = TUKEY_C * MAD_TO_SIGMA * small * np.sqrt(v[n // 2])
    return max(c * c, min_cutoff**2)


def ba_robust_cost_ref(e2, bad, use, c2):
    d = np.clip(1.0 - e2 / c2, 0.0, None)
    obj = np.where(bad | (e2 >= c2), 1.0, 1.0 - d**3)
    return float(obj[use].sum())


def ba_linearise_ref(camera, poses, points, mcam, mpt, uv, inv_sigma, use, c2, cam_row, n_points):
    """Returns U, ea, V, eb, W, live, cost with W zero where not live or the camera is fixed."""
    K = len(mcam)
    err, e2, bad = ba_residuals_ref(camera, poses, points, mcam, mpt, uv, inv_sigma, use)
    cost = ba_robust_cost_ref(e2, bad, use, c2)
    live = use & ~bad & (e2 < c2)
    sw = np.where(live, 1.0 - e2 / c2, 0.0)
    R = poses[mcam, :3, :3]
    Xc = np.einsum("kij,kj->ki", R, points[mpt]) + poses[mcam, :3, 3]
    Jp = np.zeros((K, 2, 3))
    Jp[live] = camera.project_jacobian(Xc[live])
    Jp *= (sw * inv_sigma)[:, None, None]
    A = Jp @ se3.point_jacobian(Xc)
    B = Jp @ R
    eps = err * sw[:, None]
    nf = int(cam_row.max()) + 1 if cam_row.size else 0
    row = cam_row[mcam]
    free = live & (row >= 0)
    U = np.zeros((nf, 6, 6))
    ea = np.zeros((nf, 6))
    np.add.at(U, row[free], np.einsum("kia,kib->kab", A[free], A[free]))
    np.add.at(ea, row[free], np.einsum("kia,ki->ka", A[free], eps[free]))
    V = np.zeros((n_points, 3, 3))
    eb = np.zeros((n_points, 3))
    np.add.at(V, mpt[live], np.einsum("kia,kib->kab", B[live], B[live]))
    np.add.at(eb, mpt[live], np.einsum("kia,ki->ka", B[live], eps[live]))
    W = np.zeros((K, 6, 3))
    W[free] = np.einsum("kia,kib->kab", A[free], B[free])
    return U, ea, V, eb, W, live, cost


def w_blocks(A, B, live, mrow):
    """W = AᵀB (M, 6, d) from the kernels' weighted rows A (M, 2, 6), B (M, 2, d), zero where the measurement is not
    live or its camera is fixed: the references' W."""
    on = (live & (mrow >= 0))[:, None, None]
    return np.where(on, np.einsum("ksa,ksb->kab", A, B), 0.0)


def ba_schur_ref(U, ea, V, eb, W, live, lam, mrow, mpt):
    """Dense S = U* − W V*⁻¹ Wᵀ, rhs = ε_a − W V*⁻¹ ε_b and V*⁻¹ by explicit (6N × 3M) matrices."""
    nf, m = U.shape[0], V.shape[0]
    damp = 1.0 + lam
    Ustar = U.copy()
    Ustar[:, np.arange(6), np.arange(6)] *= damp
    Vstar = V.copy()
    Vstar[:, np.arange(3), np.arange(3)] *= damp
    Vinv = np.zeros_like(V)
    for p in range(m):
        if np.prod(np.diag(Vstar[p])) != 0.0 and np.linalg.det(Vstar[p]) > 0.0:
            Vinv[p] = np.linalg.inv(Vstar[p])
    Wbig = np.zeros((6 * nf, 3 * m))
    for k in np.flatnonzero(live & (mrow >= 0)):
        Wbig[6 * mrow[k] : 6 * mrow[k] + 6, 3 * mpt[k] : 3 * mpt[k] + 3] += W[k]
    Vbig = np.zeros((3 * m, 3 * m))
    for p in range(m):
        Vbig[3 * p : 3 * p + 3, 3 * p : 3 * p + 3] = Vinv[p]
    Ubig = np.zeros((6 * nf, 6 * nf))
    for r in range(nf):
        Ubig[6 * r : 6 * r + 6, 6 * r : 6 * r + 6] = Ustar[r]
    S = Ubig - Wbig @ Vbig @ Wbig.T
    rhs = ea.ravel() - Wbig @ Vbig @ eb.ravel()
    return S, rhs, Vinv


def ba_backsub_ref(Vinv, eb, W, live, mrow, mpt, dcam):
    m = Vinv.shape[0]
    v = eb.copy()
    k = np.flatnonzero(live & (mrow >= 0))
    np.add.at(v, mpt[k], -np.einsum("kab,ka->kb", W[k], dcam.reshape(-1, 6)[mrow[k]]))
    return np.einsum("pab,pb->pa", Vinv, v).reshape(m, 3)


def ba_pair_script_ref(pt_start, order, mrow):
    """(r_a, r_b) of every free-camera pair sharing a point, in ``ba_schur``'s walk order."""
    pairs = []
    for p in range(len(pt_start) - 1):
        rows = mrow[order[pt_start[p] : pt_start[p + 1]]]
        rows = rows[rows >= 0]
        pairs += [(rows[a], rows[b]) for a in range(len(rows)) for b in range(a)]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def landmark_layout_ref(lm, cam, row, n_lm):
    """``landmark_layout`` by ``np.unique`` and ``np.lexsort``: ids, compact landmarks, order, starts, pair-walk
    entries and whether no camera measures a landmark twice."""
    ids, mlm = np.unique(lm, return_inverse=True)
    order = np.lexsort((row, mlm))
    start = np.concatenate([[0], np.cumsum(np.bincount(mlm, minlength=len(ids)))])
    free = np.bincount(mlm[row >= 0], minlength=len(ids))
    pairs = np.unique(np.c_[lm, cam], axis=0)
    return ids, mlm, order, start, int(np.sum(free * (free - 1) // 2)), len(pairs) == len(lm)
