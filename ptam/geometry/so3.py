"""SO(3) exponential and logarithm, batched over leading axes.

Rotation vectors are axis * angle. Both maps are accurate to machine precision near 0 and near π:
the log goes through a unit quaternion (Shepperd's method), whose atan2 form has no singularity.
"""

from __future__ import annotations

import numpy as np

from .lie_one_kernels import SERIES as _SERIES
from .lie_one_kernels import SMALL as _SMALL
from .lie_one_kernels import so3_exp_one, so3_log_one


def hat(w: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices of vectors (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, dtype=np.float64)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def vee(W: np.ndarray) -> np.ndarray:
    """Inverse of :func:`hat`: (..., 3, 3) -> (..., 3)."""
    W = np.asarray(W, dtype=np.float64)
    return np.stack([W[..., 2, 1], W[..., 0, 2], W[..., 1, 0]], axis=-1)


def _rodrigues_coeffs(theta: np.ndarray):
    """A = sin θ / θ, B = (1 − cos θ)/θ², C = (θ − sin θ)/θ³.

    Below θ = 1e-2 the Taylor series (to θ⁶, truncation < 1e-19) replaces the closed forms, whose
    cancellations would otherwise cost up to six digits of B and C near θ = 1e-5.
    """
    t2 = theta * theta
    t4 = t2 * t2
    small = theta < _SERIES
    ts = np.where(small, 1.0, theta)
    A = np.where(small, 1.0 - t2 / 6.0 + t4 / 120.0 - t4 * t2 / 5040.0, np.sin(ts) / ts)
    B = np.where(small, 0.5 - t2 / 24.0 + t4 / 720.0 - t4 * t2 / 40320.0, 2.0 * np.sin(0.5 * ts) ** 2 / (ts * ts))
    C = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t4 / 5040.0 - t4 * t2 / 362880.0, (ts - np.sin(ts)) / (ts**3))
    return A, B, C


def exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices from rotation vectors (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, dtype=np.float64)
    if w.shape == (3,):
        return so3_exp_one(w)
    theta = np.linalg.norm(w, axis=-1)
    A, B, _ = _rodrigues_coeffs(theta)
    W = hat(w)
    eye = np.broadcast_to(np.eye(3), W.shape)
    return eye + A[..., None, None] * W + B[..., None, None] * (W @ W)


def to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) as (x, y, z, w) with w >= 0, by Shepperd's method."""
    R = np.asarray(R, dtype=np.float64)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    cand = np.stack([tr, R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], axis=-1)
    k = np.argmax(cand, axis=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # Each branch divides by the largest of the four candidate magnitudes, so it is well conditioned.
    s0 = np.sqrt(np.maximum(1.0 + tr, 0.0)) * 2.0
    s1 = np.sqrt(np.maximum(1.0 + R[..., 0, 0] - R[..., 1, 1] - R[..., 2, 2], 0.0)) * 2.0
    s2 = np.sqrt(np.maximum(1.0 + R[..., 1, 1] - R[..., 0, 0] - R[..., 2, 2], 0.0)) * 2.0
    s3 = np.sqrt(np.maximum(1.0 + R[..., 2, 2] - R[..., 0, 0] - R[..., 1, 1], 0.0)) * 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        b0 = np.stack(
            [
                (R[..., 2, 1] - R[..., 1, 2]) / s0,
                (R[..., 0, 2] - R[..., 2, 0]) / s0,
                (R[..., 1, 0] - R[..., 0, 1]) / s0,
                0.25 * s0,
            ],
            axis=-1,
        )
        b1 = np.stack(
            [
                0.25 * s1,
                (R[..., 0, 1] + R[..., 1, 0]) / s1,
                (R[..., 0, 2] + R[..., 2, 0]) / s1,
                (R[..., 2, 1] - R[..., 1, 2]) / s1,
            ],
            axis=-1,
        )
        b2 = np.stack(
            [
                (R[..., 0, 1] + R[..., 1, 0]) / s2,
                0.25 * s2,
                (R[..., 1, 2] + R[..., 2, 1]) / s2,
                (R[..., 0, 2] - R[..., 2, 0]) / s2,
            ],
            axis=-1,
        )
        b3 = np.stack(
            [
                (R[..., 0, 2] + R[..., 2, 0]) / s3,
                (R[..., 1, 2] + R[..., 2, 1]) / s3,
                0.25 * s3,
                (R[..., 1, 0] - R[..., 0, 1]) / s3,
            ],
            axis=-1,
        )
    q = np.where((k == 0)[..., None], b0, np.where((k == 1)[..., None], b1, np.where((k == 2)[..., None], b2, b3)))
    q = np.where((q[..., 3] < 0)[..., None], -q, q)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def from_quaternion(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from quaternions (x, y, z, w), normalised first."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def log(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (..., 3) with angle in [0, π] from rotation matrices (..., 3, 3)."""
    R = np.asarray(R, dtype=np.float64)
    if R.shape == (3, 3):
        return so3_log_one(R)
    q = to_quaternion(R)
    v = q[..., :3]
    w = q[..., 3]
    n = np.linalg.norm(v, axis=-1)
    small = n < _SMALL
    ns = np.where(small, 1.0, n)
    ws = np.where(small, w, 1.0)
    # θ = 2·atan2(|v|, w); ω = θ·v/|v|; for small |v| the series 2/w·(1 − |v|²/(3w²)) avoids 0/0.
    factor = np.where(small, 2.0 / ws * (1.0 - n * n / (3.0 * ws * ws)), 2.0 * np.arctan2(ns, w) / ns)
    return v * factor[..., None]


def left_jacobian(w: np.ndarray) -> np.ndarray:
    """V(ω) = I + B·W + C·W², the matrix mapping translation parameters to exp's translation."""
    w = np.asarray(w, dtype=np.float64)
    theta = np.linalg.norm(w, axis=-1)
    _, B, C = _rodrigues_coeffs(theta)
    W = hat(w)
    eye = np.broadcast_to(np.eye(3), W.shape)
    return eye + B[..., None, None] * W + C[..., None, None] * (W @ W)


def left_jacobian_inv(w: np.ndarray) -> np.ndarray:
    """V(ω)⁻¹ = I − ½W + D·W², D = (1 − (θ/2)·cot(θ/2))/θ², by its series below θ = 1e-2."""
    w = np.asarray(w, dtype=np.float64)
    theta = np.linalg.norm(w, axis=-1)
    small = theta < _SERIES
    ts = np.where(small, 1.0, theta)
    t2 = theta * theta
    D = np.where(
        small,
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2**3 / 1209600.0,
        (1.0 - 0.5 * ts / np.tan(0.5 * ts)) / (ts * ts),
    )
    W = hat(w)
    eye = np.broadcast_to(np.eye(3), W.shape)
    return eye - 0.5 * W + D[..., None, None] * (W @ W)
