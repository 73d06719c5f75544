"""Kernels: linking Canny edgels into chains, breaking them at high curvature and cutting edgelet-length pieces
(Agility §4.3: "a full Canny edge extraction with a modification to the edgel linker stage which breaks
linked chains at points of high curvature ... Candidate edgelets are formed by splitting these long edges
into edgelet-length segments").

``link_edgels`` walks the 8-connected edgel image: chains start at end points (one neighbour), then at the
free ends of branches left at junctions, then anywhere (closed loops); each step goes to the unvisited
neighbour that best continues the current direction. ``split_chains`` marks a chain point as a corner where
the chain's direction over ``window`` edgels before and after it turns by more than the limit (cosine below
``min_cos``), cuts the chain there (corner points dropped), and splits each straight piece into
``seg_len``-long segments (by arc length, centred in the piece); each segment gets its centroid, principal
direction and the largest distance of its edgels from that line. Numpy references:
``tests/reference/edgel_linker.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_DX = np.array([1, 0, -1, 0, 1, -1, -1, 1])
_DY = np.array([0, 1, 0, -1, 1, 1, -1, -1])


@njit(nogil=True, cache=True, inline="always")
def _free_neighbours(edges, visited, x, y):
    H, W = edges.shape
    n = 0
    for k in range(8):
        xx = x + _DX[k]
        yy = y + _DY[k]
        if 0 <= xx < W and 0 <= yy < H and edges[yy, xx] != 0 and not visited[yy, xx]:
            n += 1
    return n


@njit(nogil=True, cache=True)
def edgel_positions(edges):
    """Row-major indices (y·W + x) of the non-zero pixels of ``edges``. An image is mostly empty, and three of
    the linker's passes visit only its edgels: the image is read once, eight pixels at a time."""
    H, W = edges.shape
    flat = np.ascontiguousarray(edges).reshape(H * W)
    pos = np.empty(H * W, dtype=np.int64)
    n = 0
    n8 = (H * W) // 8
    words = flat[: 8 * n8].view(np.uint64)
    for j in range(n8 + 1):
        if j < n8 and words[j] == 0:
            continue
        for i in range(8 * j, min(8 * j + 8, H * W)):
            if flat[i] != 0:
                pos[n] = i
                n += 1
    return pos[:n]


@njit(nogil=True, cache=True)
def link_edgels(edges):
    """-> points (P, 2) int32 (x, y) in chain order, starts (C + 1,) int64: chain c is points[starts[c]:starts[c+1]]."""
    H, W = edges.shape
    visited = np.zeros((H, W), dtype=np.bool_)
    pos = edgel_positions(edges)
    total = pos.shape[0]
    points = np.empty((total, 2), dtype=np.int32)
    starts = np.empty(total + 1, dtype=np.int64)
    n = 0
    c = 0
    for rule in range(3):  # 0: end points, 1: free ends left at junctions, 2: anything (loops)
        for p in range(total):
            y0 = pos[p] // W
            x0 = pos[p] - y0 * W
            if visited[y0, x0]:
                continue
            free = _free_neighbours(edges, visited, x0, y0)
            if (rule == 0 and free != 1) or (rule == 1 and free > 1):
                continue
            starts[c] = n
            c += 1
            x, y = x0, y0
            dx, dy = 0, 0
            while True:
                visited[y, x] = True
                points[n, 0] = x
                points[n, 1] = y
                n += 1
                best = -1
                best_score = -10.0
                for k in range(8):
                    xx = x + _DX[k]
                    yy = y + _DY[k]
                    if not (0 <= xx < W and 0 <= yy < H) or edges[yy, xx] == 0 or visited[yy, xx]:
                        continue
                    step = math.sqrt(_DX[k] * _DX[k] + _DY[k] * _DY[k])
                    score = (dx * _DX[k] + dy * _DY[k]) / step if (dx != 0 or dy != 0) else 0.0
                    if score > best_score + 1e-9:  # ties: the first in order (4-neighbours first)
                        best = k
                        best_score = score
                if best < 0:
                    break
                dx, dy = _DX[best], _DY[best]
                x += dx
                y += dy
    starts[c] = n
    return points, starts[: c + 1]


@njit(nogil=True, cache=True)
def split_chains(points, starts, seg_len, window, min_cos):
    """-> centre (S, 2), direction (S, 2) unit, max deviation (S,) px of the edgelet-length segments."""
    n_pts = points.shape[0]
    centre = np.empty((n_pts, 2))
    direction = np.empty((n_pts, 2))
    deviation = np.empty(n_pts)
    corner = np.zeros(n_pts, dtype=np.bool_)
    cum = np.zeros(n_pts)
    s = 0
    for c in range(starts.shape[0] - 1):
        a, b = starts[c], starts[c + 1]
        for i in range(a + window, b - window):
            v1x = points[i, 0] - points[i - window, 0]
            v1y = points[i, 1] - points[i - window, 1]
            v2x = points[i + window, 0] - points[i, 0]
            v2y = points[i + window, 1] - points[i, 1]
            den = math.sqrt(float(v1x * v1x + v1y * v1y) * float(v2x * v2x + v2y * v2y))
            corner[i] = den == 0.0 or (v1x * v2x + v1y * v2y) / den < min_cos
        i = a
        while i < b:
            if corner[i]:
                i += 1
                continue
            j = i  # the straight piece is points[i:j]
            cum[i] = 0.0
            while j + 1 < b and not corner[j + 1]:
                j += 1
                ddx = float(points[j, 0] - points[j - 1, 0])
                ddy = float(points[j, 1] - points[j - 1, 1])
                cum[j] = cum[j - 1] + math.sqrt(ddx * ddx + ddy * ddy)
            j += 1
            length = cum[j - 1]
            n_seg = int(length // seg_len)
            first = 0.5 * (length - n_seg * seg_len)
            k = i
            for q in range(n_seg):
                lo = first + q * seg_len
                hi = lo + seg_len
                while k < j and cum[k] < lo:
                    k += 1
                e = k
                mx = 0.0
                my = 0.0
                while e < j and cum[e] <= hi:
                    mx += points[e, 0]
                    my += points[e, 1]
                    e += 1
                m = e - k
                if m < 2:
                    continue
                mx /= m
                my /= m
                sxx = 0.0
                sxy = 0.0
                syy = 0.0
                for t in range(k, e):
                    ex = points[t, 0] - mx
                    ey = points[t, 1] - my
                    sxx += ex * ex
                    sxy += ex * ey
                    syy += ey * ey
                ang = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
                ux = math.cos(ang)
                uy = math.sin(ang)
                dev = 0.0
                for t in range(k, e):
                    dev = max(dev, abs(-(points[t, 0] - mx) * uy + (points[t, 1] - my) * ux))
                centre[s, 0] = mx
                centre[s, 1] = my
                direction[s, 0] = ux
                direction[s, 1] = uy
                deviation[s] = dev
                s += 1
            i = j
    return centre[:s].copy(), direction[:s].copy(), deviation[:s].copy()
