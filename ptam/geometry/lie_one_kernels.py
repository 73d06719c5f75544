"""One rotation or rigid transform at a time: the exponential and logarithm of ``so3`` and ``se3`` for a single
element, with the same formulas, series and thresholds.

The batched numpy functions cost 50-240 µs for one 3×3 or 4×4 (a dozen small array operations each), and the
tracker calls them for one pose several times a frame (the motion model's update and prediction, the rotation
estimate); ``so3.exp``/``so3.log``/``se3.exp``/``se3.log`` hand a single element to these kernels. The batched
functions are their reference (``tests/test_geometry.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

SMALL = 1e-5  # so3.log: below this quaternion vector norm, the series of 2·atan2(|v|, w)/|v|
SERIES = 1e-2  # below this angle, the Taylor series of the Rodrigues and left-Jacobian coefficients


@njit(nogil=True, cache=True)
def rodrigues_coeffs(theta):
    """A = sin θ / θ, B = (1 − cos θ)/θ², C = (θ − sin θ)/θ³, as ``so3._rodrigues_coeffs``."""
    t2 = theta * theta
    t4 = t2 * t2
    if theta < SERIES:
        return (
            1.0 - t2 / 6.0 + t4 / 120.0 - t4 * t2 / 5040.0,
            0.5 - t2 / 24.0 + t4 / 720.0 - t4 * t2 / 40320.0,
            1.0 / 6.0 - t2 / 120.0 + t4 / 5040.0 - t4 * t2 / 362880.0,
        )
    s = math.sin(theta)
    h = math.sin(0.5 * theta)
    return s / theta, 2.0 * h * h / t2, (theta - s) / (t2 * theta)


@njit(nogil=True, cache=True, inline="always")
def _rotation_terms(w):
    """θ = |ω|, W = [ω]× and W² = W·W of a rotation vector ω (3,)."""
    theta = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    W = np.empty((3, 3))
    W[0, 0], W[0, 1], W[0, 2] = 0.0, -w[2], w[1]
    W[1, 0], W[1, 1], W[1, 2] = w[2], 0.0, -w[0]
    W[2, 0], W[2, 1], W[2, 2] = -w[1], w[0], 0.0
    W2 = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            W2[r, c] = W[r, 0] * W[0, c] + W[r, 1] * W[1, c] + W[r, 2] * W[2, c]
    return theta, W, W2


@njit(nogil=True, cache=True)
def so3_exp_one(w):
    """exp: (3,) -> (3, 3), Rodrigues' R = I + A·W + B·W² (``so3.exp``)."""
    theta, W, W2 = _rotation_terms(w)
    A, B, _ = rodrigues_coeffs(theta)
    R = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            R[r, c] = (1.0 if r == c else 0.0) + A * W[r, c] + B * W2[r, c]
    return R


@njit(nogil=True, cache=True)
def se3_exp_one(mu):
    """exp: (6,) μ = (translation, rotation) -> (4, 4), t = (I + B·W + C·W²)·v (``se3.exp``)."""
    theta, W, W2 = _rotation_terms(mu[3:])
    A, B, C = rodrigues_coeffs(theta)
    T = np.zeros((4, 4))
    for r in range(3):
        t = 0.0
        for c in range(3):
            one = 1.0 if r == c else 0.0
            T[r, c] = one + A * W[r, c] + B * W2[r, c]
            t += (one + B * W[r, c] + C * W2[r, c]) * mu[c]
        T[r, 3] = t
    T[3, 3] = 1.0
    return T


@njit(nogil=True, cache=True)
def to_quaternion_one(R):
    """(x, y, z, w), w ≥ 0, unit, by Shepperd's method on the largest of the four candidates (``so3.to_quaternion``)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    k = 0
    best = tr
    for i in range(3):
        if R[i, i] > best:  # np.argmax: the first of equal maxima
            best = R[i, i]
            k = i + 1
    q = np.empty(4)
    if k == 0:
        s = math.sqrt(max(1.0 + tr, 0.0)) * 2.0
        q[0], q[1], q[2], q[3] = (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s, 0.25 * s
    elif k == 1:
        s = math.sqrt(max(1.0 + R[0, 0] - R[1, 1] - R[2, 2], 0.0)) * 2.0
        q[0], q[1], q[2], q[3] = 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s, (R[2, 1] - R[1, 2]) / s
    elif k == 2:
        s = math.sqrt(max(1.0 + R[1, 1] - R[0, 0] - R[2, 2], 0.0)) * 2.0
        q[0], q[1], q[2], q[3] = (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s, (R[0, 2] - R[2, 0]) / s
    else:
        s = math.sqrt(max(1.0 + R[2, 2] - R[0, 0] - R[1, 1], 0.0)) * 2.0
        q[0], q[1], q[2], q[3] = (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s, (R[1, 0] - R[0, 1]) / s
    if q[3] < 0.0:
        q[:] = -q
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return q / n


@njit(nogil=True, cache=True)
def so3_log_one(R):
    """log: (3, 3) -> (3,), angle in [0, π], through the unit quaternion (``so3.log``)."""
    q = to_quaternion_one(R)
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
    w = q[3]
    factor = 2.0 / w * (1.0 - n * n / (3.0 * w * w)) if n < SMALL else 2.0 * math.atan2(n, w) / n
    return q[:3] * factor


@njit(nogil=True, cache=True)
def se3_log_one(T):
    """log: (4, 4) -> (6,) μ = (translation, rotation), v = V(ω)⁻¹·t with V⁻¹ = I − ½W + D·W² (``se3.log``)."""
    w = so3_log_one(T[:3, :3])
    theta, W, W2 = _rotation_terms(w)
    t2 = theta * theta
    if theta < SERIES:
        D = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2**3 / 1209600.0
    else:
        D = (1.0 - 0.5 * theta / math.tan(0.5 * theta)) / t2
    mu = np.empty(6)
    for r in range(3):
        v = 0.0
        for c in range(3):
            v += ((1.0 if r == c else 0.0) - 0.5 * W[r, c] + D * W2[r, c]) * T[c, 3]
        mu[r] = v
        mu[3 + r] = w[r]
    return mu


@njit(nogil=True, cache=True)
def se3_exp_left(mu, T, out):
    """out[i] = exp(μ_i)·T[i] for μ (N, 6) and T (N, 4, 4): PTAM's left-multiplied update of N poses, one at a
    time (``se3.exp(mu) @ T``, whose numpy batch costs about 0.2 ms for a handful of poses)."""
    for i in range(mu.shape[0]):
        E = se3_exp_one(mu[i])
        for r in range(4):
            for c in range(4):
                out[i, r, c] = E[r, 0] * T[i, 0, c] + E[r, 1] * T[i, 1, c] + E[r, 2] * T[i, 2, c] + E[r, 3] * T[i, 3, c]
