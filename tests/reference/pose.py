"""numpy references for ``ptam.tracking.pose_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.geometry import se3
from ptam.geometry.tukey_kernels import MAD_TO_SIGMA, TUKEY_C


def tukey_sigma_sq_ref(err_sq, min_sigma):
    err_sq = np.sort(np.asarray(err_sq, dtype=np.float64))
    n = len(err_sq)
    if n == 0:
        return min_sigma**2
    c = TUKEY_C * MAD_TO_SIGMA * (1.0 + 5.0 / max(2 * n - 6, 1)) * np.sqrt(err_sq[n // 2])
    return max(c * c, min_sigma**2)


def information_ref(inv_sigma, smear):
    """Each measurement's 2×2 information σ⁻²·(I − a·aᵀ)."""
    return inv_sigma[:, None, None] ** 2 * (np.eye(2) - np.einsum("na,nb->nab", smear, smear))


def normal_equations_ref(J, r, inv_sigma, smear, w):
    info = w[:, None, None] * information_ref(inv_sigma, smear)
    return np.einsum("nai,nab,nbj->ij", J, info, J), np.einsum("nai,nab,nb->i", J, info, r)


def pose_irls_ref(
    camera,
    T_cw,
    X,
    Xw,
    meas,
    inv_sigma,
    smear,
    n_iters,
    relinearise_every,
    min_sigma,
    prior,
    override_after,
    override_sigma_sq,
    c_ref,
    t_max,
):
    """Numpy reference of :func:`pose_irls` on a :class:`~ptam.camera.model.CameraModel`: the edgelet reference
    without edgelets."""
    args = (min_sigma, prior, override_after, override_sigma_sq, c_ref, t_max)
    none = np.zeros((0, 3))
    T, w, _ = pose_irls_edgelets_ref(
        camera,
        T_cw,
        X,
        Xw,
        meas,
        inv_sigma,
        smear,
        none,
        none[:, :2],
        none[:, :2],
        np.zeros(0),
        n_iters,
        relinearise_every,
        *args,
    )
    return T, w


def pose_irls_edgelets_ref(
    camera,
    T_cw,
    X,
    Xw,
    meas,
    inv_sigma,
    smear,
    E,
    e_meas,
    e_normal,
    e_inv_sigma,
    n_iters,
    relinearise_every,
    min_sigma,
    prior,
    override_after,
    override_sigma_sq,
    c_ref,
    t_max,
):
    """Numpy reference of :func:`pose_irls_edgelets`: points and edgelets (perpendicular distances) in one IRLS."""
    T = np.array(T_cw, dtype=np.float64)
    mu = np.zeros(6)
    P = np.concatenate([X, E])
    Pw = np.concatenate([Xw, np.ones(len(E))])
    n = len(X)
    uv = J = valid = w = None
    for it in range(n_iters):
        if it % relinearise_every == 0 or it == n_iters - 1:
            Pc = P @ T[:3, :3].T + Pw[:, None] * T[:3, 3]
            valid = Pc[:, 2] > 1e-12
            uv = np.zeros((len(P), 2))
            J = np.zeros((len(P), 2, 6))
            uv[valid] = camera.project(Pc[valid])
            dPc = se3.point_jacobian(Pc[valid])
            dPc[:, :, :3] *= Pw[valid, None, None]
            J[valid] = camera.project_jacobian(Pc[valid]) @ dPc
        else:
            uv = uv + J @ mu
        r = meas - uv[:n]
        er = np.sum(e_normal * (e_meas - uv[n:]), axis=1)
        je = np.einsum("ma,mab->mb", e_normal, J[n:])
        e2 = np.concatenate(
            [np.einsum("na,nab,nb->n", r, information_ref(inv_sigma, smear), r), er**2 * e_inv_sigma**2]
        )
        if not valid.any():
            break
        c2 = tukey_sigma_sq_ref(e2[valid], min_sigma)
        if override_sigma_sq > 0 and it > override_after:
            c2 = min(c2, override_sigma_sq)
        w = np.where(valid & (e2 <= c2), (1.0 - e2 / c2) ** 2, 0.0)
        H, g = normal_equations_ref(J[:n], r, inv_sigma, smear, w[:n])
        we = w[n:] * e_inv_sigma**2
        H = H + np.einsum("m,ma,mb->ab", we, je, je)
        g = g + np.einsum("m,ma,m->a", we, je, er)
        mu = np.linalg.solve(H + prior * np.eye(6), g)
        T = se3.exp(mu) @ T
        if t_max >= 0:
            c = -T[:3, :3].T @ T[:3, 3]
            d = np.linalg.norm(c - c_ref)
            if d > t_max:
                T[:3, 3] = -T[:3, :3] @ (c_ref + (c - c_ref) * t_max / d)
    if w is None:
        return T, np.zeros(n), np.zeros(len(E))
    return T, w[:n], w[n:]
