"""Zero-mean SSD search for new-point candidates along an epipolar segment (PTAM §6.2).

PTAM code (``MapMaker::AddPointEpipolar``): the target level's FAST corners, unprojected to the unit
plane, are kept when their perpendicular distance to the epipolar line is within ``max_perp`` and their
position along it lies in [lo, hi]; the lowest zero-mean SSD against the unwarped source template wins
when below ``max_ssd``. Straight lines on the unit plane stay exact under lens distortion, which is why
the test is made there and not in pixels. Only corners inside a per-candidate pixel box around the segment
(rows through the row look-up table, PTAM §6.5) are examined, so a level with tens of thousands of corners
costs a few hundred tests per candidate. ``epipolar_search_ref`` is the numpy reference.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def epipolar_search(img, corners, corners_plane, row_lut, box, templates, normal, dist, along, lo, hi, max_perp,
                    max_ssd):
    """img: target level (H, W) uint8; corners (K, 2) int32 level pixels (sorted by row, ``row_lut`` (H+1,))
    with unit-plane positions corners_plane (K, 2); per candidate: pixel box (x0, y0, x1, y1) int, template
    (size, size) zero-mean, line normal (2,), offset ``dist`` (normal·p = dist on the line), direction
    ``along`` (2,), extent [lo, hi] along it.

    Returns the best corner index (n,) int64 (−1 when none) and its score (n,).
    """
    n = templates.shape[0]
    size = templates.shape[1]
    h = size // 2
    npix = size * size
    H, W = img.shape
    best = np.full(n, -1, dtype=np.int64)
    score = np.full(n, np.inf)
    for k in range(n):
        tsq = 0.0
        for r in range(size):
            for c in range(size):
                tsq += templates[k, r, c] * templates[k, r, c]
        bs = max_ssd
        y0 = min(max(box[k, 1], 0), H - 1)
        y1 = min(max(box[k, 3], 0), H - 1)
        for j in range(row_lut[y0], row_lut[y1 + 1]):
            if corners[j, 0] < box[k, 0] or corners[j, 0] > box[k, 2]:
                continue
            px = corners_plane[j, 0]
            py = corners_plane[j, 1]
            d = dist[k] - (px * normal[k, 0] + py * normal[k, 1])
            if d * d > max_perp[k] * max_perp[k]:
                continue
            t = px * along[k, 0] + py * along[k, 1]
            if t < lo[k] or t > hi[k]:
                continue
            x = corners[j, 0]
            y = corners[j, 1]
            if x < h or y < h or x > W - size + h or y > H - size + h:
                continue
            s = 0.0
            ss = 0.0
            cross = 0.0
            for r in range(size):
                for c in range(size):
                    v = float(img[y - h + r, x - h + c])
                    s += v
                    ss += v * v
                    cross += v * templates[k, r, c]
            z = ss - s * s / npix - 2.0 * cross + tsq
            if z < bs:
                bs = z
                best[k] = j
        if best[k] >= 0:
            score[k] = bs
    return best, score


def epipolar_search_ref(img, corners, corners_plane, box, templates, normal, dist, along, lo, hi, max_perp, max_ssd):
    """Numpy reference: every candidate against every corner by broadcasting."""
    n, size = templates.shape[:2]
    h = size // 2
    H, W = img.shape
    best = np.full(n, -1, dtype=np.int64)
    score = np.full(n, np.inf)
    x, y = corners[:, 0], corners[:, 1]
    inside = (x >= h) & (y >= h) & (x <= W - size + h) & (y <= H - size + h)
    off = np.arange(size) - h
    patches = img[np.clip(y[:, None, None] + off[None, :, None], 0, H - 1),
                  np.clip(x[:, None, None] + off[None, None, :], 0, W - 1)].astype(np.float64)
    pz = patches - patches.mean(axis=(1, 2), keepdims=True)
    for k in range(n):
        d = dist[k] - corners_plane @ normal[k]
        t = corners_plane @ along[k]
        in_box = (x >= box[k, 0]) & (x <= box[k, 2]) & (y >= box[k, 1]) & (y <= box[k, 3])
        ok = inside & in_box & (d * d <= max_perp[k] ** 2) & (t >= lo[k]) & (t <= hi[k])
        if not ok.any():
            continue
        T = templates[k].astype(np.float64)
        z = ((pz[ok] - (T - T.mean())) ** 2).sum(axis=(1, 2))
        j = int(np.argmin(z))
        if z[j] < max_ssd:
            best[k] = np.flatnonzero(ok)[j]
            score[k] = z[j]
    return best, score
