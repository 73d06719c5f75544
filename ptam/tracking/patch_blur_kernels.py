"""Kernel: the expected motion blur of point patches (Agility §5.1 eq. 10 applied to points, ``patch_blur``).

Per feature: X_c = R X + w t and its image motion ∂CamProj/∂X_c · (w δt + δω × X_c) under the exposure motion
γ_C = (δt, δω), in level-0 pixels: the smear of its patch, whose length is the blur. The tracker evaluates it
every frame for every potentially visible point; as numpy that was a projection Jacobian, a point Jacobian and an
einsum over all of them. The numpy reference is ``tests/reference/patch_blur.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac


@njit(nogil=True, cache=True)
def patch_smears(cam, T, X, w, gamma):
    """-> smear (N, 2) level-0 px of homogeneous features (X (N, 3), w (N,)) seen from pose T under the exposure
    motion ``gamma`` (6,) = (translation, rotation); +inf for a feature at or behind the camera centre."""
    n = X.shape[0]
    smear = np.empty((n, 2))
    J = np.empty((2, 3))
    for i in range(n):
        x = T[0, 0] * X[i, 0] + T[0, 1] * X[i, 1] + T[0, 2] * X[i, 2] + w[i] * T[0, 3]
        y = T[1, 0] * X[i, 0] + T[1, 1] * X[i, 1] + T[1, 2] * X[i, 2] + w[i] * T[1, 3]
        z = T[2, 0] * X[i, 0] + T[2, 1] * X[i, 1] + T[2, 2] * X[i, 2] + w[i] * T[2, 3]
        if z <= 1e-12:
            smear[i, 0] = np.inf
            smear[i, 1] = np.inf
            continue
        project_jac(cam, x, y, z, J)
        # The point's motion: w·δt + δω × X_c (a ray, w = 0, does not move with the camera's translation).
        mx = w[i] * gamma[0] + gamma[4] * z - gamma[5] * y
        my = w[i] * gamma[1] + gamma[5] * x - gamma[3] * z
        mz = w[i] * gamma[2] + gamma[3] * y - gamma[4] * x
        smear[i, 0] = J[0, 0] * mx + J[0, 1] * my + J[0, 2] * mz
        smear[i, 1] = J[1, 0] * mx + J[1, 1] * my + J[1, 2] * mz
    return smear
