"""numpy references for ``ptam.patch.warp_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.patch.warp_kernels import RULE_CLOSEST


def warp_matrices_ref(camera, T_cw, Xc, right_W, down_W, n_levels, det_min, det_max, rule):
    """Numpy reference of :func:`warp_matrices` on a :class:`~ptam.camera.model.CameraModel`."""
    J = camera.project_jacobian(Xc)
    R = T_cw[:3, :3]
    A = np.stack([np.einsum("nij,nj->ni", J, right_W @ R.T), np.einsum("nij,nj->ni", J, down_W @ R.T)], axis=-1)
    det = np.linalg.det(A)
    pos = det > 0
    logd = np.log(np.where(pos, det, 1.0)) / np.log(4.0)
    if rule == RULE_CLOSEST:
        level = np.clip(np.floor(logd + 0.5), 0, n_levels - 1).astype(np.int32)
    else:
        need = np.ceil(np.log(np.where(pos, det, 1.0) / det_max) / np.log(4.0) - 1e-12)
        level = np.clip(need, 0, n_levels - 1).astype(np.int32)
    d = det / 4.0**level
    level[~pos | (d < det_min) | (d > det_max)] = -1
    return A, det, level
