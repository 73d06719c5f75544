"""Kernel: edgelets projected into one view, with their tracking Jacobians (Agility §4.2 eq. 3–5, §5.1 eq. 11).

One pass per edgelet does what ``edgelet_projection.project_edgelets`` describes: the centre in the camera frame
X_c and its projection c (eq. 3–4); the image direction d = ∂CamProj/∂X_c · R d_W, pixels per unit length along
the edgelet (eq. 5); the unit normal perp(d̂); and, when asked, the 1×6 Jacobian of the perpendicular distance
with respect to the camera pose (eq. 11), n̂ᵀ ∂CamProj/∂X_c [I | −[X_c]×] for T ← exp(μ) T, μ = (translation,
rotation). The tracker asks for all of them every frame for every edgelet of a keyframe's table, and the mapper
for the centres and normals of every edgelet it measures in a keyframe: as numpy, three projections with their
Jacobians and a dozen temporaries per call. The numpy reference is ``tests/reference/edgelet_projection.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac

MIN_IMAGE_DIRECTION = 1e-12  # |d| below this (an edgelet seen end-on) cannot be projected


@njit(nogil=True, cache=True, inline="always")
def perpendicular_row(nx, ny, J, X, Y, Z, row):
    """row (6,) = n̂ᵀ ∂CamProj/∂X_c · [I | −[X_c]×] (eq. 8, eq. 11) for unit image normal (nx, ny), the projection
    Jacobian J (2×3) at the camera-frame point (X, Y, Z); returns n̂ᵀJ, its first three entries."""
    g0 = nx * J[0, 0] + ny * J[1, 0]
    g1 = nx * J[0, 1] + ny * J[1, 1]
    g2 = nx * J[0, 2] + ny * J[1, 2]
    row[0] = g0
    row[1] = g1
    row[2] = g2
    row[3] = Y * g2 - Z * g1
    row[4] = Z * g0 - X * g2
    row[5] = X * g1 - Y * g0
    return g0, g1, g2


@njit(nogil=True, cache=True)
def edgelet_projection(cam, T, centre, direction, with_jacobian):
    """-> centre px (N, 2), direction d (N, 2) px per unit length, unit normal (N, 2) dark → light, valid (N,)
    (in front of the camera, in the lens's range, |d| > ``MIN_IMAGE_DIRECTION``), the camera-frame centres
    (N, 3) and, with ``with_jacobian``, the perpendicular Jacobians (N, 6) of eq. 11 (else (0, 6)). Rows that are
    not valid hold zeros where the projection is undefined (behind the camera)."""
    n = centre.shape[0]
    uv = np.zeros((n, 2))
    d = np.zeros((n, 2))
    normal = np.zeros((n, 2))
    valid = np.zeros(n, dtype=np.bool_)
    Xc = np.empty((n, 3))
    jac = np.zeros((n if with_jacobian else 0, 6))
    J = np.empty((2, 3))
    for i in range(n):
        X = T[0, 0] * centre[i, 0] + T[0, 1] * centre[i, 1] + T[0, 2] * centre[i, 2] + T[0, 3]
        Y = T[1, 0] * centre[i, 0] + T[1, 1] * centre[i, 1] + T[1, 2] * centre[i, 2] + T[1, 3]
        Z = T[2, 0] * centre[i, 0] + T[2, 1] * centre[i, 1] + T[2, 2] * centre[i, 2] + T[2, 3]
        Xc[i, 0] = X
        Xc[i, 1] = Y
        Xc[i, 2] = Z
        if Z <= 0.0:
            continue
        u, v, ok = project_jac(cam, X, Y, Z, J)
        if Z <= 1e-12:  # project_jac's own limit: nothing was written
            continue
        dx = T[0, 0] * direction[i, 0] + T[0, 1] * direction[i, 1] + T[0, 2] * direction[i, 2]
        dy = T[1, 0] * direction[i, 0] + T[1, 1] * direction[i, 1] + T[1, 2] * direction[i, 2]
        dz = T[2, 0] * direction[i, 0] + T[2, 1] * direction[i, 1] + T[2, 2] * direction[i, 2]
        du = J[0, 0] * dx + J[0, 1] * dy + J[0, 2] * dz
        dv = J[1, 0] * dx + J[1, 1] * dy + J[1, 2] * dz
        length = math.sqrt(du * du + dv * dv)
        uv[i, 0] = u
        uv[i, 1] = v
        d[i, 0] = du
        d[i, 1] = dv
        scale = 1.0 / length if length > MIN_IMAGE_DIRECTION else 1.0
        nx = -dv * scale  # perp(d) / |d|
        ny = du * scale
        normal[i, 0] = nx
        normal[i, 1] = ny
        valid[i] = ok and length > MIN_IMAGE_DIRECTION and math.isfinite(u) and math.isfinite(v)
        if with_jacobian:
            perpendicular_row(nx, ny, J, X, Y, Z, jac[i])
    return uv, d, normal, valid, Xc, jac
