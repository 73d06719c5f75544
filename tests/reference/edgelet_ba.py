"""numpy reference for ``ptam.edgelet.edgelet_ba_kernels`` (Agility §4.4), built on the numpy camera models."""

from __future__ import annotations

import numpy as np

from ptam.edgelet import EDGELET_DOF, Edgelets
from ptam.geometry import se3


def edgelet_ba_terms_ref(camera, poses, frames, mkf, medg, line_a, line_n, along):
    T = poses[mkf]  # (M, 4, 4)
    E = frames[medg]
    m = len(mkf)
    Xw = E[:, None, :3, 3] + along[:, :, None] * E[:, None, :3, 2]  # (M, 2, 3)
    Xc = np.einsum("mij,msj->msi", T[:, :3, :3], Xw) + T[:, None, :3, 3]
    front = Xc[..., 2] > 0
    Xs = np.where(front[..., None], Xc, 1.0)
    uv = camera.project(Xs.reshape(-1, 3)).reshape(m, 2, 2)
    J = camera.project_jacobian(Xs.reshape(-1, 3)).reshape(m, 2, 2, 3)
    err = np.einsum("mi,msi->ms", line_n, uv - line_a[:, None, :])
    g = np.einsum("mi,msij->msj", line_n, J)  # (M, 2, 3)
    Jp = np.concatenate([g, np.cross(Xs, g)], axis=-1)
    R = np.einsum("mij,mjk->mik", T[:, :3, :3], E[:, :3, :3])  # edgelet axes in the camera frame
    gx = np.einsum("msi,mi->ms", g, R[:, :, 0])
    gy = np.einsum("msi,mi->ms", g, R[:, :, 1])
    Je = np.stack([gx, gy, -along * gy, along * gx], axis=-1)
    valid = front.all(axis=1)
    z = ~front
    err[z], Jp[z], Je[z] = 0.0, 0.0, 0.0
    return err, Jp, Je, valid


def edgelets_updated_ref(ed, mu):
    """E_WE ← E_WE · exp(μ) for μ (N, 4) = (t_x, t_y, ω_x, ω_y) in each edgelet's frame, re-orthonormalised
    (``Edgelets.updated``): numpy's batched SE(3) exponential and Gram–Schmidt."""
    mu6 = np.zeros((len(ed), 6))
    mu6[:, EDGELET_DOF] = mu
    return Edgelets.from_frames(ed.frames() @ se3.exp(mu6))


def refine_edgelets_ref(camera, poses, ed, obs, along, iterations):
    """Structure-only Gauss–Newton (``edgelet_refine_kernels.refine_frames``) in numpy: the normal equations from
    the reference terms, numpy's batched eigenvalues for the condition test and its batched solve."""
    n = len(ed)
    m_hat = np.stack([-obs.b[:, 1], obs.b[:, 0]], axis=1) / np.linalg.norm(obs.b, axis=1, keepdims=True)
    for _ in range(iterations):
        err, _, Je, valid = edgelet_ba_terms_ref(camera, poses, ed.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along)
        H = np.zeros((n, 4, 4))
        g = np.zeros((n, 4))
        np.add.at(H, obs.edgelet[valid], np.einsum("msi,msj->mij", Je, Je)[valid])
        np.add.at(g, obs.edgelet[valid], np.einsum("msi,ms->mi", Je, err)[valid])
        count = np.bincount(obs.edgelet[valid], minlength=n)
        lam = np.abs(np.linalg.eigvalsh(H))
        ok = (count >= 2) & (lam.min(axis=1) * (1.0 / np.finfo(np.float64).eps) > lam.max(axis=1))
        mu = np.zeros((n, 4))
        mu[ok] = -np.linalg.solve(H[ok], g[ok][..., None])[..., 0]
        ed = edgelets_updated_ref(ed, mu)
    return ed
