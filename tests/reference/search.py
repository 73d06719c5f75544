"""numpy references for ``ptam.patch.search_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def search_patches_ref(levels, corners, templates, level, center, radius, max_ssd, flat_fraction=np.inf):
    """Numpy reference: every corner of the level scored by broadcasting, then the circle and the minimum."""
    n, size = templates.shape[:2]
    h = size // 2
    best = np.zeros((n, 2), dtype=np.int32)
    score = np.full(n, np.inf)
    found = np.zeros(n, dtype=bool)
    off = np.arange(size) - h
    for L in np.unique(level):
        img = levels[L].astype(np.float64)
        H, W = img.shape
        c = corners[L]
        c = c[(c[:, 0] >= h) & (c[:, 0] <= W - size + h) & (c[:, 1] >= h) & (c[:, 1] <= H - size + h)]
        if len(c) == 0:
            continue
        win = img[c[:, 1, None, None] + off[None, :, None], c[:, 0, None, None] + off[None, None, :]]
        win = win - win.mean(axis=(1, 2), keepdims=True)
        for k in np.flatnonzero(level == L):
            d2 = (c[:, 0] - center[k, 0]) ** 2 + (c[:, 1] - center[k, 1]) ** 2
            cand = np.flatnonzero(d2 <= radius[k] ** 2)
            if len(cand) == 0:
                continue
            z = ((win[cand] - templates[k].astype(np.float64)) ** 2).sum(axis=(1, 2))
            j = int(np.argmin(z))
            flat = (
                flat_fraction * (templates[k].astype(np.float64) ** 2).sum() if np.isfinite(flat_fraction) else np.inf
            )
            if z[j] < min(max_ssd, flat):
                best[k] = c[cand[j]]
                score[k] = z[j]
                found[k] = True
    return best, score, found
