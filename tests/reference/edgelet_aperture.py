"""numpy references for ``ptam.mapping.edgelet_aperture_kernels`` (Agility §4.3): every keyframe × candidate as
arrays."""

from __future__ import annotations

import numpy as np


def aperture_problem_ref(Xk, D, C, min_deg):
    n_k = np.cross(D, Xk)  # k's centre is the origin
    n_j = np.cross(D[None], Xk[None] - C[:, None, :])
    sin = np.linalg.norm(np.cross(n_k[None], n_j), axis=-1)
    norm = np.linalg.norm(n_k, axis=-1)[None] * np.linalg.norm(n_j, axis=-1)
    return sin < np.sin(np.deg2rad(min_deg)) * np.maximum(norm, np.finfo(float).tiny)


def aperture_free_ref(camera, T_jk, C, Xk, D, min_deg, border):
    Xj = np.einsum("kij,nj->kni", T_jk[:, :3, :3], Xk) + T_jk[:, None, :3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        seen = camera.valid(Xj.reshape(-1, 3)) & camera.in_image(camera.project(Xj.reshape(-1, 3)), border)
    return seen.reshape(len(T_jk), len(Xk)) & ~aperture_problem_ref(Xk, D, C, min_deg)
