"""Kernel: edgelet bundle-adjustment residuals and Jacobians (Agility §4.4, eq. 6–9, Fig. 3).

Each keyframe measurement of an edgelet is an image line through ``a`` with unit normal m̂ (perpendicular to
the measured direction b). Two virtual sample points sit on the edgelet's z-axis at p_nE = (0, 0, z_n)
(eq. 6: z_n = ∓5/|d| in the edgelet frame, computed once by the caller and then fixed), project to
s_n = CamProj(E_KW E_WE p_nE), and the residual is their perpendicular distance from the measured line,
ε_n = m̂ · (s_n − a), in pixels.

Eq. 7 measures that distance along the projected edgelet normal n̂ instead of the line's own normal m̂; the two
agree to first order (they differ by the cosine of the angle between the lines, 1 at convergence), and with
m̂ the Jacobians of eq. 8–9, m̂ᵀ ∂s_n/∂μ, are exact:

* keyframe pose, T_KW ← exp(μ_K) T_KW, μ = (translation, rotation): ∂s/∂μ_K = J_proj [I | −[X_K]×];
* edgelet, E_WE ← E_WE exp(μ_E), μ_E = (t_x, t_y, ω_x, ω_y): the point moves by R_KW R_WE (e_x, e_y, −z e_y, z e_x).

Outputs err (M, 2), Jp (M, 2, 6), Je (M, 2, 4) and valid (M,) = both sample points in front of the camera.
The numpy reference is ``tests/reference/edgelet_ba.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac


@njit(nogil=True, cache=True)
def edgelet_ba_terms(cam, poses, frames, mkf, medg, line_a, line_n, along):
    """-> err (M, 2), Jp (M, 2, 6), Je (M, 2, 4), valid (M,) for measurements (keyframe ``mkf``, edgelet
    ``medg``) of lines (a, unit normal) with sample points at E-frame z = ``along`` (M, 2)."""
    m = mkf.shape[0]
    err = np.zeros((m, 2))
    Jp = np.zeros((m, 2, 6))
    Je = np.zeros((m, 2, 4))
    valid = np.ones(m, dtype=np.bool_)
    J = np.empty((2, 3))
    for k in range(m):
        T = poses[mkf[k]]
        E = frames[medg[k]]
        nx = line_n[k, 0]
        ny = line_n[k, 1]
        # The edgelet's x- and y-axes in the camera frame.
        xc0 = T[0, 0] * E[0, 0] + T[0, 1] * E[1, 0] + T[0, 2] * E[2, 0]
        xc1 = T[1, 0] * E[0, 0] + T[1, 1] * E[1, 0] + T[1, 2] * E[2, 0]
        xc2 = T[2, 0] * E[0, 0] + T[2, 1] * E[1, 0] + T[2, 2] * E[2, 0]
        yc0 = T[0, 0] * E[0, 1] + T[0, 1] * E[1, 1] + T[0, 2] * E[2, 1]
        yc1 = T[1, 0] * E[0, 1] + T[1, 1] * E[1, 1] + T[1, 2] * E[2, 1]
        yc2 = T[2, 0] * E[0, 1] + T[2, 1] * E[1, 1] + T[2, 2] * E[2, 1]
        for s in range(2):
            z = along[k, s]
            wx = E[0, 3] + z * E[0, 2]
            wy = E[1, 3] + z * E[1, 2]
            wz = E[2, 3] + z * E[2, 2]
            X = T[0, 0] * wx + T[0, 1] * wy + T[0, 2] * wz + T[0, 3]
            Y = T[1, 0] * wx + T[1, 1] * wy + T[1, 2] * wz + T[1, 3]
            Z = T[2, 0] * wx + T[2, 1] * wy + T[2, 2] * wz + T[2, 3]
            if Z <= 0.0:
                valid[k] = False
                continue
            u, v, _ = project_jac(cam, X, Y, Z, J)
            err[k, s] = nx * (u - line_a[k, 0]) + ny * (v - line_a[k, 1])
            g0 = nx * J[0, 0] + ny * J[1, 0]
            g1 = nx * J[0, 1] + ny * J[1, 1]
            g2 = nx * J[0, 2] + ny * J[1, 2]
            Jp[k, s, 0] = g0
            Jp[k, s, 1] = g1
            Jp[k, s, 2] = g2
            Jp[k, s, 3] = Y * g2 - Z * g1  # X_K × g
            Jp[k, s, 4] = Z * g0 - X * g2
            Jp[k, s, 5] = X * g1 - Y * g0
            gx = g0 * xc0 + g1 * xc1 + g2 * xc2
            gy = g0 * yc0 + g1 * yc1 + g2 * yc2
            Je[k, s, 0] = gx
            Je[k, s, 1] = gy
            Je[k, s, 2] = -z * gy
            Je[k, s, 3] = z * gx
    return err, Jp, Je, valid
