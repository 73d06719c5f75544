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
def epipolar_search(
    img, corners, corners_plane, row_lut, box, templates, normal, dist, along, lo, hi, max_perp, max_ssd
):
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
