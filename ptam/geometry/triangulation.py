"""Triangulation of points from two or more calibrated views (linear DLT on normalised rays).

Views are given by world→camera poses T_cw (4×4) and unit-plane rays (x/z, y/z) of the
observations, so any camera model works once its pixels are unprojected.
"""

from __future__ import annotations

import numpy as np


def triangulate_nview(T_cw: np.ndarray, rays: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Points (M, 3) from poses (V, 4, 4) and rays (V, M, 2); ``valid`` (V, M) masks missing views.

    Minimises the algebraic error of x·(P₃X) − P₁X = 0, y·(P₃X) − P₂X = 0 in homogeneous
    coordinates by the smallest right singular vector, batched over points.
    """
    T_cw = np.asarray(T_cw, dtype=np.float64)
    rays = np.asarray(rays, dtype=np.float64)
    V, M = rays.shape[:2]
    if valid is None:
        valid = np.ones((V, M), dtype=bool)
    P = T_cw[:, :3, :]  # (V, 3, 4)
    rows_x = rays[..., 0:1] * P[:, None, 2, :] - P[:, None, 0, :]  # (V, M, 4)
    rows_y = rays[..., 1:2] * P[:, None, 2, :] - P[:, None, 1, :]
    w = valid[..., None].astype(np.float64)
    A = np.concatenate([rows_x * w, rows_y * w], axis=0)  # (2V, M, 4)
    A = np.transpose(A, (1, 0, 2))  # (M, 2V, 4)
    # Row-normalise so that distant and near views weigh alike.
    norms = np.linalg.norm(A, axis=-1, keepdims=True)
    A = A / np.where(norms > 0, norms, 1.0)
    _, _, Vt = np.linalg.svd(A)
    Xh = Vt[:, -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        X = Xh[:, :3] / Xh[:, 3:4]
    return X


def triangulate_two_view(T_cw_a: np.ndarray, T_cw_b: np.ndarray, rays_a: np.ndarray, rays_b: np.ndarray) -> np.ndarray:
    """Points (M, 3) from two views' poses and matched rays (M, 2)."""
    return triangulate_nview(np.stack([T_cw_a, T_cw_b]), np.stack([rays_a, rays_b]))


def depths(T_cw: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Camera-frame z of world points (M, 3) for one pose."""
    T_cw = np.asarray(T_cw, dtype=np.float64)
    return X @ T_cw[2, :3] + T_cw[2, 3]
