"""Zero-mean SSD search of warped templates at FAST corners within a circular radius (PTAM §5.3, §6.5).

For each patch the candidate corners are read from its search level's corner list through the row look-up
table (PTAM §6.5) and kept when inside the circle of ``radius`` around ``center``. The zero-mean SSD with the
(already zero-mean) template is ΣI² − (ΣI)²/N − 2ΣI·T + ΣT² (PTAM code: ``ZMSSDAtPoint``); the lowest
score wins (the first corner in row-major order on ties) and is a match when below ``max_ssd`` (PTAM code) and
below ``flat_fraction``·ΣT². ΣT² is what a flat window scores: a template whose own contrast is below PTAM's
absolute limit is otherwise "found" at any corner that merely resembles flatness, so the best of a search
region's chance candidates passes (white noise at pyramid levels 2-3: 30-40 % of patches found, all wrong).
``search_patches_ref`` is the numpy reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..image.corner_rows import first_in_row


@njit(nogil=True, cache=True, fastmath=True)
def _zmssd(win, t, tsq):
    """Zero-mean SSD of the image window and a zero-mean template. Float32 sums of uint8 values are exact
    (ΣI² ≤ 64·255² < 2²⁴), so only the cross term rounds; fastmath lets the loops vectorise."""
    s = np.float32(0.0)
    ss = np.float32(0.0)
    cross = np.float32(0.0)
    for r in range(t.shape[0]):
        for c in range(t.shape[1]):
            v = np.float32(win[r, c])
            s += v
            ss += v * v
            cross += v * t[r, c]
    return float(ss) - float(s) * float(s) / t.size - 2.0 * float(cross) + tsq


@njit(nogil=True, cache=True)
def search_patches(levels, corners, row_luts, templates, level, center, radius, max_ssd, flat_fraction):
    """levels/corners/row_luts: per pyramid level. center (n, 2) int and radius (n,) int at the search level.

    ``flat_fraction``: a match must also score below this fraction of the template's ΣT² (``inf``: PTAM's
    absolute limit alone). Returns best (n, 2) int32 corner, its score (n,) and found (n,) bool. Within each row
    of the circle the corners (sorted by x) in range are found by binary search from the row look-up table.
    """
    n = templates.shape[0]
    size = templates.shape[1]
    h = size // 2
    best = np.zeros((n, 2), dtype=np.int32)
    score = np.full(n, np.inf)
    found = np.zeros(n, dtype=np.bool_)
    for k in range(n):
        L = level[k]
        img = levels[L]
        cs = corners[L]
        lut = row_luts[L]
        H, W = img.shape
        cx = center[k, 0]
        cy = center[k, 1]
        R = radius[k]
        x_lo = max(cx - R, h)
        x_hi = min(cx + R, W - size + h)
        t = templates[k]
        tsq = 0.0
        for r in range(size):
            for c in range(size):
                tsq += t[r, c] * t[r, c]
        bs = np.inf
        bx = 0
        by = 0
        for y in range(max(cy - R, h), min(cy + R, H - size + h) + 1):
            dy = y - cy
            dx = int(math.sqrt(R * R - dy * dy) + 1e-9)
            xa = max(cx - dx, x_lo)
            xb = min(cx + dx, x_hi)
            for j in range(first_in_row(cs, lut, y, xa), lut[y + 1]):
                x = cs[j, 0]
                if x > xb:
                    break
                z = _zmssd(img[y - h : y - h + size, x - h : x - h + size], t, tsq)
                if z < bs:
                    bs = z
                    bx = x
                    by = y
        limit = max_ssd
        if flat_fraction * tsq < limit:  # nan for an all-zero template under inf: PTAM's limit stands
            limit = flat_fraction * tsq
        if bs < limit:
            best[k, 0] = bx
            best[k, 1] = by
            score[k] = bs
            found[k] = True
    return best, score, found
