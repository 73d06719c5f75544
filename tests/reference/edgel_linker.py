"""Plain-Python/numpy references for ``ptam.edgelet.edgel_linker_kernels`` (Agility §4.3 linker and splitting)."""

from __future__ import annotations

import numpy as np

STEPS = [(1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 1), (-1, -1), (1, -1)]


def link_edgels_ref(edges):
    H, W = edges.shape
    on = edges != 0
    visited = np.zeros_like(on)

    def free(x, y):
        return [
            (dx, dy)
            for dx, dy in STEPS
            if 0 <= x + dx < W and 0 <= y + dy < H and on[y + dy, x + dx] and not visited[y + dy, x + dx]
        ]

    chains = []
    for rule in range(3):
        for y0, x0 in zip(*np.nonzero(on)):  # row-major, like the kernel
            if visited[y0, x0]:
                continue
            nf = len(free(x0, y0))
            if (rule == 0 and nf != 1) or (rule == 1 and nf > 1):
                continue
            chain, (x, y), (dx, dy) = [], (int(x0), int(y0)), (0, 0)
            while True:
                visited[y, x] = True
                chain.append((x, y))
                options = free(x, y)
                if not options:
                    break
                scores = [(dx * sx + dy * sy) / np.hypot(sx, sy) if (dx or dy) else 0.0 for sx, sy in options]
                dx, dy = options[int(np.argmax(scores))]  # the first of equal scores, like the kernel
                x, y = x + dx, y + dy
            chains.append(chain)
    points = np.array([p for c in chains for p in c], dtype=np.int32).reshape(-1, 2)
    starts = np.cumsum([0] + [len(c) for c in chains])
    return points, starts


def _fit(P):
    m = P.mean(axis=0)
    e = P - m
    S = e.T @ e
    ang = 0.5 * np.arctan2(2 * S[0, 1], S[0, 0] - S[1, 1])
    u = np.array([np.cos(ang), np.sin(ang)])
    return m, u, np.max(np.abs(-e[:, 0] * u[1] + e[:, 1] * u[0]))


def split_chains_ref(points, starts, seg_len, window, min_cos):
    out = []
    for a, b in zip(starts[:-1], starts[1:]):
        P = points[a:b].astype(np.float64)
        m = len(P)
        corner = np.zeros(m, dtype=bool)
        if m > 2 * window:
            v1 = P[window : m - window] - P[: m - 2 * window]
            v2 = P[2 * window :] - P[window : m - window]
            den = np.linalg.norm(v1, axis=1) * np.linalg.norm(v2, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                corner[window : m - window] = (den == 0) | (np.sum(v1 * v2, axis=1) / den < min_cos)
        # Straight pieces: maximal runs of non-corner points.
        edges = np.flatnonzero(np.diff(np.concatenate([[1], corner.astype(int), [1]])))
        for i, j in zip(edges[::2], edges[1::2]):
            Q = P[i:j]
            cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
            n_seg = int(cum[-1] // seg_len)
            first = 0.5 * (cum[-1] - n_seg * seg_len)
            for q in range(n_seg):
                lo = first + q * seg_len
                sel = (cum >= lo) & (cum <= lo + seg_len)
                if sel.sum() >= 2:
                    out.append(_fit(Q[sel]))
    if not out:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0)
    c, d, dev = zip(*out)
    return np.array(c), np.array(d), np.array(dev)
