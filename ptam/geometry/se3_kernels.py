"""SE(3) inside numba kernels: the exponential map of ``ptam.geometry.se3`` for one twist, without numpy's
batched calls (the pose update of PTAM §5.4, the edgelet frame update of Agility §4.4)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def se3_exp(mu):
    """exp(μ) for μ = (translation, rotation) -> 4×4, as ``ptam.geometry.se3.exp``."""
    w0, w1, w2 = mu[3], mu[4], mu[5]
    t2 = w0 * w0 + w1 * w1 + w2 * w2
    th = math.sqrt(t2)
    if th < 1e-5:
        A = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
        B = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        C = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
    else:
        A = math.sin(th) / th
        B = (1.0 - math.cos(th)) / t2
        C = (th - math.sin(th)) / (t2 * th)
    W = np.array([[0.0, -w2, w1], [w2, 0.0, -w0], [-w1, w0, 0.0]])
    W2 = W @ W
    T = np.eye(4)
    V = np.eye(3) + B * W + C * W2
    T[:3, :3] += A * W + B * W2
    for r in range(3):
        T[r, 3] = V[r, 0] * mu[0] + V[r, 1] * mu[1] + V[r, 2] * mu[2]
    return T
