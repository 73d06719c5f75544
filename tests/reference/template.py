"""numpy references for ``ptam.patch.template_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def make_templates_ref(kf_images, source_kf, source_level, source_xy, M, size):
    """Numpy reference: all template samples of all patches at once."""
    n = len(source_kf)
    h = size // 2
    d = np.arange(size, dtype=np.float64) - h
    dx, dy = np.meshgrid(d, d)  # [r, c] -> (c - h, r - h)
    x = source_xy[:, 0, None, None] + M[:, 0, 0, None, None] * dx + M[:, 0, 1, None, None] * dy
    y = source_xy[:, 1, None, None] + M[:, 1, 0, None, None] * dx + M[:, 1, 1, None, None] * dy
    out = np.zeros((n, size, size))
    ok = np.zeros(n, dtype=bool)
    for L in np.unique(source_level):
        sel = np.flatnonzero(source_level == L)
        stack = kf_images[L]
        H, W = stack.shape[1:]
        xs, ys = x[sel], y[sel]
        inside = ((xs >= 0) & (xs <= W - 1) & (ys >= 0) & (ys <= H - 1)).all(axis=(1, 2))
        x0 = np.clip(np.floor(xs), 0, W - 2).astype(int)
        y0 = np.clip(np.floor(ys), 0, H - 2).astype(int)
        fx, fy = xs - x0, ys - y0
        kf = source_kf[sel][:, None, None]
        img = stack.astype(np.float64)
        v = (
            (1 - fx) * (1 - fy) * img[kf, y0, x0]
            + fx * (1 - fy) * img[kf, y0, x0 + 1]
            + (1 - fx) * fy * img[kf, y0 + 1, x0]
            + fx * fy * img[kf, y0 + 1, x0 + 1]
        )
        v -= v.mean(axis=(1, 2), keepdims=True)
        out[sel] = np.where(inside[:, None, None], v, 0.0)
        ok[sel] = inside
    return out.astype(np.float32), ok
