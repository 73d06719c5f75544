"""numpy references for ``ptam.tracking.minipatch_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def minipatch_find_ref(src, src_xy, dst, dst_xy, corners, radius, half, max_ssd, gain=1.0):
    """Numpy reference: all corners × all templates, SSD by broadcasting."""
    n = len(src_xy)
    found = np.zeros((n, 2), dtype=np.int32)
    ok = np.zeros(n, dtype=bool)
    hs, ws = src.shape
    hd, wd = dst.shape
    off = np.arange(-half, half + 1)
    cin = (corners[:, 0] >= half) & (corners[:, 0] < wd - half) & (corners[:, 1] >= half) & (corners[:, 1] < hd - half)
    c = corners[cin]
    if len(c) == 0:
        return found, ok
    cp = dst[c[:, 1][:, None, None] + off[None, :, None], c[:, 0][:, None, None] + off[None, None, :]].astype(
        np.float64
    )
    for i in range(n):
        sx, sy = src_xy[i]
        if sx < half or sy < half or sx >= ws - half or sy >= hs - half:
            continue
        t = gain * src[sy - half : sy + half + 1, sx - half : sx + half + 1].astype(np.float64)
        d2 = (c[:, 0] - dst_xy[i, 0]) ** 2 + (c[:, 1] - dst_xy[i, 1]) ** 2
        cand = d2 <= radius * radius
        if not cand.any():
            continue
        d = cp[cand] - t
        ssd = (d**2).sum(axis=(1, 2))
        j = int(np.argmin(ssd))
        if ssd[j] < max_ssd:
            found[i] = c[cand][j]
            ok[i] = True
    return found, ok
