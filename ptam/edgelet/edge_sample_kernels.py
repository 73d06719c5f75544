"""Edge signals shared by the edgelet code (Agility §4.2, §4.3, §5.1): bilinear look-ups, profiles along an
edge normal, the sawtooth (ramp) taps, the sub-pixel peak of a response, and the Sobel gradient at points (the
polarity of §4.3's candidates and matches).

Pixel centres are at integer coordinates; a sample needs its 2×2 neighbourhood inside the image. The sawtooth
of period l is the zero-mean ramp k(x) = x on [−l/2, l/2] (Klein & Drummond BMVC'02, Agility §5.1); each tap j
integrates k over its pixel [j − ½, j + ½], so the kernel varies continuously with l, and the taps are scaled
so that a ramp of contrast C exactly filling the kernel responds with C. With l = 2 it is the central
difference I(t + 1) − I(t − 1); a few pixels long it is a smoothed derivative.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True, inline="always")
def bilinear(img, x, y):
    """(value, ok): the bilinear interpolation of ``img`` at (x, y); ok is False outside the image."""
    H, W = img.shape
    if not (x >= 0.0 and y >= 0.0 and x <= W - 1.0 and y <= H - 1.0):
        return 0.0, False
    x0 = min(int(math.floor(x)), W - 2)
    y0 = min(int(math.floor(y)), H - 2)
    fx = x - x0
    fy = y - y0
    a = float(img[y0, x0])
    b = float(img[y0, x0 + 1])
    c = float(img[y0 + 1, x0])
    d = float(img[y0 + 1, x0 + 1])
    return (1.0 - fy) * ((1.0 - fx) * a + fx * b) + fy * ((1.0 - fx) * c + fx * d), True


@njit(nogil=True, cache=True, inline="always")
def profile(img, x, y, nx, ny, first, out):
    """out[j] = img at (x, y) + (first + j)·(nx, ny), j = 0 … len(out) − 1; False if a sample leaves the image."""
    for j in range(out.shape[0]):
        t = first + j
        v, ok = bilinear(img, x + t * nx, y + t * ny)
        if not ok:
            return False
        out[j] = v
    return True


@njit(nogil=True, cache=True, inline="always")
def parabola_peak(ym, y0, yp):
    """Sub-sample offset in [−0.5, 0.5] of the vertex of the parabola through (−1, ym), (0, y0), (1, yp)."""
    den = ym - 2.0 * y0 + yp
    if den >= 0.0:
        return 0.0
    off = 0.5 * (ym - yp) / den
    return min(0.5, max(-0.5, off))


@njit(nogil=True, cache=True)
def ramp_half_width(length):
    """The largest tap index j whose pixel [j − ½, j + ½] overlaps [−length/2, length/2]."""
    return int(math.ceil(0.5 * (length + 1.0))) - 1


@njit(nogil=True, cache=True)
def ramp_weights(length, out):
    """Write the 2h + 1 sawtooth taps for period ``length`` into out[0 … 2h] (tap j at index j + h); -> h."""
    h = ramp_half_width(length)
    half = 0.5 * length
    s = 0.0
    for j in range(-h, h + 1):
        lo = max(j - 0.5, -half)
        hi = min(j + 0.5, half)
        w = 0.5 * (hi * hi - lo * lo) if hi > lo else 0.0
        out[j + h] = w
        s += w * j
    for j in range(2 * h + 1):
        out[j] *= length / s
    return h


@njit(nogil=True, cache=True, inline="always")
def correlate(sig, centre, h, w, first, last, resp, p0, p1):
    """resp[t − first] = Σ_j w[j + h] · sig[centre + t + j] for t = first … last, for sawtooth taps ``w``.

    The inner taps of a sawtooth are exactly proportional to j, so with prefix sums of s(x) and x·s(x)
    (scratch ``p0``, ``p1``, at least len(sig) + 1 long) each response costs O(1) whatever the blur length:
    r(t) = w₁ Σ_{|j|<h} j s(t + j) + w_h (s(t + h) − s(t − h)).
    """
    lo = centre + first - h
    hi = centre + last + h
    p0[lo] = 0.0
    p1[lo] = 0.0
    for i in range(lo, hi + 1):
        p0[i + 1] = p0[i] + sig[i]
        p1[i + 1] = p1[i] + (i - centre) * sig[i]
    responses(sig, centre, h, w, first, last, resp, p0, p1)


@njit(nogil=True, cache=True, inline="always")
def responses(sig, centre, h, w, first, last, resp, p0, p1):
    """``correlate``'s responses from its prefix sums ``p0``, ``p1`` of sig[centre + first − h … centre + last + h]."""
    scale = w[h + 1] if h >= 2 else 0.0
    end = w[2 * h]
    for t in range(first, last + 1):
        i0 = centre + t
        a = i0 - h + 1
        b = i0 + h
        inner = (p1[b] - p1[a]) - t * (p0[b] - p0[a])
        resp[t - first] = scale * inner + end * (sig[i0 + h] - sig[i0 - h])


@njit(nogil=True, cache=True, inline="always")
def box_blur_prefix(sig, centre, lo, hi, half, out, p0, p1):
    """out[i] = the mean of sig[i − half … i + half] for i = lo … hi, with ``correlate``'s prefix sums of ``out``
    over the same range into ``p0``, ``p1``, in one loop: the same values as blurring and then summing, with the
    three running sums advancing side by side instead of in separate passes."""
    s = 0.0
    for j in range(lo - half, lo + half + 1):
        s += sig[j]
    inv = 1.0 / (2 * half + 1)
    q0 = 0.0
    q1 = 0.0
    p0[lo] = q0
    p1[lo] = q1
    for i in range(lo, hi + 1):
        if i > lo:
            s += sig[i + half] - sig[i - half - 1]
        v = s * inv
        out[i] = v
        q0 = q0 + v
        q1 = q1 + (i - centre) * v
        p0[i + 1] = q0
        p1[i + 1] = q1


@njit(nogil=True, cache=True, inline="always")
def symmetric_peak(resp, k, h):
    """Sub-sample position of the response peak at index k: the zero of D(t) = r(t + h) − r(t − h) between
    k − 1 and k + 1 (the response is symmetric about the ramp's centre), else, and for the shortest kernels
    (h = 1, where it is the less precise of the two), the 3-point parabola."""
    if h < 2:
        return parabola_peak(resp[k - 1], resp[k], resp[k + 1])
    d0 = resp[k + h] - resp[k - h]
    if d0 == 0.0:
        return 0.0
    step = 1 if d0 > 0.0 else -1
    d1 = resp[k + step + h] - resp[k + step - h]
    if (d1 <= 0.0) == (d0 > 0.0):
        return step * d0 / (d0 - d1)
    return parabola_peak(resp[k - 1], resp[k], resp[k + 1])


@njit(nogil=True, cache=True)
def sobel_at(img, xy):
    """The 3×3 Sobel gradient (N, 2) of ``img`` at the pixels nearest to ``xy`` (N, 2) (rounded half to even),
    moved inside the image by at least one pixel: cv2.Sobel's values there."""
    H, W = img.shape
    out = np.empty((xy.shape[0], 2))
    for i in range(xy.shape[0]):
        x = min(max(int(np.rint(xy[i, 0])), 1), W - 2)
        y = min(max(int(np.rint(xy[i, 1])), 1), H - 2)
        a, b, c = float(img[y - 1, x - 1]), float(img[y - 1, x]), float(img[y - 1, x + 1])
        d, f = float(img[y, x - 1]), float(img[y, x + 1])
        g, h, k = float(img[y + 1, x - 1]), float(img[y + 1, x]), float(img[y + 1, x + 1])
        out[i, 0] = c + 2.0 * f + k - a - 2.0 * d - g
        out[i, 1] = g + 2.0 * h + k - a - 2.0 * b - c
    return out
