"""Ray-cast renderer for synthetic scenes of textured rectangles (kernel + numpy reference).

Every pixel averages S sub-pixel samples (supersampling) over P sub-frame poses (motion blur). A sample's
ray, given in the camera frame through the camera model (distortion included), is intersected with every
rectangle (moved into that sub-frame's camera frame once), and the nearest hit is shaded by trilinear
mip-mapping. The mip level is the footprint of one sample step on the hit rectangle's plane,
``dP = t·(dd − d·(n·dd)/(n·d))`` for the pixel-centre ray d and its differentials dd, so texture detail
finer than a sample is filtered, not aliased; it is computed once per pixel, sub-frame and rectangle.
Pixels are rendered in tiles, and a tile's rays are tested only against the rectangles whose cone of rays meets
the tile's (``_tile_candidates``): 1.3-1.5 of a desk scene's 8 rectangles, and the same image.

Packed inputs:
  rays   (H, W, S, 3)  unit camera-frame rays of the samples
  crays  (H, W, 3)     unit camera-frame ray through each pixel centre
  drays  (H, W, 2, 3)  ∂ray/∂u and ∂ray/∂v per pixel (one-pixel step)
  poses  (P, 4, 4)     T_wc of the sub-frames
  rects  (K, 14)       origin(3), unit axis a(3), unit axis b(3), normal(3), size along a, size along b
  rect_tex (K,)        texture index of each rectangle
  tex_data, tex_info (T, L, 3) = (offset, width, height), tex_levels (T,), tex_texel (T,) metres per texel
``render_ref`` is the numpy reference; ``intersect_ref`` the numpy ray/rectangle intersection.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_EPS_DENOM = 1e-12  # rays this parallel to a rectangle's plane never hit it
_EPS_T = 1e-9  # hits closer than this to the ray origin are ignored
# A rectangle whose plane passes this close to the camera centre, or one of whose edges nearly lines up with it,
# relative to its distance and size, is never culled: its edge planes would be too ill-conditioned to trust.
_EPS_CULL = 1e-9
_CONE_PAD = 1e-6  # rad added to a tile's cone, far above rounding: culling never drops a ray's hit
TILE_PX = 16  # tile side (px) over which rectangles are culled


@njit(nogil=True, cache=True, inline="always")
def _bilinear(tex_data, tex_info, t, lev, fx, fy):
    off = tex_info[t, lev, 0]
    w = tex_info[t, lev, 1]
    h = tex_info[t, lev, 2]
    x0f = math.floor(fx)
    y0f = math.floor(fy)
    ax = fx - x0f
    ay = fy - y0f
    x0 = min(max(int(x0f), 0), w - 1)
    x1 = min(max(int(x0f) + 1, 0), w - 1)
    y0 = min(max(int(y0f), 0), h - 1)
    y1 = min(max(int(y0f) + 1, 0), h - 1)
    v00 = tex_data[off + y0 * w + x0]
    v01 = tex_data[off + y0 * w + x1]
    v10 = tex_data[off + y1 * w + x0]
    v11 = tex_data[off + y1 * w + x1]
    return (1.0 - ay) * ((1.0 - ax) * v00 + ax * v01) + ay * ((1.0 - ax) * v10 + ax * v11)


@njit(nogil=True, cache=True, inline="always")
def _mip_level(r, drays, y, x, cx, cy, cz, scale):
    """log2 of the footprint (texels) of one sample step through pixel (x, y) on the plane of camera-frame
    rectangle r, from the pixel-centre ray (cx, cy, cz) and its differentials; 0 when magnified."""
    nd = r[9] * cx + r[10] * cy + r[11] * cz
    if abs(nd) < _EPS_DENOM:
        return 0.0
    rho2 = 0.0
    for j in range(2):
        ex = drays[y, x, j, 0]
        ey = drays[y, x, j, 1]
        ez = drays[y, x, j, 2]
        f = (r[9] * ex + r[10] * ey + r[11] * ez) / nd
        px = ex - cx * f
        py = ey - cy * f
        pz = ez - cz * f
        da = r[3] * px + r[4] * py + r[5] * pz
        db = r[6] * px + r[7] * py + r[8] * pz
        rho2 = max(rho2, da * da + db * db)
    rho = abs(r[12] / nd) * math.sqrt(rho2) * scale
    return math.log2(rho) if rho > 1.0 else 0.0


@njit(nogil=True, cache=True)
def _tile_candidates(rc, rects, tile_axis, tile_sin, cand, ncand):
    """For every tile and sub-frame, the rectangles (ascending) that some sample ray of the tile may hit.

    The rays that hit a rectangle are the convex cone spanned by its corners (any point of the rectangle is a
    convex combination of them), bounded by the planes through the camera centre and each edge. A tile's rays lie
    within a cone of half-angle α about its axis u, so when u is more than 90° + α from one of those planes'
    inward normals, no ray of the tile hits the rectangle. The test is conservative, so the nearest hit of every
    ray, and the image, are unchanged."""
    P, K = rc.shape[0], rc.shape[1]
    TY, TX = tile_axis.shape[0], tile_axis.shape[1]
    corners = np.empty((4, 3))
    normals = np.empty((P, K, 4, 3))
    whole = np.zeros((P, K), dtype=np.bool_)  # the camera centre (nearly) in the rectangle's plane: never culled
    for p in range(P):
        for k in range(K):
            reach = math.sqrt(rc[p, k, 0] ** 2 + rc[p, k, 1] ** 2 + rc[p, k, 2] ** 2) + rects[k, 12] + rects[k, 13]
            if abs(rc[p, k, 12]) < _EPS_CULL * reach:
                whole[p, k] = True
                continue
            for i in range(3):
                corners[0, i] = rc[p, k, i]
                corners[1, i] = rc[p, k, i] + rc[p, k, 3 + i] * rects[k, 12]
                corners[2, i] = corners[1, i] + rc[p, k, 6 + i] * rects[k, 13]
                corners[3, i] = rc[p, k, i] + rc[p, k, 6 + i] * rects[k, 13]
            for e in range(4):
                c0 = corners[e]
                c1 = corners[(e + 1) % 4]
                c2 = corners[(e + 2) % 4]
                nx = c0[1] * c1[2] - c0[2] * c1[1]
                ny = c0[2] * c1[0] - c0[0] * c1[2]
                nz = c0[0] * c1[1] - c0[1] * c1[0]
                nn = math.sqrt(nx * nx + ny * ny + nz * nz)
                if nn < _EPS_CULL * reach * reach:
                    whole[p, k] = True
                    break
                if nx * c2[0] + ny * c2[1] + nz * c2[2] < 0.0:
                    nn = -nn
                normals[p, k, e, 0] = nx / nn
                normals[p, k, e, 1] = ny / nn
                normals[p, k, e, 2] = nz / nn
    for ty in range(TY):
        for tx in range(TX):
            ux = tile_axis[ty, tx, 0]
            uy = tile_axis[ty, tx, 1]
            uz = tile_axis[ty, tx, 2]
            lim = -tile_sin[ty, tx]
            for p in range(P):
                n = 0
                for k in range(K):
                    keep = True
                    if not whole[p, k]:
                        for e in range(4):
                            if normals[p, k, e, 0] * ux + normals[p, k, e, 1] * uy + normals[p, k, e, 2] * uz < lim:
                                keep = False
                                break
                    if keep:
                        cand[ty, tx, p, n] = k
                        n += 1
                ncand[ty, tx, p] = n


@njit(nogil=True, cache=True)
def _camera_frame(rects, poses):
    """(P, K, 13): the rectangles in each sub-frame's camera frame (rays then need no rotation): origin, axis a,
    axis b, normal, and the normal's distance term n·origin."""
    P, K = poses.shape[0], rects.shape[0]
    rc = np.empty((P, K, 13))
    for p in range(P):
        for k in range(K):
            for v in range(4):
                for i in range(3):
                    acc = 0.0
                    for j in range(3):
                        w = rects[k, 3 * v + j] - (poses[p, j, 3] if v == 0 else 0.0)
                        acc += poses[p, j, i] * w  # R_wcᵀ · w
                    rc[p, k, 3 * v + i] = acc
            rc[p, k, 12] = rc[p, k, 9] * rc[p, k, 0] + rc[p, k, 10] * rc[p, k, 1] + rc[p, k, 11] * rc[p, k, 2]
    return rc


@njit(nogil=True, cache=True)
def render(
    rays,
    crays,
    drays,
    sample_step,
    poses,
    rects,
    rect_tex,
    tex_data,
    tex_info,
    tex_levels,
    tex_texel,
    background,
    tile_axis,
    tile_sin,
    out,
):
    """Fill ``out`` (H, W) float32 with the mean shade of every pixel's samples over all sub-frames.

    Pixels are visited in tiles of ``TILE_PX`` whose rays lie within ``tile_sin`` (sine of the half-angle) of the
    unit ``tile_axis`` (``tile_cones``); each tile's rays are tested only against the rectangles they may hit."""
    P, K = poses.shape[0], rects.shape[0]
    rc = _camera_frame(rects, poses)
    TY, TX = tile_axis.shape[0], tile_axis.shape[1]
    cand = np.empty((TY, TX, P, K), dtype=np.int64)
    ncand = np.empty((TY, TX, P), dtype=np.int64)
    _tile_candidates(rc, rects, tile_axis, tile_sin, cand, ncand)
    for ty in range(TY):
        for tx in range(TX):
            _render_tile(
                rays, crays, drays, sample_step, rc, rects, rect_tex, tex_data, tex_info, tex_levels, tex_texel,
                background, cand[ty, tx], ncand[ty, tx], ty * TILE_PX, tx * TILE_PX, out,
            )  # fmt: skip


@njit(nogil=True, cache=True)
def _render_tile(
    rays, crays, drays, sample_step, rc, rects, rect_tex, tex_data, tex_info, tex_levels, tex_texel, background,
    cand, ncand, y0, x0, out,
):  # fmt: skip
    """The pixels of the tile from (x0, y0), their rays tested against the tile's candidates ``cand[p, :ncand[p]]``
    in sub-frame p. Candidates are ascending, so a tie in depth goes to the lower index, as without culling."""
    H, W, S = rays.shape[0], rays.shape[1], rays.shape[2]
    P, K = rc.shape[0], rc.shape[1]
    lam_k = np.empty(K)  # mip level of each rectangle at the current pixel and sub-frame, once needed
    inv_n = 1.0 / (P * S)
    for y in range(y0, min(H, y0 + TILE_PX)):
        for x in range(x0, min(W, x0 + TILE_PX)):
            acc = 0.0
            for p in range(P):
                lam_k[:] = -1.0
                for s in range(S):
                    dx = rays[y, x, s, 0]
                    dy = rays[y, x, s, 1]
                    dz = rays[y, x, s, 2]
                    best = np.inf
                    kb = -1
                    ab = 0.0
                    bb = 0.0
                    for j in range(ncand[p]):
                        k = cand[p, j]
                        nd = rc[p, k, 9] * dx + rc[p, k, 10] * dy + rc[p, k, 11] * dz
                        if abs(nd) < _EPS_DENOM:
                            continue
                        tt = rc[p, k, 12] / nd
                        if tt <= _EPS_T or tt >= best:
                            continue
                        qx = tt * dx - rc[p, k, 0]
                        qy = tt * dy - rc[p, k, 1]
                        qz = tt * dz - rc[p, k, 2]
                        a = rc[p, k, 3] * qx + rc[p, k, 4] * qy + rc[p, k, 5] * qz
                        b = rc[p, k, 6] * qx + rc[p, k, 7] * qy + rc[p, k, 8] * qz
                        if a < 0.0 or a > rects[k, 12] or b < 0.0 or b > rects[k, 13]:
                            continue
                        best = tt
                        kb = k
                        ab = a
                        bb = b
                    if kb < 0:
                        acc += background
                        continue
                    t = rect_tex[kb]
                    if lam_k[kb] < 0.0:
                        c = crays[y, x]
                        lam_k[kb] = _mip_level(rc[p, kb], drays, y, x, c[0], c[1], c[2], sample_step / tex_texel[t])
                    lam = lam_k[kb]
                    top = tex_levels[t] - 1
                    if lam >= top:
                        lev0 = top
                        frac = 0.0
                    else:
                        lev0 = int(lam)
                        frac = lam - lev0
                    sc = 1.0 / (tex_texel[t] * (1 << lev0))
                    v = _bilinear(tex_data, tex_info, t, lev0, ab * sc - 0.5, bb * sc - 0.5)
                    if frac > 0.0:
                        v1 = _bilinear(tex_data, tex_info, t, lev0 + 1, ab * sc * 0.5 - 0.5, bb * sc * 0.5 - 0.5)
                        v = (1.0 - frac) * v + frac * v1
                    acc += v
            out[y, x] = acc * inv_n


@njit(nogil=True, cache=True)
def tile_cones(rays):
    """Per ``TILE_PX`` tile of the sample rays (H, W, S, 3): the unit mean ray (TY, TX, 3), and the sine of the
    largest angle from it to a ray of the tile, padded by ``_CONE_PAD`` rad (2 where that reaches 90°: no tile
    culling). Rays that are not finite are left out."""
    H, W, S = rays.shape[0], rays.shape[1], rays.shape[2]
    TY = (H + TILE_PX - 1) // TILE_PX
    TX = (W + TILE_PX - 1) // TILE_PX
    axis = np.zeros((TY, TX, 3))
    sin = np.full((TY, TX), 2.0)
    for ty in range(TY):
        for tx in range(TX):
            y1, x1 = min(H, (ty + 1) * TILE_PX), min(W, (tx + 1) * TILE_PX)
            sx = sy = sz = 0.0
            for y in range(ty * TILE_PX, y1):
                for x in range(tx * TILE_PX, x1):
                    for s in range(S):
                        if np.isfinite(rays[y, x, s, 0] + rays[y, x, s, 1] + rays[y, x, s, 2]):
                            sx += rays[y, x, s, 0]
                            sy += rays[y, x, s, 1]
                            sz += rays[y, x, s, 2]
            n = math.sqrt(sx * sx + sy * sy + sz * sz)
            if not n > 0.0:
                continue
            ux, uy, uz = sx / n, sy / n, sz / n
            cmin = 1.0
            for y in range(ty * TILE_PX, y1):
                for x in range(tx * TILE_PX, x1):
                    for s in range(S):
                        c = ux * rays[y, x, s, 0] + uy * rays[y, x, s, 1] + uz * rays[y, x, s, 2]
                        if np.isfinite(c):
                            cmin = min(cmin, c)
            alpha = math.acos(max(-1.0, min(1.0, cmin))) + _CONE_PAD
            axis[ty, tx, 0], axis[ty, tx, 1], axis[ty, tx, 2] = ux, uy, uz
            if alpha < 0.5 * math.pi:
                sin[ty, tx] = math.sin(alpha)
    return axis, sin


def intersect_rays(origins, dirs, rects):
    """Nearest rectangle hit of rays (N, 3) from origins (N, 3) or (3,): (t, k, a, b), k = −1 and t = inf on a miss."""
    dirs = np.asarray(dirs, dtype=np.float64)
    origins = np.broadcast_to(np.asarray(origins, dtype=np.float64), dirs.shape)
    n = rects[:, 9:12]
    nd = dirs @ n.T  # (N, K)
    diff = rects[None, :, 0:3] - origins[:, None, :]  # (N, K, 3)
    with np.errstate(divide="ignore", invalid="ignore"):  # rays parallel to a plane: inf / nan, rejected below
        t = np.einsum("nkc,kc->nk", diff, n) / nd
        q = t[..., None] * dirs[:, None, :] - diff
        a = np.einsum("nkc,kc->nk", q, rects[:, 3:6])
        b = np.einsum("nkc,kc->nk", q, rects[:, 6:9])
        ok = (
            (np.abs(nd) >= _EPS_DENOM)
            & (t > _EPS_T)
            & (a >= 0.0)
            & (a <= rects[:, 12])
            & (b >= 0.0)
            & (b <= rects[:, 13])
        )
    t = np.where(ok, t, np.inf)
    k = np.argmin(t, axis=1)
    rows = np.arange(len(dirs))
    tk = t[rows, k]
    hit = np.isfinite(tk)
    return tk, np.where(hit, k, -1), a[rows, k], b[rows, k]
