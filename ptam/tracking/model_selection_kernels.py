"""Numba kernels of per-frame model selection (Gauglitz et al. TVCG 2013 §4.2): the scaled reprojection errors
GRIC scores and the EM for σ and the inlier ratio. Numpy references: ``tests/reference/model_selection.py``."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project

ERROR_DIM = 2  # Table 2: D − d_m, a 2-D reprojection error for both absolute pose models


@njit(nogil=True, cache=True)
def scaled_sq_errors(cam, T_cw, X, Xw, xy, level, outside):
    """Squared reprojection errors of homogeneous features (X, w = Xw) at T_cw, in units of each measurement's
    σ = 2^level; a feature behind the camera counts as ``outside`` (the search region's size)."""
    n = X.shape[0]
    e2 = np.empty(n)
    for i in range(n):
        x, y, z = X[i, 0], X[i, 1], X[i, 2]
        cx = T_cw[0, 0] * x + T_cw[0, 1] * y + T_cw[0, 2] * z + Xw[i] * T_cw[0, 3]
        cy = T_cw[1, 0] * x + T_cw[1, 1] * y + T_cw[1, 2] * z + Xw[i] * T_cw[1, 3]
        cz = T_cw[2, 0] * x + T_cw[2, 1] * y + T_cw[2, 2] * z + Xw[i] * T_cw[2, 3]
        if cz <= 0.0:
            e2[i] = outside
            continue
        u, v, _ = project(cam, cx, cy, cz)
        s = 2.0 ** (-2.0 * level[i])
        e2[i] = ((u - xy[i, 0]) ** 2 + (v - xy[i, 1]) ** 2) * s
    return e2


@njit(nogil=True, cache=True)
def em_noise(e2, search_area, lo, hi, floor, iterations):
    """σ² and inlier ratio γ of squared 2-D errors by EM: Gaussian inliers, outliers uniform over
    ``search_area``; γ clamped to [lo, hi] and σ² to ``floor`` (§8.1)."""
    n = e2.shape[0]
    sigma2 = max(np.median(e2) / (2.0 * math.log(2.0)), floor)  # median of a 2-dof χ² is 2 ln 2 σ²
    gamma = 0.5 * (lo + hi)
    for _ in range(iterations):
        p_out = (1.0 - gamma) / search_area
        norm = gamma / (2.0 * math.pi * sigma2)
        r_sum = 0.0
        re_sum = 0.0
        for i in range(n):
            p_in = norm * math.exp(-e2[i] / (2.0 * sigma2))
            r = p_in / (p_in + p_out)
            r_sum += r
            re_sum += r * e2[i]
        gamma = min(max(r_sum / n, lo), hi)
        sigma2 = max(re_sum / (ERROR_DIM * max(r_sum, 1e-12)), floor)
    return sigma2, gamma
