"""numpy references for ``ptam.image.esm_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.image.esm_kernels import _PIVOT_EPS
from tests.reference.pose import tukey_sigma_sq_ref


def esm_se2_ref(image, template, template_grad, params0, iterations, with_offset, robust=False):
    """Numpy reference of :func:`esm_se2`: the same iteration with array operations."""
    image = np.asarray(image, np.float64)
    template = np.asarray(template, np.float64)
    h, w = image.shape
    cx, cy = 0.5 * (w - 1), 0.5 * (h - 1)
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    p = np.array(params0, np.float64)
    n = 4 if with_offset else 3
    score, done = 0.0, 0
    for _ in range(iterations):
        c, s = np.cos(p[2]), np.sin(p[2])
        u = cx + c * (xs - cx) - s * (ys - cy) + p[0]
        v = cy + s * (xs - cx) + c * (ys - cy) + p[1]
        valid = (u >= 0) & (v >= 0) & (u <= w - 1) & (v <= h - 1)
        x0 = np.minimum(np.clip(u, 0, None).astype(np.int64), w - 2)
        y0 = np.minimum(np.clip(v, 0, None).astype(np.int64), h - 2)
        fx, fy = u - x0, v - y0
        top = image[y0, x0] + fx * (image[y0, x0 + 1] - image[y0, x0])
        bot = image[y0 + 1, x0] + fx * (image[y0 + 1, x0 + 1] - image[y0 + 1, x0])
        warped = np.where(valid, (top + fy * (bot - top)).astype(np.float32), 0.0).astype(np.float64)
        inner = np.zeros((h, w), bool)
        inner[1:-1, 1:-1] = valid[1:-1, 1:-1] & valid[1:-1, :-2] & valid[1:-1, 2:] & valid[:-2, 1:-1] & valid[2:, 1:-1]
        gx = np.zeros((h, w))
        gy = np.zeros((h, w))
        gx[:, 1:-1] = 0.25 * (warped[:, 2:] - warped[:, :-2])
        gy[1:-1, :] = 0.25 * (warped[2:, :] - warped[:-2, :])
        gx += 0.5 * template_grad[..., 0]
        gy += 0.5 * template_grad[..., 1]
        Jm = np.stack([gx, gy, -(ys - cy) * gx + (xs - cx) * gy, np.ones((h, w))], axis=-1)[inner][:, :n]
        r = (warped - template + p[3])[inner]
        score = float(r @ r)
        c2 = tukey_sigma_sq_ref(r * r, 0.0) if robust else 0.0
        wt = np.where(r * r > c2, 0.0, (1.0 - r * r / c2) ** 2) if c2 > 0 else np.ones(len(r))
        A = Jm.T @ (wt[:, None] * Jm)
        if not A.size or np.max(np.diag(A)) <= 0:
            break
        try:
            L = np.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            break
        if np.min(np.diag(L)) ** 2 <= _PIVOT_EPS * np.max(np.diag(A)):
            break
        du = np.linalg.solve(A, Jm.T @ (wt * r))
        p[0] -= c * du[0] - s * du[1]
        p[1] -= s * du[0] + c * du[1]
        p[2] -= du[2]
        if with_offset:
            p[3] -= du[3]
        done += 1
    return p, score, done
