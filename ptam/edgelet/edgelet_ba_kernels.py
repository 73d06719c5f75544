"""Kernel: edgelet bundle-adjustment residuals and Jacobians (Agility §4.4, eq. 6–9, Fig. 3).

Each keyframe measurement of an edgelet is an image line through ``a`` with unit normal m̂ (perpendicular to
the measured direction b). Two virtual sample points sit on the edgelet's z-axis at p_nE = (0, 0, z_n)
(eq. 6: z_n = ∓5/|d| in the edgelet frame, placed by the caller and fixed while it evaluates), project to
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

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac
from ..geometry.se3_kernels import se3_exp_into
from .edgelet_projection_kernels import perpendicular_row


@njit(nogil=True, cache=True, inline="always")
def axis_in_camera(T, E):
    """The edgelet's centre and its direction (the E-frame z-axis) in the frame of pose T: the sample point at
    E-frame z is centre + z·direction."""
    return (
        T[0, 0] * E[0, 3] + T[0, 1] * E[1, 3] + T[0, 2] * E[2, 3] + T[0, 3],
        T[1, 0] * E[0, 3] + T[1, 1] * E[1, 3] + T[1, 2] * E[2, 3] + T[1, 3],
        T[2, 0] * E[0, 3] + T[2, 1] * E[1, 3] + T[2, 2] * E[2, 3] + T[2, 3],
        T[0, 0] * E[0, 2] + T[0, 1] * E[1, 2] + T[0, 2] * E[2, 2],
        T[1, 0] * E[0, 2] + T[1, 1] * E[1, 2] + T[1, 2] * E[2, 2],
        T[2, 0] * E[0, 2] + T[2, 1] * E[1, 2] + T[2, 2] * E[2, 2],
    )


@njit(nogil=True, cache=True, inline="always")
def measurement_rows(cam, T, E, z2, a, n, J, jp, je, r):
    """One measurement's residuals r (2,) px and Jacobian rows jp (2, 6), je (2, 4) for pose T, edgelet frame E,
    sample points at E-frame z2 (2,) and the measured line through a with normal n (unit in an image; on the
    normalised plane of ``bundle_edgelets.plane_camera`` m̂ᵀL, so that r is in pixels); False (and nothing
    written) when a sample point is behind the camera. Inlined: called, the BA's rows loop took 1.9x as long
    (numba 0.68)."""
    cx, cy, cz, dx, dy, dz = axis_in_camera(T, E)
    if cz + z2[0] * dz <= 0.0 or cz + z2[1] * dz <= 0.0:
        return False
    # The edgelet's x- and y-axes in the camera frame.
    xc0 = T[0, 0] * E[0, 0] + T[0, 1] * E[1, 0] + T[0, 2] * E[2, 0]
    xc1 = T[1, 0] * E[0, 0] + T[1, 1] * E[1, 0] + T[1, 2] * E[2, 0]
    xc2 = T[2, 0] * E[0, 0] + T[2, 1] * E[1, 0] + T[2, 2] * E[2, 0]
    yc0 = T[0, 0] * E[0, 1] + T[0, 1] * E[1, 1] + T[0, 2] * E[2, 1]
    yc1 = T[1, 0] * E[0, 1] + T[1, 1] * E[1, 1] + T[1, 2] * E[2, 1]
    yc2 = T[2, 0] * E[0, 1] + T[2, 1] * E[1, 1] + T[2, 2] * E[2, 1]
    for s in range(2):
        z = z2[s]
        X = cx + z * dx
        Y = cy + z * dy
        Z = cz + z * dz
        u, v, _ = project_jac(cam, X, Y, Z, J)
        r[s] = n[0] * (u - a[0]) + n[1] * (v - a[1])
        g0, g1, g2 = perpendicular_row(n[0], n[1], J, X, Y, Z, jp[s])
        gx = g0 * xc0 + g1 * xc1 + g2 * xc2
        gy = g0 * yc0 + g1 * yc1 + g2 * yc2
        je[s, 0] = gx
        je[s, 1] = gy
        je[s, 2] = -z * gy
        je[s, 3] = z * gx
    return True


@njit(nogil=True, cache=True)
def edgelet_ba_terms(cam, poses, frames, mkf, medg, line_a, line_n, along):
    """-> err (M, 2), Jp (M, 2, 6), Je (M, 2, 4), valid (M,) for measurements (keyframe ``mkf``, edgelet
    ``medg``) of lines (a, unit normal) with sample points at E-frame z = ``along`` (M, 2); an invalid
    measurement's terms are zero."""
    m = mkf.shape[0]
    err = np.zeros((m, 2))
    Jp = np.zeros((m, 2, 6))
    Je = np.zeros((m, 2, 4))
    valid = np.empty(m, dtype=np.bool_)
    J = np.empty((2, 3))
    for k in range(m):
        T = poses[mkf[k]]
        E = frames[medg[k]]
        valid[k] = measurement_rows(cam, T, E, along[k], line_a[k], line_n[k], J, Jp[k], Je[k], err[k])
    return err, Jp, Je, valid


@njit(nogil=True, cache=True)
def edgelet_normal_equations(cam, poses, frames, mkf, medg, line_a, line_n, along, n):
    """The edgelet blocks of the normal equations with the poses fixed: Σ JᵀJ (n, 4, 4) and Σ Jᵀε (n, 4) over
    each edgelet's valid measurements (as ``edgelet_ba_terms`` has them), and how many there are (n,)."""
    H = np.zeros((n, 4, 4))
    g = np.zeros((n, 4))
    count = np.zeros(n, dtype=np.int64)
    J = np.empty((2, 3))
    jp = np.empty((2, 6))
    je = np.empty((2, 4))
    r = np.empty(2)
    for k in range(mkf.shape[0]):
        if not measurement_rows(cam, poses[mkf[k]], frames[medg[k]], along[k], line_a[k], line_n[k], J, jp, je, r):
            continue
        e = medg[k]
        count[e] += 1
        for s in range(2):
            for a in range(4):
                g[e, a] += je[s, a] * r[s]
                for b in range(4):
                    H[e, a, b] += je[s, a] * je[s, b]
    return H, g, count


@njit(nogil=True, cache=True, inline="always")
def _set_frame(z0, z1, z2, x0, x1, x2, c0, c1, c2, out):
    """``out`` (4, 4) = the frame at centre c with direction z and normal x made orthonormal as
    ``Edgelets.orthonormalised`` does: z normalised, x made perpendicular to it and normalised, y = z × x."""
    zn = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
    z0, z1, z2 = z0 / zn, z1 / zn, z2 / zn
    xz = x0 * z0 + x1 * z1 + x2 * z2
    x0, x1, x2 = x0 - xz * z0, x1 - xz * z1, x2 - xz * z2
    xn = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 / xn, x1 / xn, x2 / xn
    out[:] = 0.0
    out[0, 0], out[1, 0], out[2, 0] = x0, x1, x2
    out[0, 1], out[1, 1], out[2, 1] = z1 * x2 - z2 * x1, z2 * x0 - z0 * x2, z0 * x1 - z1 * x0
    out[0, 2], out[1, 2], out[2, 2] = z0, z1, z2
    out[0, 3], out[1, 3], out[2, 3] = c0, c1, c2
    out[3, 3] = 1.0


@njit(nogil=True, cache=True)
def frames_of(centre, direction, normal, ids, out):
    """E_WE (len(ids), 4, 4) of the edgelets ``ids``, orthonormalised (``Edgelets.orthonormalised().frames()``)."""
    for i in range(ids.shape[0]):
        e = ids[i]
        z, x, c = direction[e], normal[e], centre[e]
        _set_frame(z[0], z[1], z[2], x[0], x[1], x[2], c[0], c[1], c[2], out[i])


@njit(nogil=True, cache=True)
def frames_updated(F, de, out):
    """E_WE ← E_WE · exp(μ) for μ = (t_x, t_y, ω_x, ω_y) (E, 4) in each edgelet's own frame (eq. 9), written to
    ``out`` (E, 4, 4) re-orthonormalised (``_set_frame``)."""
    mu = np.zeros(6)
    X = np.empty((4, 4))
    M = np.zeros((4, 4))
    for e in range(F.shape[0]):
        mu[0] = de[e, 0]
        mu[1] = de[e, 1]
        mu[3] = de[e, 2]
        mu[4] = de[e, 3]
        se3_exp_into(mu, X)
        for r in range(3):
            for c in range(4):
                M[r, c] = F[e, r, 0] * X[0, c] + F[e, r, 1] * X[1, c] + F[e, r, 2] * X[2, c]
            M[r, 3] += F[e, r, 3]
        _set_frame(M[0, 2], M[1, 2], M[2, 2], M[0, 0], M[1, 0], M[2, 0], M[0, 3], M[1, 3], M[2, 3], out[e])
