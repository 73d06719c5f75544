"""Timestamp association of two trajectories, as TUM's ``associate.py``: one-to-one pairs, chosen greedily by
smallest time difference, each within ``max_dt`` seconds.

TUM's tool sorts every candidate pair and walks the list. Greedy matching equals repeated matching of
mutually-nearest pairs (each pair is the best edge at both its ends; Preis 1999), and in one dimension the
nearest neighbours come from ``np.searchsorted``, so each round is vectorised and rounds are few.
"""

from __future__ import annotations

import numpy as np


def _nearest(sorted_ref: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Index into ``sorted_ref`` of the closest value to each query (ties go to the earlier one)."""
    j = np.searchsorted(sorted_ref, query)
    left = np.clip(j - 1, 0, len(sorted_ref) - 1)
    right = np.clip(j, 0, len(sorted_ref) - 1)
    use_right = np.abs(sorted_ref[right] - query) < np.abs(query - sorted_ref[left])
    return np.where(use_right, right, left)


def associate(t_a: np.ndarray, t_b: np.ndarray, max_dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays (ia, ib) of matched timestamps, |t_a[ia] − t_b[ib]| ≤ max_dt, ordered by t_a."""
    t_a = np.asarray(t_a, dtype=np.float64)
    t_b = np.asarray(t_b, dtype=np.float64)
    # Stable sorts make equal-difference ties resolve by position, a consistent total order on the pairs.
    oa = np.argsort(t_a, kind="stable")
    ob = np.argsort(t_b, kind="stable")
    free_a, free_b = oa, ob
    got_a, got_b = [], []
    while len(free_a) and len(free_b):
        ta, tb = t_a[free_a], t_b[free_b]
        nb = _nearest(tb, ta)
        na = _nearest(ta, tb)
        ia = np.arange(len(free_a))
        mutual = (na[nb] == ia) & (np.abs(tb[nb] - ta) <= max_dt)
        if not mutual.any():
            break
        got_a.append(free_a[mutual])
        got_b.append(free_b[nb[mutual]])
        keep_b = np.ones(len(free_b), bool)
        keep_b[nb[mutual]] = False
        free_a, free_b = free_a[~mutual], free_b[keep_b]
    if not got_a:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    ia, ib = np.concatenate(got_a), np.concatenate(got_b)
    order = np.lexsort((ia, t_a[ia]))
    return ia[order], ib[order]
