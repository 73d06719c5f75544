"""numpy references for ``ptam.patch.subpix_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np


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
            v[k] = (
                (1 - fx) * (1 - fy) * img[ys, xs]
                + fx * (1 - fy) * img[ys, xs + 1]
                + (1 - fx) * fy * img[ys + 1, xs]
                + fx * fy * img[ys + 1, xs + 1]
            )
        init = active & first
        m[init] = (v[init] - Ti[init]).mean(axis=(1, 2))
        first[init] = False
        e = (v - Ti - m[:, None, None]).reshape(n, -1)
        d = np.einsum("nij,nj->ni", Hinv, np.einsum("npi,np->ni", G, e))
        d[~active] = 0.0
        xy -= d[:, :2]
        m += d[:, 2]
        done = active & ((d[:, :2] ** 2).sum(axis=1) < converge_px**2)
        converged |= done
        active &= ~done
    return xy, converged
