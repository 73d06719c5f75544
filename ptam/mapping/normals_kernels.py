"""Inverse-compositional affine alignment of many small patches at once (Gauglitz §5.4, Baker & Matthews 2004).

Patch k is a ``size``×``size`` template of its source keyframe's level, centred on ``src_xy[k]`` (pixels of
that level), sampled at offsets ξ = (c − h, r − h), h = (size − 1)/2. It is aligned to the target keyframe's
level by the warp W(ξ) = A·ξ + c (target-level pixels) and an intensity offset m: I(W(ξ)) ≈ T(ξ) + m, the
six-parameter affine of Gauglitz §5.4 plus the offset PTAM's sub-pixel search also fits (§5.3), so a
lighting change does not bend the warp. Inverse composition linearises on the template: the steepest-descent
images (∂T/∂x·x, ∂T/∂y·x, ∂T/∂x·y, ∂T/∂y·y, ∂T/∂x, ∂T/∂y, 1) and their 7×7 Hessian are fixed, and each
iteration composes W ← W ∘ W(Δ)⁻¹. Template gradients are central differences over a one-pixel border.

Converged when the last update moves no template corner by ``converge_px`` pixels or more; not converged
within ``max_its`` iterations, a singular Hessian (flat texture) or a warp leaving either image means no
alignment. The zero-mean normalised cross-correlation at the final warp tells a real match from one that
settled on noise. ``tests/reference/normals.py`` holds the numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..geometry.cholesky_kernels import cholesky_solve

_PIVOT_EPS = 1e-12  # relative to the largest diagonal entry: below this the template has no texture to align
_N_PARAMS = 7  # six affine parameters and the intensity offset


@njit(nogil=True, cache=True, inline="always")
def _bilinear(img, x, y):
    x0 = min(int(x), img.shape[1] - 2)  # x, y >= 0 (checked): truncation is the floor
    y0 = min(int(y), img.shape[0] - 2)
    fx = x - x0
    fy = y - y0
    return (
        (1.0 - fx) * (1.0 - fy) * img[y0, x0]
        + fx * (1.0 - fy) * img[y0, x0 + 1]
        + (1.0 - fx) * fy * img[y0 + 1, x0]
        + fx * fy * img[y0 + 1, x0 + 1]
    )


@njit(nogil=True, cache=True, inline="always")
def _square_inside(img, a00, a01, a10, a11, cx, cy, h):
    """Whether the affine image of the square [−h, h]² lies inside ``img`` (its corners do: it is convex)."""
    H, W = img.shape
    for sy in (-h, h):
        for sx in (-h, h):
            x = cx + a00 * sx + a01 * sy
            y = cy + a10 * sx + a11 * sy
            if not (0.0 <= x <= W - 1.0 and 0.0 <= y <= H - 1.0):
                return False
    return True


@njit(nogil=True, cache=True)
def align_affine(kf_images, src_kf, src_level, src_xy, tgt_kf, tgt_level, A_init, c_init, size, max_its, converge_px):
    """kf_images: per level (N_kf, H_L, W_L) uint8. Returns A (n, 2, 2), c (n, 2), converged (n,) bool and the
    zero-mean normalised cross-correlation (n,) of template and image at the last warp sampled."""
    n = src_kf.shape[0]
    A = A_init.astype(np.float64).copy()
    c = c_init.astype(np.float64).copy()
    converged = np.zeros(n, dtype=np.bool_)
    ncc = np.zeros(n)
    count = float(size * size)
    h = 0.5 * (size - 1)
    T = np.empty((size + 2, size + 2))
    sd = np.empty((size, size, _N_PARAMS))
    Hs = np.empty((_N_PARAMS, _N_PARAMS))
    b = np.empty(_N_PARAMS)
    for k in range(n):
        img1 = kf_images[src_level[k]][src_kf[k]]
        img2 = kf_images[tgt_level[k]][tgt_kf[k]]
        sx, sy = src_xy[k, 0], src_xy[k, 1]
        if not _square_inside(img1, 1.0, 0.0, 0.0, 1.0, sx, sy, h + 1.0):
            continue
        for r in range(size + 2):
            for q in range(size + 2):
                T[r, q] = _bilinear(img1, sx + q - 1.0 - h, sy + r - 1.0 - h)
        Hs[:, :] = 0.0
        tsum = tsq = 0.0
        for r in range(size):
            y = r - h
            for q in range(size):
                x = q - h
                gx = 0.5 * (T[r + 1, q + 2] - T[r + 1, q])
                gy = 0.5 * (T[r + 2, q + 1] - T[r, q + 1])
                g = sd[r, q]
                g[0], g[1], g[2], g[3], g[4], g[5], g[6] = gx * x, gy * x, gx * y, gy * y, gx, gy, 1.0
                for i in range(_N_PARAMS):
                    for j in range(i + 1):
                        Hs[i, j] += g[i] * g[j]
                tsum += T[r + 1, q + 1]
                tsq += T[r + 1, q + 1] * T[r + 1, q + 1]
        for i in range(_N_PARAMS):
            for j in range(i + 1, _N_PARAMS):
                Hs[i, j] = Hs[j, i]
        a00, a01, a10, a11 = A[k, 0, 0], A[k, 0, 1], A[k, 1, 0], A[k, 1, 1]
        cx, cy = c[k, 0], c[k, 1]
        m = 0.0
        for it in range(max_its):
            if not _square_inside(img2, a00, a01, a10, a11, cx, cy, h):
                break
            b[:] = 0.0
            isum = isq = cross = 0.0
            for r in range(size):
                y = r - h
                for q in range(size):
                    x = q - h
                    v = _bilinear(img2, cx + a00 * x + a01 * y, cy + a10 * x + a11 * y)
                    isum += v
                    isq += v * v
                    cross += v * T[r + 1, q + 1]
                    e = v - T[r + 1, q + 1] - m
                    g = sd[r, q]
                    for i in range(_N_PARAMS):
                        b[i] += g[i] * e
            var = (isq - isum * isum / count) * (tsq - tsum * tsum / count)
            ncc[k] = (cross - isum * tsum / count) / math.sqrt(var) if var > 0.0 else 0.0
            if it == 0:
                # Start from the offset of the means, so the first step is not spent on brightness.
                m = (isum - tsum) / count
                for i in range(_N_PARAMS):
                    b[i] -= m * Hs[i, _N_PARAMS - 1]
            d, ok = cholesky_solve(Hs, b, _N_PARAMS, _PIVOT_EPS)
            if not ok:
                break
            # W(Δ)⁻¹ of the affine [[1 + d0, d2, d4], [d1, 1 + d3, d5]], composed on the right of W.
            p00, p01, p10, p11 = 1.0 + d[0], d[2], d[1], 1.0 + d[3]
            det = p00 * p11 - p01 * p10
            if not det > 0.0:
                break
            q00, q01, q10, q11 = p11 / det, -p01 / det, -p10 / det, p00 / det
            qx = -(q00 * d[4] + q01 * d[5])
            qy = -(q10 * d[4] + q11 * d[5])
            cx, cy = cx + a00 * qx + a01 * qy, cy + a10 * qx + a11 * qy
            a00, a01, a10, a11 = (
                a00 * q00 + a01 * q10,
                a00 * q01 + a01 * q11,
                a10 * q00 + a11 * q10,
                a10 * q01 + a11 * q11,
            )
            m += d[6]
            step = 0.0  # the largest move of a template corner
            for ey in (-h, h):
                for ex in (-h, h):
                    ux = d[0] * ex + d[2] * ey + d[4]
                    uy = d[1] * ex + d[3] * ey + d[5]
                    step = max(step, math.sqrt(ux * ux + uy * uy))
            if step < converge_px:
                converged[k] = _square_inside(img2, a00, a01, a10, a11, cx, cy, h)
                break
        A[k, 0, 0], A[k, 0, 1], A[k, 1, 0], A[k, 1, 1] = a00, a01, a10, a11
        c[k, 0], c[k, 1] = cx, cy
    return A, c, converged, ncc
