"""SE(3) as 4×4 matrices with the PTAM parametrisation μ = (translation, rotation) (PTAM §5.2, eq. 6).

Pose updates are left-multiplied: T ← exp(μ)·T. Every function is batched over leading axes.
"""

from __future__ import annotations

import numpy as np

from . import so3
from .lie_one_kernels import se3_exp_left, se3_exp_one, se3_log_one


def exp(mu: np.ndarray) -> np.ndarray:
    """exp: (..., 6) -> (..., 4, 4)."""
    mu = np.asarray(mu, dtype=np.float64)
    if mu.shape == (6,):
        return se3_exp_one(mu)
    v, w = mu[..., :3], mu[..., 3:]
    T = np.zeros(mu.shape[:-1] + (4, 4))
    T[..., :3, :3] = so3.exp(w)
    T[..., :3, 3] = np.einsum("...ij,...j->...i", so3.left_jacobian(w), v)
    T[..., 3, 3] = 1.0
    return T


def exp_left(mu: np.ndarray, T: np.ndarray) -> np.ndarray:
    """exp(μ_i)·T_i for updates μ (N, 6) and poses T (N, 4, 4): the pose update, in one kernel call."""
    mu = np.ascontiguousarray(mu, dtype=np.float64).reshape(-1, 6)
    T = np.ascontiguousarray(T, dtype=np.float64).reshape(-1, 4, 4)
    out = np.empty_like(T)
    se3_exp_left(mu, T, out)
    return out


def log(T: np.ndarray) -> np.ndarray:
    """log: (..., 4, 4) -> (..., 6) with rotation angle in [0, π]."""
    T = np.asarray(T, dtype=np.float64)
    if T.shape == (4, 4):
        return se3_log_one(T)
    w = so3.log(T[..., :3, :3])
    v = np.einsum("...ij,...j->...i", so3.left_jacobian_inv(w), T[..., :3, 3])
    return np.concatenate([v, w], axis=-1)


def inv(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4)."""
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def compose(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A·B for rigid transforms (batched matmul, kept for readability at call sites)."""
    return np.asarray(A, dtype=np.float64) @ np.asarray(B, dtype=np.float64)


def from_Rt(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    R = np.asarray(R, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def transform(T: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Apply one transform (4, 4) to points (N, 3)."""
    T = np.asarray(T, dtype=np.float64)
    X = np.asarray(X, dtype=np.float64)
    return X @ T[:3, :3].T + T[:3, 3]


def adjoint(T: np.ndarray) -> np.ndarray:
    """Adjoint (..., 6, 6) for μ = (v, ω): exp(Ad_T μ) = T exp(μ) T⁻¹."""
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Ad = np.zeros(T.shape[:-2] + (6, 6))
    Ad[..., :3, :3] = R
    Ad[..., 3:, 3:] = R
    Ad[..., :3, 3:] = so3.hat(t) @ R
    return Ad


def generators() -> np.ndarray:
    """The six 4×4 generators G_k with exp(μ) ≈ I + Σ μ_k G_k."""
    G = np.zeros((6, 4, 4))
    for k in range(3):
        G[k, k, 3] = 1.0
    G[3:, :3, :3] = so3.hat(np.eye(3))
    return G


def point_jacobian(Xc: np.ndarray) -> np.ndarray:
    """∂(exp(μ)·X)/∂μ at μ = 0 for camera-frame points (N, 3) -> (N, 3, 6): [I | −[X]×]."""
    Xc = np.asarray(Xc, dtype=np.float64)
    J = np.zeros(Xc.shape[:-1] + (3, 6))
    J[..., :, :3] = np.eye(3)
    J[..., :, 3:] = -so3.hat(Xc)
    return J
