"""numpy reference for ``ptam.edgelet.edgelet_ba_kernels`` (Agility §4.4), built on the numpy camera models."""

from __future__ import annotations

import numpy as np


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
