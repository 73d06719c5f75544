"""Similarities: the alignment of point sets (Umeyama 1991), used to compare trajectories up to gauge (PTAM §7.3),
and :class:`Similarity`, which moves points and poses between two frames of different scale (merged tracks,
Gauglitz et al. §5.3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = True):
    """Least-squares (s, R, t) with dst ≈ s·R·src + t for (N, 3) point sets, N ≥ 3 not collinear.

    With ``with_scale=False`` s is fixed to 1 (SE(3) alignment).
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3:
        raise ValueError("umeyama needs two (N, 3) arrays of the same shape")
    n = src.shape[0]
    if n < 3:
        raise ValueError("umeyama needs at least 3 points")
    mu_s = src.mean(axis=0)
    mu_d = dst.mean(axis=0)
    xs = src - mu_s
    xd = dst - mu_d
    cov = xd.T @ xs / n
    U, D, Vt = np.linalg.svd(cov)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    var_s = (xs * xs).sum() / n
    s = float(np.trace(np.diag(D) @ S) / var_s) if with_scale else 1.0
    t = mu_d - s * R @ mu_s
    return s, R, t


@dataclass(frozen=True)
class Similarity:
    """X_this = s·R·X_other + t."""

    R: np.ndarray
    t: np.ndarray
    s: float

    def points(self, X: np.ndarray) -> np.ndarray:
        return self.s * X @ self.R.T + self.t

    def poses_cw(self, T_cw: np.ndarray) -> np.ndarray:
        """World-to-camera poses (N, 4, 4) of the other frame in this frame (the camera's units scale by s)."""
        out = np.array(T_cw, dtype=np.float64, copy=True)
        Rk = out[:, :3, :3] @ self.R.T
        out[:, :3, 3] = self.s * out[:, :3, 3] - Rk @ self.t
        out[:, :3, :3] = Rk
        return out

    def poses_wc(self, T_wc: np.ndarray) -> np.ndarray:
        """Camera-to-world poses (N, 4, 4) of the other frame in this frame."""
        out = np.array(T_wc, dtype=np.float64, copy=True)
        out[:, :3, 3] = self.points(out[:, :3, 3])
        out[:, :3, :3] = self.R @ out[:, :3, :3]
        return out

    def inverse(self) -> Similarity:
        return Similarity(self.R.T, -(self.R.T @ self.t) / self.s, 1.0 / self.s)

    def then(self, other: Similarity) -> Similarity:
        """``other`` applied after this one."""
        return Similarity(other.R @ self.R, other.points(self.t), other.s * self.s)
