"""numpy references for ``ptam.tracking.pose_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.geometry import se3
from ptam.tracking.pose_kernels import MAD_TO_SIGMA, TUKEY_C


def tukey_sigma_sq_ref(err_sq, min_sigma):
    err_sq = np.sort(np.asarray(err_sq, dtype=np.float64))
    n = len(err_sq)
    if n == 0:
        return min_sigma**2
    c = TUKEY_C * MAD_TO_SIGMA * (1.0 + 5.0 / max(2 * n - 6, 1)) * np.sqrt(err_sq[n // 2])
    return max(c * c, min_sigma**2)


def normal_equations_ref(J, r, inv_sigma, w):
    ws = w * inv_sigma**2
    return np.einsum("n,nai,naj->ij", ws, J, J), np.einsum("n,nai,na->i", ws, J, r)


def pose_irls_ref(
    camera, T_cw, X, meas, inv_sigma, n_iters, relinearise_every, min_sigma, prior, override_after, override_sigma_sq
):
    """Numpy reference of :func:`pose_irls` on a :class:`~ptam.camera.model.CameraModel`."""
    T = np.array(T_cw, dtype=np.float64)
    mu = np.zeros(6)
    uv = J = valid = w = None
    for it in range(n_iters):
        if it % relinearise_every == 0 or it == n_iters - 1:
            Xc = se3.transform(T, X)
            valid = Xc[:, 2] > 1e-12
            uv = np.zeros((len(X), 2))
            J = np.zeros((len(X), 2, 6))
            uv[valid] = camera.project(Xc[valid])
            J[valid] = camera.project_jacobian(Xc[valid]) @ se3.point_jacobian(Xc[valid])
        else:
            uv = uv + J @ mu
        r = meas - uv
        e2 = (r**2).sum(axis=1) * inv_sigma**2
        if not valid.any():
            break
        c2 = tukey_sigma_sq_ref(e2[valid], min_sigma)
        if override_sigma_sq > 0 and it > override_after:
            c2 = min(c2, override_sigma_sq)
        w = np.where(valid & (e2 <= c2), (1.0 - e2 / c2) ** 2, 0.0)
        H, g = normal_equations_ref(J, r, inv_sigma, w)
        mu = np.linalg.solve(H + prior * np.eye(6), g)
        T = se3.exp(mu) @ T
    return T, (np.zeros(len(X)) if w is None else w)
