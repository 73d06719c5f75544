"""numpy references for ``ptam.edgelet.sawtooth_kernels`` (Agility §5.1–§5.2): the sawtooth taps, the search
and the visibility table, one edgelet at a time with array operations along the signal."""

from __future__ import annotations

import numpy as np

from tests.reference.edgelet_measure import bilinear_ref, parabola_peak_ref, ramp_weights_ref, symmetric_peak_ref


def _responses(sig, w, h, n_out):
    """Cross-correlation of the signal with the taps, for the n_out central positions."""
    r = np.correlate(sig, w, mode="valid")
    extra = (len(r) - n_out) // 2
    return r[extra : len(r) - extra] if extra else r


def _local_maxima(r, lo):
    """Indices k (1 … len − 2) where r[k] ≥ lo, r[k] ≥ r[k − 1] and r[k] > r[k + 1]."""
    k = np.arange(1, len(r) - 1)
    return k[(r[k] >= lo) & (r[k] >= r[k - 1]) & (r[k] > r[k + 1])]


def _symmetric_peak_ref(r, k, h):
    return float(symmetric_peak_ref(r[None], np.array([k]), h)[0])


def sawtooth_search_ref(img, centres, normals, blur, radius, t_min, min_len, max_len):
    n = len(centres)
    offset, response, found = np.zeros(n), np.zeros(n), np.zeros(n, dtype=bool)
    for i in range(n):
        nrm = normals[i] / np.linalg.norm(normals[i])
        w, h = ramp_weights_ref(min(max_len, max(min_len, blur[i])))
        R = int(radius[i])
        ext = R + 1 + 2 * h
        t = np.arange(-ext, ext + 1)
        sig, ok = bilinear_ref(img, centres[i, 0] + t * nrm[0], centres[i, 1] + t * nrm[1])
        if not ok.all():
            continue
        o = R + 1 + h
        r = _responses(sig, w, h, 2 * o + 1)
        k = _local_maxima(r, t_min[i])
        k = k[np.abs(k - o) <= R]
        if len(k) == 0:
            continue
        dist = np.abs(k - o)
        k = k[dist == dist.min()]
        best = k[np.argmax(r[k])]
        offset[i] = best - o + _symmetric_peak_ref(r, best, h)
        response[i] = r[best]
        found[i] = True
    return offset, response, found


def _edge_signal(img, c, nrm, ext):
    t = np.arange(-ext, ext + 1)
    sig, ok = bilinear_ref(img, c[0] + t * nrm[0], c[1] + t * nrm[1])
    if not ok.any():
        return None
    idx = np.flatnonzero(ok)
    return sig[np.clip(np.arange(len(sig)), idx[0], idx[-1])]  # repeat the last sample inside the image


def visibility_table_ref(
    img, centres, normals, blurs, max_search, centre_tol, tmin_frac, rsearch_frac, min_len, max_len
):
    n, nb = len(centres), len(blurs)
    visible = np.zeros((n, nb), dtype=bool)
    r_search, t_min, max_blur = np.zeros((n, nb)), np.zeros((n, nb)), np.zeros(n)
    R = 2 * int(max_search)
    hmax = ramp_weights_ref(max_len)[1]
    ext = R + 1 + hmax + int(max(blurs)) // 2 + 1
    for i in range(n):
        sig = _edge_signal(img, centres[i], normals[i] / np.linalg.norm(normals[i]), ext)
        if sig is None:
            continue
        for b, L in enumerate(blurs):
            blurred = np.convolve(sig, np.ones(L) / L, mode="same")
            w, h = ramp_weights_ref(min(max_len, max(min_len, float(L))))
            r = np.correlate(blurred[ext - R - 1 - h : ext + R + 2 + h], w, mode="valid")
            k = _local_maxima(r, 1e-300)
            k = k[r[k] > 0]
            sub = k - (R + 1) + parabola_peak_ref(r[k - 1], r[k], r[k + 1])
            at_centre = k[np.abs(sub) <= centre_tol]
            if len(at_centre) == 0:
                break
            kc = at_centre[np.argmax(r[at_centre])]
            tmin = tmin_frac * r[kc]
            others = k[(k != kc) & (r[k] > tmin)]
            near = min(float(R), float(np.min(np.abs(others - (R + 1))))) if len(others) else float(R)
            visible[i, b], t_min[i, b], max_blur[i] = True, tmin, L
            r_search[i, b] = min(float(max_search), rsearch_frac * near)
    return visible, r_search, t_min, max_blur
