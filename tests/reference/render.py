"""numpy references for ``ptam.synthetic.render_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.synthetic.render_kernels import _CONE_PAD, _EPS_DENOM, TILE_PX, intersect_rays


def _bilinear_ref(tex_data, tex_info, t, lev, fx, fy):
    off, w, h = (tex_info[t, lev, i] for i in range(3))
    x0f, y0f = np.floor(fx), np.floor(fy)
    ax, ay = fx - x0f, fy - y0f
    x0 = np.clip(x0f.astype(np.int64), 0, w - 1)
    x1 = np.clip(x0f.astype(np.int64) + 1, 0, w - 1)
    y0 = np.clip(y0f.astype(np.int64), 0, h - 1)
    y1 = np.clip(y0f.astype(np.int64) + 1, 0, h - 1)
    g = tex_data.astype(np.float64)
    return (1 - ay) * ((1 - ax) * g[off + y0 * w + x0] + ax * g[off + y0 * w + x1]) + ay * (
        (1 - ax) * g[off + y1 * w + x0] + ax * g[off + y1 * w + x1]
    )


def render_ref(
    rays, crays, drays, sample_step, poses, rects, rect_tex, tex_data, tex_info, tex_levels, tex_texel, background, *_
):
    """Numpy reference of :func:`render` (world frame throughout); returns the (H, W) float32 image. Every ray is
    tested against every rectangle: the kernel's tile cones (the trailing arguments) only save it work."""
    H, W, S, _ = rays.shape
    acc = np.zeros((H, W))
    for T in poses:  # sub-frames: a handful
        R, c = T[:3, :3], T[:3, 3]
        d = rays.reshape(-1, 3) @ R.T
        t, k, a, b = intersect_rays(c, d, rects)
        hit = k >= 0
        kk = np.where(hit, k, 0)
        n = rects[kk, 9:12]
        # Footprint on the hit rectangle's plane from the pixel-centre ray and its differentials.
        d0 = np.repeat(crays.reshape(-1, 3) @ R.T, S, axis=0)
        nd0 = np.einsum("nc,nc->n", d0, n)
        ok = np.abs(nd0) >= _EPS_DENOM
        nd0 = np.where(ok, nd0, 1.0)
        t0 = np.abs(np.einsum("nc,nc->n", rects[kk, 0:3] - c, n) / nd0)
        rho2 = np.zeros(len(d))
        for j in range(2):
            e = np.repeat(drays[:, :, j, :].reshape(-1, 3) @ R.T, S, axis=0)
            dP = e - d0 * (np.einsum("nc,nc->n", e, n) / nd0)[:, None]
            rho2 = np.maximum(
                rho2, np.einsum("nc,nc->n", dP, rects[kk, 3:6]) ** 2 + np.einsum("nc,nc->n", dP, rects[kk, 6:9]) ** 2
            )
        tex = rect_tex[kk]
        texel = tex_texel[tex]
        rho = np.where(ok, t0 * np.sqrt(rho2) * sample_step / texel, 0.0)
        lam = np.where(rho > 1.0, np.log2(np.maximum(rho, 1.0)), 0.0)
        top = tex_levels[tex] - 1
        lev0 = np.where(lam >= top, top, np.floor(lam).astype(np.int64))
        frac = np.where(lam >= top, 0.0, lam - np.floor(lam))
        val = np.zeros(len(d))
        for ti in np.unique(tex[hit]):
            for lev in np.unique(lev0[hit & (tex == ti)]):
                m = hit & (tex == ti) & (lev0 == lev)
                sc = 1.0 / (texel[m] * (1 << int(lev)))
                v = _bilinear_ref(tex_data, tex_info, ti, lev, a[m] * sc - 0.5, b[m] * sc - 0.5)
                if lev + 1 < tex_levels[ti]:
                    v1 = _bilinear_ref(tex_data, tex_info, ti, lev + 1, a[m] * sc * 0.5 - 0.5, b[m] * sc * 0.5 - 0.5)
                    v = np.where(frac[m] > 0, (1 - frac[m]) * v + frac[m] * v1, v)
                val[m] = v
        val[~hit] = background
        acc += val.reshape(H, W, S).sum(axis=2)
    return (acc / (len(poses) * S)).astype(np.float32)


def tile_cones_ref(rays: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numpy reference of :func:`tile_cones` (the tiles padded with NaN)."""
    H, W = rays.shape[:2]
    TY, TX = -(-H // TILE_PX), -(-W // TILE_PX)
    pad = np.full((TY * TILE_PX, TX * TILE_PX) + rays.shape[2:], np.nan)
    pad[:H, :W] = rays
    tiles = pad.reshape(TY, TILE_PX, TX, TILE_PX, -1, 3).transpose(0, 2, 1, 3, 4, 5).reshape(TY, TX, -1, 3)
    axis = np.nansum(tiles, axis=2)
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    cos = np.nanmin(np.einsum("yxnc,yxc->yxn", tiles, axis), axis=2)
    alpha = np.arccos(np.clip(cos, -1.0, 1.0)) + _CONE_PAD
    sin = np.where(alpha < 0.5 * np.pi, np.sin(alpha), 2.0)
    return np.ascontiguousarray(axis), np.ascontiguousarray(sin)
