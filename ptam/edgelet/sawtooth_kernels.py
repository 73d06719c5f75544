"""Kernels: the blur-aware sawtooth edge search and the per-edgelet visibility table (Agility §5.1–§5.2).

A step edge blurred by a box of length l along its normal becomes an intensity ramp of length l. Following
Klein & Drummond (BMVC'02) the 1-D intensity signal along the edge normal is cross-correlated with one cycle
of a sawtooth of period l, the zero-mean ramp k(x) = x on [−l/2, l/2] (§5.1). Each tap j of the discrete
kernel integrates k over its pixel [j − ½, j + ½], so the kernel varies continuously with l; the taps are
scaled so that a ramp of contrast C exactly filling the kernel responds with C (grey levels, whatever l).
The response is symmetric about the ramp's centre, so the integer peak is refined to the zero of
r(t + h) − r(t − h) (h the kernel's half-width), which under image noise is several times more precise at long
blurs than a parabola through three samples of the flat-topped peak (the paper does not say how it refines);
the parabola is kept for the shortest kernels (h = 1), where it is the more precise. Only responses of the
correct polarity (dark → light along the normal, a positive response) count, and of the local maxima at least
``t_min`` the one nearest the predicted centre is taken within the search radius.

The visibility table (§5.2) simulates blur on the signal a keyframe shows at each measured edgelet: box
blurs of the given odd lengths, each followed by the sawtooth of the same length. For each blur it records
whether a response maximum stays at the edgelet's centre (within ``centre_tol``), t_min = tmin_frac · t_max
and r_search = rsearch_frac · r_near, r_near being the distance from the centre to the nearest other local
maximum above t_min (responses are examined to 2 · ``max_search``, and r_search is capped at ``max_search``).
Blurs beyond the first failure are marked invisible, and the largest visible one is the edgelet's maximum
blur. Numpy references: ``tests/reference/edgelet_sawtooth.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .edge_sample_kernels import (
    bilinear,
    box_blur_prefix,
    correlate,
    parabola_peak,
    profile,
    ramp_half_width,
    ramp_weights,
    responses,
    symmetric_peak,
)


@njit(nogil=True, cache=True)
def sawtooth_search(img, centres, normals, blur, radius, t_min, min_len, max_len):
    """One perpendicular search per edgelet (§5.1) -> offset along the unit normal (N,), response (N,), found (N,).

    ``blur`` (N,) is the expected edge-normal blur l = |Jγ| (px), clipped to [min_len, max_len]; ``radius``
    (N,) the search radius r_search (px) and ``t_min`` (N,) the smallest response accepted. The peak is refined
    by ``symmetric_peak``.
    """
    n = centres.shape[0]
    offset = np.zeros(n)
    response = np.zeros(n)
    found = np.zeros(n, dtype=np.bool_)
    hmax = ramp_half_width(max_len)
    rmax = 0
    for i in range(n):
        rmax = max(rmax, int(radius[i]))
    w = np.empty(2 * hmax + 1)
    sig = np.empty(2 * (rmax + 1 + 2 * hmax) + 1)
    resp = np.empty(2 * (rmax + 1 + hmax) + 1)
    p0 = np.empty(sig.shape[0] + 1)
    p1 = np.empty(sig.shape[0] + 1)
    for i in range(n):
        nl = math.hypot(normals[i, 0], normals[i, 1])
        if not nl > 0.0 or not radius[i] >= 0.0:
            continue
        nx = normals[i, 0] / nl
        ny = normals[i, 1] / nl
        h = ramp_weights(min(max_len, max(min_len, blur[i])), w)
        R = int(radius[i])
        ext = R + 1 + 2 * h
        if not profile(img, centres[i, 0], centres[i, 1], nx, ny, -ext, sig[: 2 * ext + 1]):
            continue
        o = R + 1 + h  # resp[t + o] is the response at offset t, t = −o … o
        correlate(sig, ext, h, w, -o, o, resp, p0, p1)
        best = -1
        for k in range(o - R, o + R + 1):
            r = resp[k]
            if r < t_min[i] or r < resp[k - 1] or r <= resp[k + 1]:
                continue
            if best < 0 or abs(k - o) < abs(best - o) or (abs(k - o) == abs(best - o) and r > resp[best]):
                best = k
        if best < 0:
            continue
        offset[i] = best - o + symmetric_peak(resp, best, h)
        response[i] = resp[best]
        found[i] = True
    return offset, response, found


@njit(nogil=True, cache=True, inline="always")
def _sample_outwards(img, x, y, nx, ny, sig, centre, lo, hi, new_lo, new_hi):
    """Extend the signal ``sig`` (sig[centre + t] = img at (x, y) + t·(nx, ny)), sampled on [lo, hi], to
    [new_lo, new_hi]; -> (new_lo, new_hi). Beyond the image a sample repeats the last one inside it: the samples
    inside the image are one run along the line, and the centre (sampled first) is among them."""
    for j in range(lo - 1, new_lo - 1, -1):
        v, ok = bilinear(img, x + (j - centre) * nx, y + (j - centre) * ny)
        sig[j] = v if ok else sig[j + 1]
    for j in range(hi + 1, new_hi + 1):
        v, ok = bilinear(img, x + (j - centre) * nx, y + (j - centre) * ny)
        sig[j] = v if ok else sig[j - 1]
    return new_lo, new_hi


@njit(nogil=True, cache=True, inline="always")
def _whole_signal(img, x, y, nx, ny, sig, centre):
    """sig[j] = img at (x, y) + (j − centre)·(nx, ny) for every j, those beyond the image repeating the last one
    inside it; -> the last index, or −1 when no sample is inside."""
    first_ok = -1
    last_ok = -1
    for j in range(sig.shape[0]):
        v, ok = bilinear(img, x + (j - centre) * nx, y + (j - centre) * ny)
        sig[j] = v
        if ok:
            if first_ok < 0:
                first_ok = j
            last_ok = j
    if first_ok < 0:
        return -1
    for j in range(first_ok):
        sig[j] = sig[first_ok]
    for j in range(last_ok + 1, sig.shape[0]):
        sig[j] = sig[last_ok]
    return sig.shape[0] - 1


@njit(nogil=True, cache=True, inline="always")
def _local_max(resp, k, floor):
    r = resp[k]
    return r > floor and r >= resp[k - 1] and r > resp[k + 1]


@njit(nogil=True, cache=True)
def visibility_table(img, centres, normals, blurs, max_search, centre_tol, tmin_frac, rsearch_frac, min_len, max_len):
    """(§5.2) -> visible (N, B), r_search (N, B), t_min (N, B), max_blur (N,) for odd box ``blurs`` (B,).

    The work per blur is kept to what decides the table: the signal is sampled only as far as the blurs tried so
    far read it (most rows stop after a few short blurs), a maximum at the centre can only be within
    ``centre_tol`` + ½ samples of it (the parabola moves a peak by at most ½), and the nearest rival maximum is
    sought outwards from the centre.
    """
    n = centres.shape[0]
    nb = blurs.shape[0]
    visible = np.zeros((n, nb), dtype=np.bool_)
    r_search = np.zeros((n, nb))
    t_min = np.zeros((n, nb))
    max_blur = np.zeros(n)
    bmax = 0
    for b in range(nb):
        bmax = max(bmax, int(blurs[b]))
    hmax = ramp_half_width(max_len)
    R = 2 * int(max_search)  # responses are examined to twice the largest search radius (r_search = ½ r_near)
    ext = R + 1 + hmax + bmax // 2 + 1
    sig = np.empty(2 * ext + 1)
    blurred = np.empty(2 * ext + 1)
    w = np.empty((nb, 2 * hmax + 1))  # each blur's sawtooth taps, the same for every edgelet
    hw = np.empty(nb, np.int64)
    for b in range(nb):
        hw[b] = ramp_weights(min(max_len, max(min_len, float(blurs[b]))), w[b])
    resp = np.empty(2 * R + 3)
    p0 = np.empty(2 * ext + 2)
    p1 = np.empty(2 * ext + 2)
    reach = min(R, int(math.floor(centre_tol + 0.5)))  # the centre maximum's index lies within this of R + 1
    for i in range(n):
        nl = math.hypot(normals[i, 0], normals[i, 1])
        if not nl > 0.0:
            continue
        nx = normals[i, 0] / nl
        ny = normals[i, 1] / nl
        x = centres[i, 0]
        y = centres[i, 1]
        v, ok = bilinear(img, x, y)
        if ok:
            sig[ext] = v
            lo = ext
            hi = ext
        else:  # a centre outside the image (never a measured one): the whole signal, as far as it is inside
            lo = 0
            hi = _whole_signal(img, x, y, nx, ny, sig, ext)
            if hi < 0:
                continue
        for b in range(nb):
            L = int(blurs[b])
            bh = L // 2
            h = hw[b]
            a = ext - R - 1 - h  # the samples the correlation reads: a … e, box-blurred from a − bh … e + bh
            e = ext + R + 1 + h
            if a - bh < lo or e + bh > hi:
                lo, hi = _sample_outwards(img, x, y, nx, ny, sig, ext, lo, hi, min(lo, a - bh), max(hi, e + bh))
            box_blur_prefix(sig, ext, a, e, bh, blurred, p0, p1)
            responses(blurred, ext, h, w[b], -R - 1, R + 1, resp, p0, p1)
            centre_k = -1
            for k in range(max(1, R + 1 - reach), min(2 * R + 1, R + 1 + reach) + 1):
                if not _local_max(resp, k, 0.0):
                    continue
                t = k - R - 1 + parabola_peak(resp[k - 1], resp[k], resp[k + 1])
                if abs(t) <= centre_tol and (centre_k < 0 or resp[k] > resp[centre_k]):
                    centre_k = k
            if centre_k < 0:
                break
            tmin = tmin_frac * resp[centre_k]
            near = R  # no other maximum within 2·max_search: r_near ≥ 2·max_search
            for d in range(R + 1):
                if (R + 1 - d != centre_k and _local_max(resp, R + 1 - d, tmin)) or (
                    d > 0 and R + 1 + d != centre_k and _local_max(resp, R + 1 + d, tmin)
                ):
                    near = d
                    break
            visible[i, b] = True
            t_min[i, b] = tmin
            r_search[i, b] = min(float(max_search), rsearch_frac * near)
            max_blur[i] = L
    return visible, r_search, t_min, max_blur
