"""Small-patch SSD search at FAST corners, for the 2-D trails of stereo initialisation (PTAM §6.1).

PTAM code (``MiniPatch``): a (2h+1)² patch sampled at an integer pixel, compared by plain (not zero-mean)
SSD at every FAST corner within a circular radius of a predicted position; the best one is a match when
its SSD is below ``max_ssd``. The template is scaled by ``gain`` first, the frame-wide brightness ratio of
``dst`` to ``src`` (1 = PTAM's plain SSD), so a change of exposure does not end the trails while the SSD still
tells patches of different brightness apart (a zero-mean SSD would not).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..image.corner_rows import first_in_row


@njit(nogil=True, cache=True)
def minipatch_find(src, src_xy, dst, dst_xy, corners, row_lut, radius, half, max_ssd, gain):
    """For each i: template at ``src_xy[i]`` in ``src``, searched in ``dst`` around ``dst_xy[i]``.

    Returns found (T, 2) int32 and ok (T,) bool. Ties keep the corner met first (row-major order). ``corners``
    are sorted by y, then x (``fast_corners``): within each row of the circle the first one in range is found by
    binary search from the row look-up table, as the tracker's patch search does (a full-row scan took 40 % of
    a trail step on two_wall's 31 000 level-0 corners).
    """
    n = src_xy.shape[0]
    hs, ws = src.shape
    hd, wd = dst.shape
    found = np.zeros((n, 2), dtype=np.int32)
    ok = np.zeros(n, dtype=np.bool_)
    r2 = radius * radius
    for i in range(n):
        sx = src_xy[i, 0]
        sy = src_xy[i, 1]
        if sx < half or sy < half or sx >= ws - half or sy >= hs - half:
            continue
        cx = dst_xy[i, 0]
        cy = dst_xy[i, 1]
        y0 = max(cy - radius, half)
        y1 = min(cy + radius, hd - 1 - half)
        if y1 < y0:
            continue
        best = float(max_ssd)
        bx = -1
        by = -1
        x_lo = max(cx - radius, half)
        x_hi = min(cx + radius, wd - 1 - half)
        for row in range(y0, y1 + 1):
            for k in range(first_in_row(corners, row_lut, row, x_lo), row_lut[row + 1]):
                x = corners[k, 0]
                if x > x_hi:
                    break
                dx = x - cx
                dy = row - cy
                if dx * dx + dy * dy > r2:
                    continue
                acc = 0.0
                for v in range(-half, half + 1):
                    for u in range(-half, half + 1):
                        d = float(dst[row + v, x + u]) - gain * float(src[sy + v, sx + u])
                        acc += d * d
                        if acc >= best:
                            break
                    if acc >= best:
                        break
                if acc < best:
                    best = acc
                    bx = x
                    by = row
        if bx >= 0:
            found[i, 0] = bx
            found[i, 1] = by
            ok[i] = True
    return found, ok
