"""Kernel: the runs of maximal edgels each candidate's rasterised epipolar curve crosses (Agility §4.3).

Each candidate's curve is a polyline through the projections of its viewing ray at a few depths, even in inverse
depth (``edgelet_mapping._epipolar_hits``). It is sampled every ``step`` pixels of arc length from its first
vertex; a sample hits where its piece is valid (in front of the camera, through the lens's valid region), it lies
``border`` pixels inside the image and the edgel image is non-zero at its nearest pixel. Every run of consecutive
hits is one match, reported at its middle sample with the sample's inverse depth (linear along the piece) and the
piece's unit tangent. One walk along each curve replaces numpy arrays of every sample of every curve, about a
hundred thousand per keyframe at half-pixel steps. The numpy reference is
``tests/reference/edgelet_epipolar.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project


@njit(nogil=True, cache=True)
def _sample_count(length, step):
    """Samples on each polyline of piece lengths (n, s): ⌊total / step⌋ + 1."""
    n, s = length.shape
    count = np.empty(n, dtype=np.int64)
    for c in range(n):
        total = 0.0
        for j in range(s):
            total += length[c, j]
        count[c] = int(math.floor(total / step)) + 1
    return count


@njit(nogil=True, cache=True)
def _sample(uv, length, inv_z, c, j, arc, before):
    """(x, y, inverse depth) of the sample at ``arc`` on piece j of polyline c, the piece starting at ``before``."""
    frac = (arc - before) / max(length[c, j], np.finfo(np.float64).tiny)
    frac = min(1.0, max(0.0, frac))
    x = uv[c, j, 0] + frac * (uv[c, j + 1, 0] - uv[c, j, 0])
    y = uv[c, j, 1] + frac * (uv[c, j + 1, 1] - uv[c, j, 1])
    return x, y, inv_z[j] + frac * (inv_z[j + 1] - inv_z[j])


@njit(nogil=True, cache=True, inline="always")
def _piece_at(length, c, arc, j, before):
    """(piece, arc length at its start) of the sample at ``arc`` on polyline c, walking on from piece j, which
    starts at ``before`` (numpy's searchsorted(side="right") on the cumulative lengths, the last piece at most)."""
    s = length.shape[1]
    while j < s - 1 and before + length[c, j] <= arc:
        before += length[c, j]
        j += 1
    return j, before


@njit(nogil=True, cache=True)
def curve_hits(uv, seg_ok, length, inv_z, step, edgels, border):
    """-> candidate (H,), point (H, 2), inverse depth (H,), unit tangent (H, 2) of the middle sample of every run
    of hits, for polylines ``uv`` (n, s + 1, 2) with piece validity ``seg_ok`` and lengths ``length`` (n, s)
    (zero where invalid) and vertex inverse depths ``inv_z`` (s + 1,)."""
    n = length.shape[0]
    h, w = edgels.shape
    count = _sample_count(length, step)
    cap = 0
    for c in range(n):
        cap += count[c] // 2 + 1  # runs are separated by misses
    cand = np.empty(cap, dtype=np.int64)
    pts = np.empty((cap, 2))
    iz = np.empty(cap)
    tangent = np.empty((cap, 2))
    out = 0
    tiny = np.finfo(np.float64).tiny
    for c in range(n):
        j = 0
        before = 0.0  # arc length at the start of piece j
        first = -1  # the current run's first sample
        for i in range(count[c] + 1):  # one past the end closes the last run
            hit = False
            if i < count[c]:
                arc = i * step
                j, before = _piece_at(length, c, arc, j, before)
                x, y, _ = _sample(uv, length, inv_z, c, j, arc, before)
                if seg_ok[c, j] and x >= border and y >= border and x <= w - 1 - border and y <= h - 1 - border:
                    hit = edgels[int(np.rint(y)), int(np.rint(x))] > 0
            if hit and first < 0:
                first = i
            if not hit and first >= 0:
                mid = (first + i - 1) // 2
                jm, bm = _piece_at(length, c, mid * step, 0, 0.0)
                x, y, z = _sample(uv, length, inv_z, c, jm, mid * step, bm)
                cand[out] = c
                pts[out, 0], pts[out, 1], iz[out] = x, y, z
                # The piece's own length, not ``length`` (clipped to max_len on a piece longer than that).
                tx = uv[c, jm + 1, 0] - uv[c, jm, 0]
                ty = uv[c, jm + 1, 1] - uv[c, jm, 1]
                lm = max(math.hypot(tx, ty), tiny)
                tangent[out, 0] = tx / lm
                tangent[out, 1] = ty / lm
                out += 1
                first = -1
    return cand[:out], pts[:out], iz[:out], tangent[:out]


@njit(nogil=True, cache=True)
def curve_vertices(cam, T_ts, rays, z, max_len):
    """The polylines ``curve_hits`` walks: each candidate's viewing ray ``rays[c]`` (z = 1, source frame) at the
    depths ``z`` (s + 1,), moved into the target by ``T_ts`` and projected -> uv (n, s + 1, 2), and per piece
    whether both its vertices are in front and within the lens's range (``seg_ok`` (n, s)) and its length in px,
    at most ``max_len`` (``length`` (n, s), zero where not ok). A vertex outside that range is placed where
    (1, 1, 1) projects, which no valid piece reaches."""
    n = rays.shape[0]
    v = z.shape[0]
    uv = np.empty((n, v, 2))
    front = np.empty(v, dtype=np.bool_)
    seg_ok = np.zeros((n, v - 1), dtype=np.bool_)
    length = np.zeros((n, v - 1))
    bu, bv, _ = project(cam, 1.0, 1.0, 1.0)
    for c in range(n):
        for j in range(v):
            x, y, w = rays[c, 0] * z[j], rays[c, 1] * z[j], rays[c, 2] * z[j]
            X = T_ts[0, 0] * x + T_ts[0, 1] * y + T_ts[0, 2] * w + T_ts[0, 3]
            Y = T_ts[1, 0] * x + T_ts[1, 1] * y + T_ts[1, 2] * w + T_ts[1, 3]
            Z = T_ts[2, 0] * x + T_ts[2, 1] * y + T_ts[2, 2] * w + T_ts[2, 3]
            u, vv, ok = project(cam, X, Y, Z)
            front[j] = ok
            uv[c, j, 0], uv[c, j, 1] = (u, vv) if ok else (bu, bv)
        for j in range(v - 1):
            d = math.hypot(uv[c, j + 1, 0] - uv[c, j, 0], uv[c, j + 1, 1] - uv[c, j, 1])
            if front[j] and front[j + 1] and math.isfinite(d):
                seg_ok[c, j] = True
                length[c, j] = min(d, max_len)
    return uv, seg_ok, length
