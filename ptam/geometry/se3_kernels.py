"""SE(3) inside numba kernels: the exponential map of ``ptam.geometry.se3`` for one twist, without numpy's
batched calls (the pose update of PTAM §5.4, the edgelet frame update of Agility §4.4)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def se3_exp(mu):
    """exp(μ) for μ = (translation, rotation) -> 4×4, as ``ptam.geometry.se3.exp``."""
    T = np.empty((4, 4))
    se3_exp_into(mu, T)
    return T


@njit(nogil=True, cache=True)
def se3_exp_into(mu, T):
    """exp(μ) written into the 4×4 ``T``: Rodrigues' R = I + A·[ω]× + B·[ω]×² and t = (I + B·[ω]× + C·[ω]×²)·v,
    with no temporary arrays (per-edgelet frame updates would otherwise allocate several per call)."""
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
    # [ω]× and [ω]×² = ωωᵀ − |ω|² I, entry by entry.
    W = ((0.0, -w2, w1), (w2, 0.0, -w0), (-w1, w0, 0.0))
    w = (w0, w1, w2)
    for r in range(3):
        tr = 0.0
        for c in range(3):
            w2rc = w[r] * w[c] - (t2 if r == c else 0.0)
            one = 1.0 if r == c else 0.0
            T[r, c] = one + A * W[r][c] + B * w2rc
            tr += (one + B * W[r][c] + C * w2rc) * mu[c]
        T[r, 3] = tr
        T[3, r] = 0.0
    T[3, 3] = 1.0
