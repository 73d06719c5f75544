"""Per-pixel ray-cast rasteriser for the AR overlay (PTAM §7.5): shaded spheres and decals on the plane.

Every pixel's ray d = (x, y, 1) is read from a table built once from the camera model's exact unprojection
(``RAY_*`` channels: x, y, 1/|d|², 1/f and f·|d|, where f, the footprint, is the unit-plane distance between
neighbouring pixels' rays), so the objects follow the lens distortion exactly, with no mesh and no undistorted
intermediate image (PTAM renders undistorted to a texture and warps it with a 24×32 mesh). The footprint turns
object edges into one-pixel-wide anti-aliasing ramps.

Spheres write a z-buffer (camera z) and are tested against it, so they occlude one another correctly in any
order; drawn back to front, their anti-aliased rims also blend over what lies behind. Decals lie on the plane
(shadows, rings) and are drawn after the spheres, only where the z-buffer is empty: spheres resting on the
plane are always nearer a camera above it than the plane behind them.

Record layouts (float64 rows; camera frame):

- sphere: centre (3), radius, R_co (9, object→camera, row-major), colours A, B, C (3 each, BGR 0–255),
  pattern, p0, p1, specular scale. Patterns: ``PLAIN`` (A), ``EYE`` (about the object's +z: C where
  cos θ > p0 (pupil), B where cos θ > p1 (iris), else A), ``BALL`` (p0 longitude sectors alternating A and B,
  caps where |cos θ| > p1 in C).
- decal: centre (u, v) in plane coordinates, inner and outer radius, softness (plane units), colour (3), alpha.
- plane: origin (3), in-plane axes e1, e2 (3 each), normal (3).
- shading: ambient, diffuse, specular, shininess (Blinn–Phong, one directional light; the half vector is taken
  per sphere, towards its centre, which spheres a few degrees wide cannot tell from per pixel).

Lines (the grid) are anti-aliased by distance: every pixel near a segment of a polyline gets coverage
clamp(w + ½ − distance, 0, 1) for half-width w, kept as the maximum over segments in a coverage buffer, so
the joints of a densely sampled polyline are not blended twice; the buffer is then blended and cleared pixel by
pixel (only the pixels touched), ready for the next frame.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project

PLAIN, EYE, BALL = 0, 1, 2
S_RADIUS, S_ROT, S_COLOURS, S_PATTERN, S_P0, S_P1, S_SPEC = 3, 4, 13, 22, 23, 24, 25  # centre at 0:3
SPHERE_LEN = 26
D_RIN, D_ROUT, D_SOFT, D_COLOUR, D_ALPHA = 2, 3, 4, 5, 8  # centre (u, v) at 0:2
DECAL_LEN = 9
RAY_X, RAY_Y, RAY_INV_DD, RAY_INV_FP, RAY_FP_NORM = 0, 1, 2, 3, 4
RAY_LEN = 5


def ray_table(xy: np.ndarray) -> np.ndarray:
    """(H, W, RAY_LEN) float32 table from the unit-plane rays (H, W, 2) of every pixel."""
    xy = np.asarray(xy, np.float64)
    step_x = np.linalg.norm(np.gradient(xy, axis=1), axis=-1)
    step_y = np.linalg.norm(np.gradient(xy, axis=0), axis=-1)
    fp = 0.5 * (step_x + step_y)
    dd = (xy**2).sum(axis=-1) + 1.0
    return np.stack([xy[..., 0], xy[..., 1], 1.0 / dd, 1.0 / fp, fp * np.sqrt(dd)], axis=-1).astype(np.float32)


def specular_cutoff(specular: float, shininess: float) -> float:
    """cos(n, h) below which the highlight adds less than half a grey level (the power function is skipped)."""
    return (0.5 / (255.0 * specular)) ** (1.0 / shininess) if specular > 0.0 else 1.0


def sphere_half_vector(centre: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Blinn's half vector between the light and the direction from the sphere's centre to the camera."""
    h = light - centre / np.linalg.norm(centre)
    n = np.linalg.norm(h)
    return h / n if n > 0 else h


@njit(nogil=True, cache=True, inline="always")
def _pattern_colour(s, mx, my, mz):
    """Offset in the sphere record of the colour at object-frame unit normal (mx, my, mz)."""
    pattern = int(s[S_PATTERN])
    if pattern == EYE:
        if mz > s[S_P0]:
            return S_COLOURS + 6
        if mz > s[S_P1]:
            return S_COLOURS + 3
    elif pattern == BALL:
        if abs(mz) > s[S_P1]:
            return S_COLOURS + 6
        k = int(math.floor((math.atan2(my, mx) + math.pi) * s[S_P0] / (2.0 * math.pi)))
        return S_COLOURS + 3 * (k % 2)
    return S_COLOURS


@njit(nogil=True, cache=True)
def draw_spheres(img, zbuf, rays, spheres, boxes, light, shading):
    """Ray-cast spheres into ``img`` (H, W, 3) uint8 with z-buffer ``zbuf`` (H, W) float64, in record order,
    each over its pixel box [x0, y0, x1, y1) (``boxes`` (N, 4) int); ``rays`` is the ``ray_table``."""
    ambient, diffuse, specular, shininess = shading[0], shading[1], shading[2], shading[3]
    nh_min = (0.5 / (255.0 * specular)) ** (1.0 / shininess) if specular > 0.0 else 1.0
    for k in range(spheres.shape[0]):
        s = spheres[k]
        cx, cy, cz, r = s[0], s[1], s[2], s[S_RADIUS]
        cc = cx * cx + cy * cy + cz * cz
        cl = math.sqrt(cc)
        hx, hy, hz = light[0] - cx / cl, light[1] - cy / cl, light[2] - cz / cl
        hl = math.sqrt(hx * hx + hy * hy + hz * hz)
        if hl > 0.0:
            hx, hy, hz = hx / hl, hy / hl, hz / hl
        inv_r = 1.0 / r
        inv_cz = 1.0 / cz  # the rim ramp's width uses the centre's depth (r/z off at most)
        for v in range(boxes[k, 1], boxes[k, 3]):
            for u in range(boxes[k, 0], boxes[k, 2]):
                ray = rays[v, u]
                dx = np.float64(ray[RAY_X])
                dy = np.float64(ray[RAY_Y])
                inv_dd = np.float64(ray[RAY_INV_DD])
                dc = dx * cx + dy * cy + cz
                t0 = dc * inv_dd
                if t0 <= 0.0:
                    continue
                d2 = cc - dc * t0  # squared distance from the centre to the ray
                inv_w = np.float64(ray[RAY_INV_FP]) * inv_cz
                edge = r + 0.5 / inv_w
                if d2 >= edge * edge:
                    continue
                d2 = max(d2, 0.0)
                dist = math.sqrt(d2)
                cov = min(0.5 + (r - dist) * inv_w, 1.0)
                hit = dist < r
                # Rim pixels whose ray misses are shaded at the ray's closest approach (the silhouette).
                t = t0 - math.sqrt((r * r - d2) * inv_dd) if hit else t0
                if t <= 0.0 or t >= zbuf[v, u]:
                    continue
                px, py, pz = t * dx - cx, t * dy - cy, t - cz
                if hit:
                    nx, ny, nz = px * inv_r, py * inv_r, pz * inv_r
                else:
                    nl = math.sqrt(px * px + py * py + pz * pz)
                    if nl == 0.0:
                        continue
                    nx, ny, nz = px / nl, py / nl, pz / nl
                mx = s[4] * nx + s[7] * ny + s[10] * nz
                my = s[5] * nx + s[8] * ny + s[11] * nz
                mz = s[6] * nx + s[9] * ny + s[12] * nz
                ci = _pattern_colour(s, mx, my, mz)
                lam = max(nx * light[0] + ny * light[1] + nz * light[2], 0.0)
                nh = nx * hx + ny * hy + nz * hz
                spec = 255.0 * specular * s[S_SPEC] * nh**shininess if nh > nh_min else 0.0
                inten = ambient + diffuse * lam
                if cov >= 1.0:
                    for c in range(3):
                        img[v, u, c] = np.uint8(min(s[ci + c] * inten + spec, 255.0) + 0.5)
                else:
                    for c in range(3):
                        val = min(s[ci + c] * inten + spec, 255.0)
                        img[v, u, c] = np.uint8(np.float64(img[v, u, c]) * (1.0 - cov) + val * cov + 0.5)
                if cov >= 0.5:
                    zbuf[v, u] = t


@njit(nogil=True, cache=True)
def draw_decals(img, zbuf, rays, plane, decals, boxes):
    """Blend soft discs and rings lying on the plane into ``img`` over their boxes, where no sphere has been drawn
    (a sphere resting on the plane is always nearer a camera above the plane than the plane behind it)."""
    ox, oy, oz = plane[0], plane[1], plane[2]
    nx, ny, nz = plane[9], plane[10], plane[11]
    nd = nx * ox + ny * oy + nz * oz
    for k in range(decals.shape[0]):
        d = decals[k]
        soft, r_in, r_out = d[D_SOFT], d[D_RIN], d[D_ROUT]
        for v in range(boxes[k, 1], boxes[k, 3]):
            for u in range(boxes[k, 0], boxes[k, 2]):
                if zbuf[v, u] < np.inf:  # a sphere is drawn here: it is nearer than the plane
                    continue
                ray = rays[v, u]
                dx = np.float64(ray[RAY_X])
                dy = np.float64(ray[RAY_Y])
                den = nx * dx + ny * dy + nz
                if abs(den) < 1e-12:
                    continue
                inv_den = 1.0 / den
                t = nd * inv_den
                if t <= 0.0:
                    continue
                qx, qy, qz = t * dx - ox, t * dy - oy, t - oz
                a = plane[3] * qx + plane[4] * qy + plane[5] * qz - d[0]
                b = plane[6] * qx + plane[7] * qy + plane[8] * qz - d[1]
                rho2 = a * a + b * b
                # Edge ramp: the decal's own softness plus one pixel's footprint on the (slanted) plane.
                w = soft + abs(nd) * np.float64(ray[RAY_FP_NORM]) * inv_den * inv_den
                reach = r_out + 0.5 * w
                if rho2 >= reach * reach:
                    continue
                rho = math.sqrt(rho2)
                inv_w = 1.0 / w
                cov = min((r_out - rho) * inv_w + 0.5, 1.0)
                if r_in > 0.0:
                    cov *= min(max((rho - r_in) * inv_w + 0.5, 0.0), 1.0)
                alpha = d[D_ALPHA] * cov
                if alpha <= 0.0:
                    continue
                for c in range(3):
                    img[v, u, c] = np.uint8(np.float64(img[v, u, c]) * (1.0 - alpha) + d[D_COLOUR + c] * alpha + 0.5)


@njit(nogil=True, cache=True, inline="always")
def _rasterise_segment(cov, touched, n, W, H, x0, y0, x1, y1, reach):
    """One segment into the flat coverage buffer ``cov`` (H·W), walked along its major axis a (b the minor one;
    pixel (a, b) is flat index a·sa + b·sb). Branch-free per pixel: every pixel of the band is written (its
    coverage kept as the maximum, so pixels out of reach keep theirs) and its index stored at ``touched[n]``, which
    only counts (n grows) for a pixel newly within reach; the last slot of ``touched`` is scratch, for a full
    buffer."""
    cap = touched.shape[0] - 1
    ex, ey = x1 - x0, y1 - y0
    ee = ex * ex + ey * ey
    inv_ee = 1.0 / ee if ee > 0.0 else 0.0
    if abs(ey) > abs(ex):  # steep: a = y, b = x
        a0, b0, a1, b1, ea, eb, oa, ob, amax, bmax, sa, sb = y0, x0, y1, x1, ey, ex, y0, x0, H, W, W, 1
    else:
        a0, b0, a1, b1, ea, eb, oa, ob, amax, bmax, sa, sb = x0, y0, x1, y1, ex, ey, x0, y0, W, H, 1, W
    if a1 < a0:
        a0, b0, a1, b1 = a1, b1, a0, b0
    slope = (b1 - b0) / (a1 - a0) if a1 > a0 else 0.0
    band = reach * math.sqrt(1.0 + slope * slope) + 0.5
    r2 = reach * reach
    for a in range(max(int(math.floor(a0)), 0), min(int(math.ceil(a1)), amax - 1) + 1):
        bc = b0 + slope * (min(max(a, a0), a1) - a0)
        pa = a - oa
        for b in range(max(int(math.ceil(bc - band)), 0), min(int(math.floor(bc + band)), bmax - 1) + 1):
            pb = b - ob
            t = min(max((pa * ea + pb * eb) * inv_ee, 0.0), 1.0)
            da, db = pa - t * ea, pb - t * eb
            d2 = da * da + db * db
            i = a * sa + b * sb
            old = cov[i]
            touched[min(n, cap)] = i
            n = min(n + ((old == 0.0) & (d2 < r2)), cap)
            cov[i] = max(old, np.float32(min(reach - math.sqrt(d2), 1.0)))
    return n


@njit(nogil=True, cache=True)
def rasterise_polylines(cov, touched, uv, ok, half_width):
    """Coverage of polylines (L, S, 2) (pixel positions; segment s → s+1 of a line is drawn when ``ok`` holds
    at both ends) of half-width ``half_width`` into ``cov`` (H, W) float32 (zero on entry except where already
    drawn), as the maximum over segments; appends each newly covered pixel's flat index to ``touched`` (its last
    slot is scratch: capacity ``len(touched) - 1``) and returns how many it holds.

    Each segment is walked along its major axis between its end points only (consecutive segments share end
    points, so a line is continuous; its two ends are cut square), over the band of the minor axis that can lie
    within w + 1/2 of it.
    """
    H, W = cov.shape
    flat = cov.reshape(-1)
    n = 0
    reach = half_width + 0.5
    for i in range(uv.shape[0]):
        for s in range(uv.shape[1] - 1):
            if ok[i, s] and ok[i, s + 1]:
                n = _rasterise_segment(
                    flat, touched, n, W, H, uv[i, s, 0], uv[i, s, 1], uv[i, s + 1, 0], uv[i, s + 1, 1], reach
                )
    return n


@njit(nogil=True, cache=True)
def blend_coverage(img, cov, touched, n, colour, alpha):
    """Blend ``colour`` at ``alpha`` × coverage into the touched pixels of ``img`` (H, W, C) (C-contiguous; C = 3:
    BGR; C = 1: grey, with ``colour[0]``) and clear their coverage. Pixels are addressed by their flat index."""
    C = img.shape[2]
    pixels = img.reshape(-1, C)
    flat = cov.reshape(-1)
    for i in range(n):
        p = touched[i]
        a = alpha * np.float64(flat[p])
        flat[p] = 0.0
        for c in range(C):
            pixels[p, c] = np.uint8(np.float64(pixels[p, c]) * (1.0 - a) + colour[c] * a + 0.5)


@njit(nogil=True, cache=True)
def outline_boxes(samples, visible, cam, max_radius, W, H, margin):
    """Pixel boxes [x0, y0, x1, y1) (N, 4) int bounding projected outline samples (N, K, 3) (camera frame) through
    the lens ``cam`` (``CameraModel.kernel_params()``), padded by ``margin`` px and clipped to the W×H image; empty
    (zeros) where not ``visible``. Samples beyond the projectable cone (unit-plane radius ``max_radius``) are first
    pulled radially onto its edge, which lies outside the image (radial lens models are monotonic inside it), so
    the box still covers every image pixel of the object; an outline reaching behind the camera gets the whole
    image (the raster kernels test every pixel exactly)."""
    n, k = samples.shape[0], samples.shape[1]
    boxes = np.zeros((n, 4), np.int64)
    for i in range(n):
        if not visible[i]:
            continue
        boxes[i, 2], boxes[i, 3] = W, H
        front = True
        for j in range(k):
            front = front and samples[i, j, 2] > 0.0
        if not front:
            continue
        u0, v0, u1, v1 = np.inf, np.inf, -np.inf, -np.inf
        for j in range(k):
            x, y = samples[i, j, 0] / samples[i, j, 2], samples[i, j, 1] / samples[i, j, 2]
            r = math.sqrt(x * x + y * y)
            scale = min(1.0, max_radius / r) if r > 0.0 else 1.0
            u, v, _ = project(cam, x * scale, y * scale, 1.0)
            u0, v0, u1, v1 = min(u0, u), min(v0, v), max(u1, u), max(v1, v)
        boxes[i, 0] = min(max(int(math.floor(u0)) - margin, 0), W)
        boxes[i, 1] = min(max(int(math.floor(v0)) - margin, 0), H)
        boxes[i, 2] = min(max(int(math.ceil(u1)) + margin + 1, 0), W)
        boxes[i, 3] = min(max(int(math.ceil(v1)) + margin + 1, 0), H)
    return boxes
