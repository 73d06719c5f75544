"""numpy references for ``ptam.ar.raster_kernels``: plain numpy, compared with the kernels."""

from __future__ import annotations

import numpy as np

from ptam.ar.raster_kernels import (
    BALL,
    D_ALPHA,
    D_COLOUR,
    D_RIN,
    D_ROUT,
    D_SOFT,
    EYE,
    RAY_FP_NORM,
    RAY_INV_DD,
    RAY_INV_FP,
    RAY_LEN,
    S_COLOURS,
    S_P0,
    S_P1,
    S_PATTERN,
    S_RADIUS,
    S_ROT,
    S_SPEC,
    specular_cutoff,
    sphere_half_vector,
)


# -- numpy references (same arithmetic, vectorised per object) ----------------------------------------------
def _pattern_colour_ref(s, m):
    idx = np.full(m.shape[0], S_COLOURS)
    pattern = int(s[S_PATTERN])
    if pattern == EYE:
        idx = np.where(m[:, 2] > s[S_P1], S_COLOURS + 3, idx)
        idx = np.where(m[:, 2] > s[S_P0], S_COLOURS + 6, idx)
    elif pattern == BALL:
        k = np.floor((np.arctan2(m[:, 1], m[:, 0]) + np.pi) * s[S_P0] / (2.0 * np.pi)).astype(np.int64)
        idx = S_COLOURS + 3 * (k % 2)
        idx = np.where(np.abs(m[:, 2]) > s[S_P1], S_COLOURS + 6, idx)
    return idx


def _box_rays(rays, box):
    x0, y0, x1, y1 = (int(b) for b in box)
    if x1 <= x0 or y1 <= y0:
        return None, (x0, y0, x1, y1)
    return rays[y0:y1, x0:x1].astype(np.float64).reshape(-1, RAY_LEN), (x0, y0, x1, y1)


def _blend_ref(img, zbuf, box, idx, colour, cov, z=None):
    x0, y0, x1, y1 = box
    sub = img[y0:y1, x0:x1].reshape(-1, 3)
    sub[idx] = (sub[idx].astype(np.float64) * (1.0 - cov[:, None]) + colour * cov[:, None] + 0.5).astype(np.uint8)
    img[y0:y1, x0:x1] = sub.reshape(y1 - y0, x1 - x0, 3)
    if z is not None:
        zs = zbuf[y0:y1, x0:x1].reshape(-1)
        w = cov >= 0.5
        zs[idx[w]] = z[w]
        zbuf[y0:y1, x0:x1] = zs.reshape(y1 - y0, x1 - x0)


def draw_spheres_ref(img, zbuf, rays, spheres, boxes, light, shading):
    ambient, diffuse, specular, shininess = shading
    for k in range(len(spheres)):
        s = spheres[k]
        ray, box = _box_rays(rays, boxes[k])
        if ray is None:
            continue
        c, r = s[:3], s[S_RADIUS]
        d = np.concatenate([ray[:, :2], np.ones((len(ray), 1))], axis=1)
        dc = d @ c
        t0 = dc * ray[:, RAY_INV_DD]
        d2 = c @ c - dc * t0
        inv_w = ray[:, RAY_INV_FP] / c[2]
        outside = d2 >= (r + 0.5 / inv_w) ** 2
        d2 = np.maximum(d2, 0.0)
        dist = np.sqrt(d2)
        cov = np.minimum(0.5 + (r - dist) * inv_w, 1.0)
        hit = dist < r
        t = np.where(hit, t0 - np.sqrt(np.maximum(r * r - d2, 0.0) * ray[:, RAY_INV_DD]), t0)
        z = zbuf[box[1] : box[3], box[0] : box[2]].reshape(-1)
        p = t[:, None] * d - c
        nl = np.linalg.norm(p, axis=1)
        ok = (t0 > 0) & ~outside & (t > 0) & (t < z) & (hit | (nl > 0))
        with np.errstate(divide="ignore", invalid="ignore"):
            n = np.where(hit[:, None], p / r, p / nl[:, None])[ok]
        m = n @ s[S_ROT : S_ROT + 9].reshape(3, 3)
        base = s[_pattern_colour_ref(s, m)[:, None] + np.arange(3)]
        lam = np.maximum(n @ light, 0.0)
        nh = n @ sphere_half_vector(c, light)
        with np.errstate(invalid="ignore"):
            spec = np.where(
                nh > specular_cutoff(specular, shininess),
                255.0 * specular * s[S_SPEC] * np.maximum(nh, 0.0) ** shininess,
                0.0,
            )
        val = np.minimum(base * (ambient + diffuse * lam)[:, None] + spec[:, None], 255.0)
        _blend_ref(img, zbuf, box, np.flatnonzero(ok), val, cov[ok], t[ok])


def draw_decals_ref(img, zbuf, rays, plane, decals, boxes):
    o, e1, e2, nrm = plane[0:3], plane[3:6], plane[6:9], plane[9:12]
    nd = nrm @ o
    for k in range(len(decals)):
        dk = decals[k]
        ray, box = _box_rays(rays, boxes[k])
        if ray is None:
            continue
        d = np.concatenate([ray[:, :2], np.ones((len(ray), 1))], axis=1)
        den = d @ nrm
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_den = 1.0 / den
            t = nd * inv_den
        z = zbuf[box[1] : box[3], box[0] : box[2]].reshape(-1)
        q = t[:, None] * d - o
        a = q @ e1 - dk[0]
        b = q @ e2 - dk[1]
        rho2 = a * a + b * b
        w = dk[D_SOFT] + abs(nd) * ray[:, RAY_FP_NORM] * inv_den * inv_den
        with np.errstate(invalid="ignore"):
            ok = np.isinf(z) & (np.abs(den) >= 1e-12) & (t > 0) & (rho2 < (dk[D_ROUT] + 0.5 * w) ** 2)
        rho = np.sqrt(rho2[ok])
        cov = np.minimum((dk[D_ROUT] - rho) / w[ok] + 0.5, 1.0)
        if dk[D_RIN] > 0:
            cov = cov * np.clip((rho - dk[D_RIN]) / w[ok] + 0.5, 0.0, 1.0)
        alpha = dk[D_ALPHA] * cov
        draw = alpha > 0
        _blend_ref(img, zbuf, box, np.flatnonzero(ok)[draw], dk[D_COLOUR : D_COLOUR + 3], alpha[draw])


def rasterise_polylines_ref(shape, uv, ok, half_width):
    """Coverage image (H, W): max over the drawn segments of clamp(w + 1/2 - distance, 0, 1), each segment
    limited to the pixels whose major-axis coordinate lies within its end points' (rounded outwards)."""
    H, W = shape
    cov = np.zeros(shape)
    reach = half_width + 0.5
    y, x = np.mgrid[0:H, 0:W].astype(np.float64)
    keep = ok[:, :-1] & ok[:, 1:]
    for (x0, y0), (x1, y1) in zip(uv[:, :-1][keep], uv[:, 1:][keep]):
        steep = abs(y1 - y0) > abs(x1 - x0)
        a, (a0, a1) = (y, sorted((y0, y1))) if steep else (x, sorted((x0, x1)))
        inside = (a >= np.floor(a0)) & (a <= np.ceil(a1))
        e = np.array([x1 - x0, y1 - y0])
        ee = e @ e
        t = np.zeros_like(x) if ee == 0 else np.clip(((x - x0) * e[0] + (y - y0) * e[1]) / ee, 0.0, 1.0)
        d = np.hypot(x - x0 - t * e[0], y - y0 - t * e[1])
        cov = np.maximum(cov, np.where(inside, np.clip(reach - d, 0.0, 1.0), 0.0))
    return cov


def outline_boxes_ref(samples, visible, camera, max_radius, margin):
    """Pixel boxes [x0, y0, x1, y1) (N, 4) of outline samples (N, K, 3) projected by ``camera`` (after pulling
    samples beyond the projectable cone onto its edge), padded and clipped; the whole image for an outline reaching
    behind the camera, empty where not ``visible``."""
    n, k, _ = samples.shape
    W, H = camera.size
    z = samples[..., 2]
    front = (z > 0.0).all(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = samples[..., :2] / z[..., None]
        r = np.linalg.norm(xy, axis=-1, keepdims=True)
        xy = xy * np.minimum(1.0, max_radius / r)
    pts = np.concatenate([xy, np.ones((n, k, 1))], axis=-1)
    pts[~front] = [0.0, 0.0, 1.0]
    uv = camera.project(pts.reshape(-1, 3)).reshape(n, k, 2)
    boxes = np.zeros((n, 4), np.int64)
    boxes[:, 2], boxes[:, 3] = W, H
    boxes[front, 0:2] = np.floor(uv[front].min(axis=1)) - margin
    boxes[front, 2:4] = np.ceil(uv[front].max(axis=1)) + margin + 1
    boxes[:, [0, 2]] = np.clip(boxes[:, [0, 2]], 0, W)
    boxes[:, [1, 3]] = np.clip(boxes[:, [1, 3]], 0, H)
    boxes[~visible] = 0
    return boxes
