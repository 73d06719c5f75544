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
                        isum += (wtl * img[y, x] + wtr * img[y, x + 1] + wbl * img[y + 1, x]
                                 + wbr * img[y + 1, x + 1])
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


def refine_subpix_ref(levels, templates, level, start_xy, max_its, converge_px):
    """Numpy reference: all patches iterate together; finished ones are frozen by a mask."""
    n, size = templates.shape[:2]
    h = size // 2
    T = templates.astype(np.float64)
    Ti = T[:, 1:-1, 1:-1]
    gx = 0.5 * (T[:, 1:-1, 2:] - T[:, 1:-1, :-2])
    gy = 0.5 * (T[:, 2:, 1:-1] - T[:, :-2, 1:-1])
    G = np.stack([gx, gy, np.ones_like(gx)], axis=-1).reshape(n, -1, 3)
    Hm = np.einsum("npi,npj->nij", G, G)
    det = np.linalg.det(Hm)
    active = np.abs(det) > 1e-9
    Hinv = np.zeros_like(Hm)
    Hinv[active] = np.linalg.inv(Hm[active])
    xy = start_xy.astype(np.float64).copy()
    converged = np.zeros(n, dtype=bool)
    m = np.zeros(n)
    off = np.arange(1, size - 1) - h
    first = np.ones(n, dtype=bool)
    for _ in range(max_its):
        if not active.any():
            break
        base = np.floor(xy)
        ix, iy = base[:, 0].astype(int), base[:, 1].astype(int)
        frac = xy - base
        v = np.zeros((n, size - 2, size - 2))
        for k in np.flatnonzero(active):
            img = levels[level[k]].astype(np.float64)
            H, W = img.shape
            if ix[k] + off[0] < 0 or iy[k] + off[0] < 0 or ix[k] + off[-1] + 1 > W - 1 or iy[k] + off[-1] + 1 > H - 1:
                active[k] = False
                continue
            ys, xs = iy[k] + off[:, None], ix[k] + off[None, :]
            fx, fy = frac[k]
            v[k] = ((1 - fx) * (1 - fy) * img[ys, xs] + fx * (1 - fy) * img[ys, xs + 1]
                    + (1 - fx) * fy * img[ys + 1, xs] + fx * fy * img[ys + 1, xs + 1])
        init = active & first
        m[init] = (v[init] - Ti[init]).mean(axis=(1, 2))
        first[init] = False
        e = (v - Ti - m[:, None, None]).reshape(n, -1)
        d = np.einsum("nij,nj->ni", Hinv, np.einsum("npi,np->ni", G, e))
        d[~active] = 0.0
        xy -= d[:, :2]
        m += d[:, 2]
        done = active & ((d[:, :2] ** 2).sum(axis=1) < converge_px ** 2)
        converged |= done
        active &= ~done
    return xy, converged
