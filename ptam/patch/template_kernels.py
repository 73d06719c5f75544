"""Warped 8×8 search templates from the patches' source keyframe levels (PTAM §5.3).

Template pixel (r, c) samples the source level at ``source_xy + M·(c − h, r − h)``, h = size // 2, with
bilinear interpolation; M = A⁻¹·2^l maps one search-level pixel to source-level pixels (PTAM code:
``MakeTemplateCoarseCont``, which puts the patch centre at template pixel (h, h) and matches it against the
image window [x − h, x + size − 1 − h]). The mean is subtracted (PTAM §5.3: resilience to lighting changes).
A template that samples outside its source image is bad (PTAM code: ``mbTemplateBad``).
``make_templates_ref`` is the numpy reference.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def make_templates(kf_images, source_kf, source_level, source_xy, M, size):
    """kf_images: per level (N_kf, H_L, W_L) uint8. Returns templates (n, size, size) float32 and ok (n,)."""
    n = source_kf.shape[0]
    out = np.zeros((n, size, size), dtype=np.float32)
    ok = np.zeros(n, dtype=np.bool_)
    h = size // 2
    for k in range(n):
        img = kf_images[source_level[k]][source_kf[k]]
        H, W = img.shape
        m00, m01, m10, m11 = M[k, 0, 0], M[k, 0, 1], M[k, 1, 0], M[k, 1, 1]
        # The samples are an affine image of a square: all inside when its four corners are.
        inside = True
        for dy in (-h, size - 1 - h):
            for dx in (-h, size - 1 - h):
                x = source_xy[k, 0] + m00 * dx + m01 * dy
                y = source_xy[k, 1] + m10 * dx + m11 * dy
                inside &= 0.0 <= x <= W - 1.0 and 0.0 <= y <= H - 1.0
        if not inside:
            continue
        total = 0.0
        for r in range(size):
            x = source_xy[k, 0] - m00 * h + m01 * (r - h)
            y = source_xy[k, 1] - m10 * h + m11 * (r - h)
            for c in range(size):
                x0 = min(int(x), W - 2)  # x, y >= 0: truncation is the floor
                y0 = min(int(y), H - 2)
                fx = x - x0
                fy = y - y0
                v = (
                    (1.0 - fx) * (1.0 - fy) * img[y0, x0]
                    + fx * (1.0 - fy) * img[y0, x0 + 1]
                    + (1.0 - fx) * fy * img[y0 + 1, x0]
                    + fx * fy * img[y0 + 1, x0 + 1]
                )
                out[k, r, c] = v
                total += v
                x += m00
                y += m10
        mean = np.float32(total / (size * size))
        for r in range(size):
            for c in range(size):
                out[k, r, c] -= mean
        ok[k] = True
    return out, ok
