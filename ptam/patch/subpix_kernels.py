"""Inverse-compositional sub-pixel refinement over translation and mean intensity (PTAM §5.3, Baker & Matthews).

The image patch at position p (the template's pixel (h, h), h = size // 2) should equal the template plus an
intensity offset m: I(p + x) ≈ T(x) + m over the template's inner (size − 2)² pixels (PTAM code:
``MakeSubPixTemplate`` / ``IterateSubPix``). Inverse composition linearises on the template, so the Jacobian
g = (∂T/∂x, ∂T/∂y, 1) and H = Σ g gᵀ are fixed; each iteration solves (Δ, Δm) = H⁻¹ Σ g·(I(p + x) − T(x) − m)
and moves p ← p − Δ, m ← m + Δm. Converged when |Δ| < ``converge_px``; not converged within ``max_its``
iterations, or leaving the image, means the match is dropped (PTAM code: ``IterateSubPixToConvergence``).
All image samples of one iteration share p's bilinear weights. ``refine_subpix_ref`` is the numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def refine_subpix(levels, templates, level, start_xy, max_its, converge_px):
    """start_xy (n, 2) at the search level -> refined xy (n, 2) at that level and converged (n,) bool."""
    n = templates.shape[0]
    size = templates.shape[1]
    h = size // 2
    inner = size - 2
    xy = start_xy.astype(np.float64).copy()
    converged = np.zeros(n, dtype=np.bool_)
    gx = np.empty((inner, inner))
    gy = np.empty((inner, inner))
    conv2 = converge_px * converge_px
    for k in range(n):
        img = levels[level[k]]
        H, W = img.shape
        T = templates[k]
        h00 = h01 = h02 = h11 = h12 = 0.0
        tsum = 0.0
        for r in range(inner):
            for c in range(inner):
                a = 0.5 * (float(T[r + 1, c + 2]) - float(T[r + 1, c]))
                b = 0.5 * (float(T[r + 2, c + 1]) - float(T[r, c + 1]))
                gx[r, c] = a
                gy[r, c] = b
                h00 += a * a
                h01 += a * b
                h02 += a
                h11 += b * b
                h12 += b
                tsum += T[r + 1, c + 1]
        h22 = float(inner * inner)
        # 3×3 symmetric inverse by cofactors.
        c00 = h11 * h22 - h12 * h12
        c01 = h02 * h12 - h01 * h22
        c02 = h01 * h12 - h02 * h11
        det = h00 * c00 + h01 * c01 + h02 * c02
        if not abs(det) > 1e-9:
            continue
        c11 = h00 * h22 - h02 * h02
        c12 = h01 * h02 - h00 * h12
        c22 = h00 * h11 - h01 * h01
        m = 0.0
        first = True
        for _ in range(max_its):
            bx = math.floor(xy[k, 0])
            by = math.floor(xy[k, 1])
            ix = int(bx)
            iy = int(by)
            if ix + 1 - h < 0 or iy + 1 - h < 0 or ix + size - 1 - h > W - 1 or iy + size - 1 - h > H - 1:
                break
            fx = xy[k, 0] - bx
            fy = xy[k, 1] - by
            wtl = (1.0 - fx) * (1.0 - fy)
            wtr = fx * (1.0 - fy)
            wbl = (1.0 - fx) * fy
            wbr = fx * fy
            if first:
                isum = 0.0
                for r in range(inner):
                    for c in range(inner):
                        y = iy + r + 1 - h
                        x = ix + c + 1 - h
                        isum += wtl * img[y, x] + wtr * img[y, x + 1] + wbl * img[y + 1, x] + wbr * img[y + 1, x + 1]
                m = (isum - tsum) / h22
                first = False
            b0 = b1 = b2 = 0.0
            for r in range(inner):
                for c in range(inner):
                    y = iy + r + 1 - h
                    x = ix + c + 1 - h
                    v = wtl * img[y, x] + wtr * img[y, x + 1] + wbl * img[y + 1, x] + wbr * img[y + 1, x + 1]
                    e = v - T[r + 1, c + 1] - m
                    b0 += gx[r, c] * e
                    b1 += gy[r, c] * e
                    b2 += e
            d0 = (c00 * b0 + c01 * b1 + c02 * b2) / det
            d1 = (c01 * b0 + c11 * b1 + c12 * b2) / det
            d2 = (c02 * b0 + c12 * b1 + c22 * b2) / det
            xy[k, 0] -= d0
            xy[k, 1] -= d1
            m += d2
            if d0 * d0 + d1 * d1 < conv2:
                converged[k] = True
                break
    return xy, converged
