"""numpy references for ``ptam.mapping.epipolar_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def epipolar_search_ref(img, corners, corners_plane, box, templates, normal, dist, along, lo, hi, max_perp, max_ssd):
    """Numpy reference: every candidate against every corner by broadcasting."""
    n, size = templates.shape[:2]
    h = size // 2
    H, W = img.shape
    best = np.full(n, -1, dtype=np.int64)
    score = np.full(n, np.inf)
    x, y = corners[:, 0], corners[:, 1]
    inside = (x >= h) & (y >= h) & (x <= W - size + h) & (y <= H - size + h)
    off = np.arange(size) - h
    patches = img[
        np.clip(y[:, None, None] + off[None, :, None], 0, H - 1),
        np.clip(x[:, None, None] + off[None, None, :], 0, W - 1),
    ].astype(np.float64)
    pz = patches - patches.mean(axis=(1, 2), keepdims=True)
    for k in range(n):
        d = dist[k] - corners_plane @ normal[k]
        t = corners_plane @ along[k]
        in_box = (x >= box[k, 0]) & (x <= box[k, 2]) & (y >= box[k, 1]) & (y <= box[k, 3])
        ok = inside & in_box & (d * d <= max_perp[k] ** 2) & (t >= lo[k]) & (t <= hi[k])
        if not ok.any():
            continue
        T = templates[k].astype(np.float64)
        z = ((pz[ok] - (T - T.mean())) ** 2).sum(axis=(1, 2))
        j = int(np.argmin(z))
        if z[j] < max_ssd:
            best[k] = np.flatnonzero(ok)[j]
            score[k] = z[j]
    return best, score
