"""numpy reference for ``ptam.mapping.normals_kernels``: plain numpy, compared with the kernel."""

from __future__ import annotations

import numpy as np

PIVOT_EPS = 1e-12


def _bilinear(img, x, y):
    img = img.astype(np.float64)
    x0 = np.minimum(np.floor(x).astype(int), img.shape[1] - 2)
    y0 = np.minimum(np.floor(y).astype(int), img.shape[0] - 2)
    fx, fy = x - x0, y - y0
    return (
        (1 - fx) * (1 - fy) * img[y0, x0]
        + fx * (1 - fy) * img[y0, x0 + 1]
        + (1 - fx) * fy * img[y0 + 1, x0]
        + fx * fy * img[y0 + 1, x0 + 1]
    )


def _inside(img, M, h):
    corners = np.array([[-h, -h, 1.0], [h, -h, 1.0], [-h, h, 1.0], [h, h, 1.0]])
    p = corners @ M.T
    H, W = img.shape
    return bool(np.all((p[:, 0] >= 0) & (p[:, 0] <= W - 1) & (p[:, 1] >= 0) & (p[:, 1] <= H - 1)))


def _solve(Hs, b):
    """Cholesky solve that fails like the kernel's: a pivot at or below PIVOT_EPS × the largest diagonal."""
    try:
        L = np.linalg.cholesky(Hs)
    except np.linalg.LinAlgError:
        return None
    if np.any(np.diag(L) ** 2 <= PIVOT_EPS * np.max(np.diag(Hs))):
        return None
    return np.linalg.solve(Hs, b)


def _align_one(img1, img2, sxy, M, size, max_its, converge_px):
    h = 0.5 * (size - 1)
    if not _inside(img1, np.array([[1.0, 0, sxy[0]], [0, 1.0, sxy[1]]]), h + 1):
        return M, False, 0.0
    off = np.arange(size + 2) - 1 - h
    gx_, gy_ = np.meshgrid(off, off)
    T = _bilinear(img1, sxy[0] + gx_, sxy[1] + gy_)
    gx = 0.5 * (T[1:-1, 2:] - T[1:-1, :-2])
    gy = 0.5 * (T[2:, 1:-1] - T[:-2, 1:-1])
    x, y = gx_[1:-1, 1:-1], gy_[1:-1, 1:-1]
    sd = np.stack([gx * x, gy * x, gx * y, gy * y, gx, gy, np.ones_like(gx)], axis=-1).reshape(-1, 7)
    Hs = sd.T @ sd
    Ti = T[1:-1, 1:-1].ravel()
    pts = np.stack([x.ravel(), y.ravel(), np.ones(x.size)], axis=1)
    m = None
    ncc = 0.0
    corners = np.array([[-h, -h, 1.0], [h, -h, 1.0], [-h, h, 1.0], [h, h, 1.0]])
    for _ in range(max_its):
        if not _inside(img2, M, h):
            break
        p = pts @ M.T
        v = _bilinear(img2, p[:, 0], p[:, 1])
        dv, dt = v - v.mean(), Ti - Ti.mean()
        var = np.sum(dv * dv) * np.sum(dt * dt)
        ncc = np.sum(dv * dt) / np.sqrt(var) if var > 0 else 0.0
        if m is None:
            m = np.mean(v) - np.mean(Ti)
        d = _solve(Hs, sd.T @ (v - Ti - m))
        if d is None:
            break
        D = np.array([[1 + d[0], d[2], d[4]], [d[1], 1 + d[3], d[5]], [0, 0, 1.0]])
        if not np.linalg.det(D[:2, :2]) > 0:
            break
        M = (np.vstack([M, [0, 0, 1.0]]) @ np.linalg.inv(D))[:2]
        m += d[6]
        if np.max(np.linalg.norm(corners @ (D - np.eye(3))[:2].T, axis=1)) < converge_px:
            return M, _inside(img2, M, h), ncc
    return M, False, ncc


def align_affine_ref(kf_images, src_kf, src_level, src_xy, tgt_kf, tgt_level, A_init, c_init, size, max_its, conv):
    n = len(src_kf)
    A, c, converged = A_init.astype(np.float64).copy(), c_init.astype(np.float64).copy(), np.zeros(n, bool)
    ncc = np.zeros(n)
    for k in range(n):
        img1 = kf_images[src_level[k]][src_kf[k]]
        img2 = kf_images[tgt_level[k]][tgt_kf[k]]
        M0 = np.concatenate([A[k], c[k][:, None]], axis=1)
        M, converged[k], ncc[k] = _align_one(img1, img2, src_xy[k], M0, size, max_its, conv)
        A[k], c[k] = M[:, :2], M[:, 2]
    return A, c, converged, ncc
