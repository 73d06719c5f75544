"""numpy references for ``ptam.tracking.model_selection_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import math

import numpy as np


def scaled_sq_errors_ref(camera, T_cw, X, Xw, xy, level, outside):
    """Squared reprojection errors in units of each measurement's σ = 2^level; behind the camera: ``outside``."""
    Xc = X @ T_cw[:3, :3].T + Xw[:, None] * T_cw[:3, 3]
    front = Xc[:, 2] > 0
    e2 = np.full(len(X), outside)
    e2[front] = ((camera.project(Xc[front]) - xy[front]) ** 2).sum(axis=1) * np.exp2(-2.0 * level[front])
    return e2


def em_noise_ref(e2, search_area, lo, hi, floor, iterations):
    sigma2 = max(float(np.median(e2)) / (2.0 * math.log(2.0)), floor)
    gamma = 0.5 * (lo + hi)
    for _ in range(iterations):
        p_in = gamma * np.exp(-e2 / (2.0 * sigma2)) / (2.0 * math.pi * sigma2)
        p_out = (1.0 - gamma) / search_area
        r = p_in / (p_in + p_out)
        gamma = min(max(float(r.mean()), lo), hi)
        sigma2 = max(float((r * e2).sum() / (2 * max(r.sum(), 1e-12))), floor)
    return sigma2, gamma
