"""The measurements of one bundle adjustment laid out by landmark (PTAM §6.3; Agility §4.4 for edgelets), in one pass.

``landmark_layout`` numbers the landmarks that have a measurement, sorts the measurements by landmark and then by
camera row (fixed keyframes, row −1, first; ties in input order: ``np.lexsort((row, landmark))``), and finds a
keyframe that measures one landmark twice. In numpy (``np.unique``-like compaction, a sort to find the duplicates,
``np.lexsort``, ``np.bincount``) this took 0.58 ms for the points of a local BA on the bench's 30-keyframe maps and
0.26 ms more for its edgelets, about 7 % of the adjustment. The numpy reference is in ``tests/reference/bundle.py``.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def landmark_layout(lm, cam, row, n_lm, n_cams):
    """For measurements of landmarks ``lm`` (< ``n_lm``) in compact cameras ``cam`` (< ``n_cams``) at reduced-system
    rows ``row`` (−1 fixed): the landmarks measured (ids, ascending), each measurement's compact landmark, the
    measurements sorted by (landmark, row) (``order``, stable), where each landmark's run starts (``start``), the
    entries of the camera-pair walk of the free measurements (Σ c(c−1)/2, c free measurements per landmark) and
    False when a camera measures a landmark twice."""
    n = lm.shape[0]
    rank = np.full(n_lm, -1, np.int64)
    for k in range(n):
        rank[lm[k]] = 0
    m = 0
    for j in range(n_lm):
        if rank[j] == 0:
            rank[j] = m
            m += 1
    ids = np.empty(m, np.int64)
    for j in range(n_lm):
        if rank[j] >= 0:
            ids[rank[j]] = j
    mlm = np.empty(n, np.int64)
    start = np.zeros(m + 1, np.int64)
    for k in range(n):
        mlm[k] = rank[lm[k]]
        start[mlm[k] + 1] += 1
    for p in range(m):
        start[p + 1] += start[p]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for k in range(n):
        order[fill[mlm[k]]] = k
        fill[mlm[k]] += 1
    seen = np.full(n_cams, -1, np.int64)
    ok = True
    n_entries = 0
    for p in range(m):
        free = 0
        for i in range(start[p], start[p + 1]):
            k = order[i]
            j = i  # insertion sort by row: a landmark has a few dozen measurements at most
            while j > start[p] and row[order[j - 1]] > row[k]:
                order[j] = order[j - 1]
                j -= 1
            order[j] = k
            if seen[cam[k]] == p:
                ok = False
            seen[cam[k]] = p
            free += row[k] >= 0
        n_entries += free * (free - 1) // 2
    return ids, mlm, order, start, n_entries, ok
