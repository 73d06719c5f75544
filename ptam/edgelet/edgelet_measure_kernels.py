"""Kernel: measuring predicted edgelets in a keyframe image (Agility §4.2, Fig. 2).

An edge of ``length`` px is placed at each predicted centre along its direction and ``n_samples`` sample
points are spread evenly along it (ends included). From each sample point a perpendicular search over
offsets t ∈ [−search, search] (1 px steps along the unit normal) looks for the gradient maximum of the right
polarity: the derivative along the dark-to-light normal, a sawtooth of ``kernel`` px (a smoothed derivative
whose response is the edge's contrast in grey levels, ``edge_sample_kernels``), must be a local maximum and at
least ``min_contrast``; the maximum nearest the sample point wins (data association by proximity), refined to
sub-pixel accuracy by ``symmetric_peak``. (A 3-point parabola on the central difference is biased by up to
0.07 px and 0.6° over an edgelet on area-sampled edges; a 4 px kernel with the symmetric refinement by 0.03 px
on slightly blurred ones, measured; the paper does not say which derivative it uses.) A straight line is fitted
to the found points by total least squares; the measurement is valid when at least ``min_found`` samples were
found and the RMS perpendicular residual is at most ``max_rms`` (the paper's "tight threshold", which rejects
curved, blurred and crowded edges).

Outputs per edgelet: the measured centre a (the foot of the predicted centre on the fitted line), the unit
line direction b (oriented so that perp(b) points like the given normal: b carries the polarity), the RMS
residual, the number of samples found, the sample positions and the valid flag. The numpy reference is
``tests/reference/edgelet_measure.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .edge_sample_kernels import correlate, profile, ramp_half_width, ramp_weights, symmetric_peak


@njit(nogil=True, cache=True)
def measure_edgelets(img, centres, dirs, normals, length, n_samples, search, kernel, min_contrast, min_found, max_rms):
    """-> a (N, 2), b (N, 2), rms (N,), n_found (N,), points (N, S, 2), found (N, S), ok (N,)."""
    n = centres.shape[0]
    a = np.zeros((n, 2))
    b = np.zeros((n, 2))
    rms = np.full(n, np.inf)
    n_found = np.zeros(n, dtype=np.int64)
    points = np.zeros((n, n_samples, 2))
    found = np.zeros((n, n_samples), dtype=np.bool_)
    ok = np.zeros(n, dtype=np.bool_)
    w = np.empty(2 * ramp_half_width(kernel) + 1)
    h = ramp_weights(kernel, w)
    o = search + 1 + h  # resp[t + o] is the derivative at offset t, t = −o … o
    ext = o + h
    prof = np.empty(2 * ext + 1)
    resp = np.empty(2 * o + 1)
    p0 = np.empty(2 * ext + 2)
    p1 = np.empty(2 * ext + 2)
    for i in range(n):
        dl = math.hypot(dirs[i, 0], dirs[i, 1])
        if not dl > 0.0:
            continue
        dx = dirs[i, 0] / dl
        dy = dirs[i, 1] / dl
        nx = -dy
        ny = dx
        if nx * normals[i, 0] + ny * normals[i, 1] < 0.0:
            nx = -nx
            ny = -ny
        for k in range(n_samples):
            along = (k / (n_samples - 1) - 0.5) * length
            sx = centres[i, 0] + along * dx
            sy = centres[i, 1] + along * dy
            if not profile(img, sx, sy, nx, ny, -ext, prof):
                continue
            correlate(prof, ext, h, w, -o, o, resp, p0, p1)
            best = -1
            for j in range(o - search, o + search + 1):
                g = resp[j]
                if g < min_contrast or g < resp[j - 1] or g <= resp[j + 1]:
                    continue
                if best < 0 or abs(j - o) < abs(best - o) or (abs(j - o) == abs(best - o) and g > resp[best]):
                    best = j
            if best < 0:
                continue
            t = best - o + symmetric_peak(resp, best, h)
            points[i, k, 0] = sx + t * nx
            points[i, k, 1] = sy + t * ny
            found[i, k] = True
            n_found[i] += 1
        m = n_found[i]
        if m < 2:
            continue
        mx = 0.0
        my = 0.0
        for k in range(n_samples):
            if found[i, k]:
                mx += points[i, k, 0]
                my += points[i, k, 1]
        mx /= m
        my /= m
        sxx = 0.0
        sxy = 0.0
        syy = 0.0
        for k in range(n_samples):
            if found[i, k]:
                ex = points[i, k, 0] - mx
                ey = points[i, k, 1] - my
                sxx += ex * ex
                sxy += ex * ey
                syy += ey * ey
        # Smallest eigenvalue of the 2×2 scatter matrix and the line direction (largest eigenvector).
        half_tr = 0.5 * (sxx + syy)
        disc = math.sqrt(max(0.0, 0.25 * (sxx - syy) ** 2 + sxy * sxy))
        lam_min = max(0.0, half_tr - disc)
        lam_max = half_tr + disc
        if sxx >= syy:
            bx = lam_max - syy
            by = sxy
        else:
            bx = sxy
            by = lam_max - sxx
        bl = math.hypot(bx, by)
        if not bl > 0.0:
            continue
        bx /= bl
        by /= bl
        if -by * nx + bx * ny < 0.0:  # perp(b) must point along the dark-to-light normal
            bx = -bx
            by = -by
        s = (centres[i, 0] - mx) * bx + (centres[i, 1] - my) * by
        a[i, 0] = mx + s * bx
        a[i, 1] = my + s * by
        b[i, 0] = bx
        b[i, 1] = by
        rms[i] = math.sqrt(lam_min / m)
        ok[i] = m >= min_found and rms[i] <= max_rms
    return a, b, rms, n_found, points, found, ok
