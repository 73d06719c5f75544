"""Shi-Tomasi corner score at a list of pixels (PTAM §6.2; code ``FindShiTomasiScoreAtPoint``).

Central differences dx = I(x+1, y) − I(x−1, y), dy = I(x, y+1) − I(x, y−1) over a (2h+1)² box; the
structure-tensor sums are divided by 2·(2h+1)², and the score is the smaller eigenvalue
0.5·(a + c − sqrt((a + c)² − 4(ac − b²))). Pixels whose box (plus the one-pixel gradient support) leaves
the image get −inf, so they fail any threshold. ``shi_tomasi_ref`` is the numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def shi_tomasi_scores(img, xy, half):
    """img (H, W) uint8, xy (K, 2) int32 (x, y), half-box size -> (K,) float64 scores."""
    h, w = img.shape
    n = xy.shape[0]
    out = np.empty(n)
    norm = 2.0 * (2 * half + 1) ** 2
    for k in range(n):
        cx = xy[k, 0]
        cy = xy[k, 1]
        if cx - half < 1 or cy - half < 1 or cx + half > w - 2 or cy + half > h - 2:
            out[k] = -np.inf
            continue
        sxx = 0.0
        syy = 0.0
        sxy = 0.0
        for y in range(cy - half, cy + half + 1):
            for x in range(cx - half, cx + half + 1):
                dx = float(img[y, x + 1]) - float(img[y, x - 1])
                dy = float(img[y + 1, x]) - float(img[y - 1, x])
                sxx += dx * dx
                syy += dy * dy
                sxy += dx * dy
        a = sxx / norm
        c = syy / norm
        b = sxy / norm
        disc = (a + c) * (a + c) - 4.0 * (a * c - b * b)
        out[k] = 0.5 * (a + c - math.sqrt(max(disc, 0.0)))
    return out
