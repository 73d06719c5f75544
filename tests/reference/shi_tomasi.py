"""numpy references for ``ptam.image.shi_tomasi_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


def shi_tomasi_ref(img: np.ndarray, xy: np.ndarray, half: int) -> np.ndarray:
    """Numpy reference of :func:`shi_tomasi_scores`, via gradient images and box sums."""
    I = img.astype(np.float64)
    H, W = I.shape
    dx = np.zeros_like(I)
    dy = np.zeros_like(I)
    dx[:, 1:-1] = I[:, 2:] - I[:, :-2]
    dy[1:-1, :] = I[2:, :] - I[:-2, :]
    xy = np.asarray(xy, dtype=np.int64).reshape(-1, 2)
    inside = (xy[:, 0] - half >= 1) & (xy[:, 1] - half >= 1) & (xy[:, 0] + half <= W - 2) & (xy[:, 1] + half <= H - 2)
    out = np.full(len(xy), -np.inf)
    if not inside.any():
        return out
    off = np.arange(-half, half + 1)
    ys = xy[inside, 1][:, None, None] + off[None, :, None]
    xs = xy[inside, 0][:, None, None] + off[None, None, :]
    gx, gy = dx[ys, xs], dy[ys, xs]
    norm = 2.0 * (2 * half + 1) ** 2
    a = (gx * gx).sum(axis=(1, 2)) / norm
    c = (gy * gy).sum(axis=(1, 2)) / norm
    b = (gx * gy).sum(axis=(1, 2)) / norm
    out[inside] = 0.5 * (a + c - np.sqrt(np.maximum((a + c) ** 2 - 4.0 * (a * c - b * b), 0.0)))
    return out
