"""numpy reference for ``ptam.edgelet.edgelet_measure_kernels`` (Agility §4.2), vectorised over edgelets and
samples: compared with the kernel on random data."""

from __future__ import annotations

import numpy as np


def bilinear_ref(img, x, y):
    """Bilinear samples of ``img`` at arrays x, y and the in-image mask (pixel centres at integers)."""
    H, W = img.shape
    ok = (x >= 0) & (y >= 0) & (x <= W - 1) & (y <= H - 1)
    xs, ys = np.where(ok, x, 0.0), np.where(ok, y, 0.0)
    x0 = np.minimum(np.floor(xs).astype(int), W - 2)
    y0 = np.minimum(np.floor(ys).astype(int), H - 2)
    fx, fy = xs - x0, ys - y0
    im = img.astype(np.float64)
    v = (1 - fy) * ((1 - fx) * im[y0, x0] + fx * im[y0, x0 + 1]) + fy * (
        (1 - fx) * im[y0 + 1, x0] + fx * im[y0 + 1, x0 + 1]
    )
    return np.where(ok, v, 0.0), ok


def parabola_peak_ref(ym, y0, yp):
    den = ym - 2.0 * y0 + yp
    off = np.where(den < 0, 0.5 * (ym - yp) / np.where(den < 0, den, -1.0), 0.0)
    return np.clip(off, -0.5, 0.5)


def ramp_weights_ref(length):
    """Taps j = −h … h of the unit-contrast sawtooth of period ``length`` (each integrates x over its pixel)."""
    h = int(np.ceil(0.5 * (length + 1.0))) - 1
    j = np.arange(-h, h + 1, dtype=np.float64)
    lo = np.maximum(j - 0.5, -0.5 * length)
    hi = np.minimum(j + 0.5, 0.5 * length)
    w = np.where(hi > lo, 0.5 * (hi * hi - lo * lo), 0.0)
    return w * length / np.sum(w * j), h


def symmetric_peak_ref(r, k, h):
    """Vectorised over leading axes: r (..., T), peak indices k (...); see ``edge_sample_kernels``."""
    at = lambda i: np.take_along_axis(r, i[..., None], axis=-1)[..., 0]  # noqa: E731
    para = parabola_peak_ref(at(k - 1), at(k), at(k + 1))
    if h < 2:
        return para
    d0 = at(k + h) - at(k - h)
    step = np.where(d0 > 0, 1, -1)
    d1 = at(k + step + h) - at(k + step - h)
    cross = (d1 <= 0) == (d0 > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        zero = step * d0 / (d0 - d1)
    return np.where(d0 == 0, 0.0, np.where(cross, zero, para))


def _nearest_maximum(g, cand, tt):
    """Index of the candidate with the smallest |t|, the larger value on a tie (first one if equal)."""
    absd = np.where(cand, np.abs(tt), np.inf)
    sel = cand & (absd == absd.min(axis=-1, keepdims=True))
    best = np.argmax(np.where(sel, g, -np.inf), axis=-1)
    return best, cand.any(axis=-1)


def measure_edgelets_ref(
    img, centres, dirs, normals, length, n_samples, search, kernel, min_contrast, min_found, max_rms
):
    dl = np.linalg.norm(dirs, axis=1)
    good = dl > 0
    d = dirs / np.where(good, dl, 1.0)[:, None]
    nrm = np.stack([-d[:, 1], d[:, 0]], axis=1)
    nrm *= np.where(np.sum(nrm * normals, axis=1) < 0, -1.0, 1.0)[:, None]
    along = (np.arange(n_samples) / (n_samples - 1) - 0.5) * length
    s = centres[:, None, :] + along[None, :, None] * d[:, None, :]  # (N, S, 2)
    w, h = ramp_weights_ref(kernel)
    o = search + 1 + h
    t = np.arange(-o - h, o + h + 1)
    p = s[:, :, None, :] + t[None, None, :, None] * nrm[:, None, None, :]  # (N, S, T, 2)
    v, ok = bilinear_ref(img, p[..., 0], p[..., 1])
    r = np.lib.stride_tricks.sliding_window_view(v, 2 * h + 1, axis=-1) @ w  # r[..., k]: offset k − o
    k = np.arange(o - search, o + search + 1)
    g0 = r[..., k]
    cand = (g0 >= min_contrast) & (g0 >= r[..., k - 1]) & (g0 > r[..., k + 1])
    cand &= ok.all(axis=-1)[..., None] & good[:, None, None]
    best, found = _nearest_maximum(g0, cand, k - o)
    kb = k[best]
    off = kb - o + symmetric_peak_ref(r, kb, h)
    points = np.where(found[..., None], s + off[..., None] * nrm[:, None, :], 0.0)
    return _line_fit_ref(centres, nrm, points, found, min_found, max_rms)


def _line_fit_ref(centres, nrm, points, found, min_found, max_rms):
    n_found = found.sum(axis=1)
    m = np.maximum(n_found, 1)[:, None]
    mean = np.sum(np.where(found[..., None], points, 0.0), axis=1) / m
    e = np.where(found[..., None], points - mean[:, None, :], 0.0)
    S = np.einsum("nsi,nsj->nij", e, e)
    lam, vec = np.linalg.eigh(S)
    b = vec[:, :, 1]
    b *= np.where(np.sum(np.stack([-b[:, 1], b[:, 0]], axis=1) * nrm, axis=1) < 0, -1.0, 1.0)[:, None]
    a = mean + np.sum((centres - mean) * b, axis=1)[:, None] * b
    fit = n_found >= 2
    rms = np.where(fit, np.sqrt(np.maximum(lam[:, 0], 0.0) / m[:, 0]), np.inf)
    okm = fit & (n_found >= min_found) & (rms <= max_rms)
    return np.where(fit[:, None], a, 0.0), np.where(fit[:, None], b, 0.0), rms, n_found, points, found, okm
