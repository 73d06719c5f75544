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


@njit(nogil=True, cache=True)
def minipatch_find(src, src_xy, dst, dst_xy, corners, row_lut, radius, half, max_ssd, gain):
    """For each i: template at ``src_xy[i]`` in ``src``, searched in ``dst`` around ``dst_xy[i]``.

    Returns found (T, 2) int32 and ok (T,) bool. Ties keep the corner met first (row-major order).
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
        for k in range(row_lut[y0], row_lut[y1 + 1]):
            x = corners[k, 0]
            y = corners[k, 1]
            if x < half or x >= wd - half:
                continue
            dx = x - cx
            dy = y - cy
            if dx * dx + dy * dy > r2:
                continue
            acc = 0.0
            for v in range(-half, half + 1):
                for u in range(-half, half + 1):
                    d = float(dst[y + v, x + u]) - gain * float(src[sy + v, sx + u])
                    acc += d * d
                    if acc >= best:
                        break
                if acc >= best:
                    break
            ssd = acc
            if ssd < best:
                best = ssd
                bx = x
                by = y
        if bx >= 0:
            found[i, 0] = bx
            found[i, 1] = by
            ok[i] = True
    return found, ok
