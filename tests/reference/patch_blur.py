"""numpy reference for ``ptam.tracking.patch_blur_kernels`` (Agility §5.1 eq. 10 for point patches)."""

from __future__ import annotations

import numpy as np

from ptam.geometry import se3


def patch_blur_ref(camera, T_cw, X, w, gamma):
    Xc = X @ T_cw[:3, :3].T + w[:, None] * T_cw[:3, 3]
    J = se3.point_jacobian(Xc)
    J[:, :, :3] *= w[:, None, None]
    motion = np.einsum("nij,njk,k->ni", camera.project_jacobian(Xc), J, np.asarray(gamma, dtype=np.float64))
    return np.linalg.norm(motion, axis=1)
