"""Bundle-adjustment kernels: the Schur complement of PTAM's Levenberg–Marquardt (PTAM §6.3; Hartley & Zisserman,
MVG 2nd ed., A6.4), for points (3 DOF) and edgelets (4 DOF, Agility §4.4) alike.

* ``ba_pair_script``: every pair of free cameras sharing a landmark, numbered once per adjustment (PTAM code:
  GenerateOffDiagScripts); the measurements are sorted by landmark (``order``, ``start``).
* ``ba_schur``: S = U* − Σ W V*⁻¹ Wᵀ over every camera pair that shares a point (the O(N²M)
  camera-point-camera products of §6.3) and the reduced right-hand side; * means the diagonal × (1 + λ).
* ``eliminate``: the walk itself, for the points and then the edgelets (``ba_edgelet_schur``). A
  measurement's W = AᵀB has rank 2 (its two image coordinates or distances), so each pair's block is
  A_aᵀ (B_a V*⁻¹ B_bᵀ) A_b, through a 2×2 product. Against W V*⁻¹ Wᵀ from 6×3 blocks the points' Schur
  complement took 29 % less time (a desk_bricks global BA), the edgelets' (6×4) 44 % less.
* ``ba_edgelet_schur``: the edgelets' S −= Σ W V*⁻¹ Wᵀ, V* the diagonal × (1 + λ) inverted by Cholesky; it continues
  the walk of ``ba_pair_script`` after the points, with the points' ``eliminate`` (W has rank 2 for both: two
  distances per measurement).
* ``ba_backsub``: the landmark updates δp = V*⁻¹ (ε_b − Σ Wᵀ δμ), Wᵀ δμ = Bᵀ (A δμ).

The numpy references are in ``tests/reference/bundle.py`` (points) and ``tests/reference/bundle_edgelets.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def _free_measurements(pt_start, order, mrow):
    """The free-camera measurements in walk order: their camera rows, points and ranks within their point, where
    each point's run starts (``fr_start``) and where its entries start in the walk (``entry_start``)."""
    n_pt = pt_start.shape[0] - 1
    fr = np.empty(order.shape[0], np.int64)
    pt_of = np.empty(order.shape[0], np.int64)
    rank = np.empty(order.shape[0], np.int64)
    fr_start = np.zeros(n_pt + 1, np.int64)
    entry_start = np.zeros(n_pt + 1, np.int64)
    k = 0
    for p in range(n_pt):
        c = 0
        for i in range(pt_start[p], pt_start[p + 1]):
            r = mrow[order[i]]
            if r >= 0:
                fr[k], pt_of[k], rank[k] = r, p, c
                k += 1
                c += 1
        fr_start[p + 1] = k
        entry_start[p + 1] = entry_start[p] + c * (c - 1) // 2
    return fr[:k], pt_of[:k], rank[:k], fr_start, entry_start


@njit(nogil=True, cache=True)
def ba_pair_script(pt_start, order, mrow, n_free):
    """Every pair of free cameras sharing a point, as ``ba_schur`` walks them (PTAM code: GenerateOffDiagScripts).

    ``order`` lists the measurements by point, and within a point by ascending camera row. Returns, per entry
    of that walk, the index of its camera pair (r_a > r_b), and each pair's rows (r_a) and columns (r_b). The
    pairs are numbered row by row (r_a), each row's in the order the walk meets them. The entries are visited
    row by row through the measurements grouped by camera (a counting sort), an entry's place in the walk known
    from its point and ranks: O(entries + n_free) time and O(measurements + n_free) memory; bucketing the
    entries themselves by row took 2.7x as long (a 75-keyframe global BA's 460 000 entries).
    """
    fr, pt_of, rank, fr_start, entry_start = _free_measurements(pt_start, order, mrow)
    start = np.zeros(n_free + 1, np.int64)
    for t in range(fr.shape[0]):
        start[fr[t] + 1] += 1
    for r in range(n_free):
        start[r + 1] += start[r]
    fill = start[:-1].copy()
    by_row = np.empty(fr.shape[0], np.int64)
    for t in range(fr.shape[0]):
        by_row[fill[fr[t]]] = t
        fill[fr[t]] += 1
    n = entry_start[-1]
    seen = np.full(n_free, -1, np.int64)
    slot = np.empty(n_free, np.int64)
    pair_id = np.empty(n, np.int64)
    rows = np.empty(min(n, n_free * (n_free - 1) // 2), np.int64)
    cols = np.empty_like(rows)
    n_pairs = 0
    for a in range(n_free):
        for q in range(start[a], start[a + 1]):
            t = by_row[q]
            i, first = rank[t], fr_start[pt_of[t]]
            base = entry_start[pt_of[t]] + i * (i - 1) // 2  # the walk's entries of (point, r_a), by r_b
            for j in range(i):
                b = fr[first + j]
                if seen[b] != a:
                    seen[b] = a
                    slot[b] = n_pairs
                    rows[n_pairs] = a
                    cols[n_pairs] = b
                    n_pairs += 1
                pair_id[base + j] = slot[b]
    return pair_id, rows[:n_pairs].copy(), cols[:n_pairs].copy()


@njit(nogil=True, cache=True)
def inv_sym3(M, lam, out):
    """out = (M with its diagonal × (1 + λ))⁻¹, or zeros when that is not positive definite (PTAM code)."""
    a = M[0, 0] * (1.0 + lam)
    d = M[1, 1] * (1.0 + lam)
    f = M[2, 2] * (1.0 + lam)
    b = M[0, 1]
    c = M[0, 2]
    e = M[1, 2]
    c00 = d * f - e * e
    c01 = c * e - b * f
    c02 = b * e - c * d
    det = a * c00 + b * c01 + c * c02
    if a * d * f == 0.0 or det <= 0.0:
        out[:] = 0.0
        return
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[0, 1] = c01 * inv
    out[0, 2] = c02 * inv
    out[1, 0] = c01 * inv
    out[1, 1] = (a * f - c * c) * inv
    out[1, 2] = (b * c - a * e) * inv
    out[2, 0] = c02 * inv
    out[2, 1] = (b * c - a * e) * inv
    out[2, 2] = (a * d - b * b) * inv


@njit(nogil=True, cache=True, inline="always")
def _sub_pair(blocks, q, Q, A, B, ka, kb):
    """blocks[q] −= A_kaᵀ (Q B_kbᵀ) A_kb for Q = B_ka V*⁻¹ (2×d): the innermost product of the O(N²M) pair walk."""
    c00 = 0.0
    c01 = 0.0
    c10 = 0.0
    c11 = 0.0
    for j in range(Q.shape[1]):
        c00 += Q[0, j] * B[kb, 0, j]
        c01 += Q[0, j] * B[kb, 1, j]
        c10 += Q[1, j] * B[kb, 0, j]
        c11 += Q[1, j] * B[kb, 1, j]
    for a in range(6):
        d0 = A[ka, 0, a] * c00 + A[ka, 1, a] * c10
        d1 = A[ka, 0, a] * c01 + A[ka, 1, a] * c11
        for b in range(6):
            blocks[q, a, b] -= d0 * A[kb, 0, b] + d1 * A[kb, 1, b]


@njit(nogil=True, cache=True)
def eliminate(Vinv, eb, A, B, live, mrow, start, order, pair_id, blocks, rhs):
    """Subtract Σ W V*⁻¹ Wᵀ of every landmark (points: 3 DOF; edgelets: 4, Agility §4.4) from the reduced
    system's ``blocks`` and W V*⁻¹ ε_b from ``rhs``. ``order`` lists the measurements by landmark (``start``),
    then camera row; ``pair_id`` numbers the camera pairs in that walk (``ba_pair_script``). A measurement's
    W = AᵀB has rank 2 (two image coordinates or distances): a pair's block is A_aᵀ (B_a V*⁻¹ B_bᵀ) A_b."""
    d = B.shape[2]
    Q = np.empty((2, d))
    q = 0
    for p in range(start.shape[0] - 1):
        Vi = Vinv[p]
        for ia in range(start[p], start[p + 1]):
            ka = order[ia]
            ra = mrow[ka]
            if ra < 0:
                continue
            if live[ka]:
                q0 = 0.0
                q1 = 0.0
                for b in range(d):
                    s0 = 0.0
                    s1 = 0.0
                    for c in range(d):
                        s0 += B[ka, 0, c] * Vi[c, b]
                        s1 += B[ka, 1, c] * Vi[c, b]
                    Q[0, b] = s0
                    Q[1, b] = s1
                    q0 += s0 * eb[p, b]
                    q1 += s1 * eb[p, b]
                for a in range(6):
                    rhs[6 * ra + a] -= A[ka, 0, a] * q0 + A[ka, 1, a] * q1
                _sub_pair(blocks, ra, Q, A, B, ka, ka)
            for ib in range(start[p], ia):
                kb = order[ib]
                if mrow[kb] < 0:
                    continue
                pid = pair_id[q]
                q += 1
                if live[ka] and live[kb]:
                    _sub_pair(blocks, pid, Q, A, B, ka, kb)


@njit(nogil=True, cache=True)
def ba_schur(U, ea, V, eb, A, B, live, lam, mrow, pt_start, order, pair_id, blocks, rhs, Vinv):
    """Reduced camera system S δμ = rhs as blocks, and V*⁻¹ (M, 3, 3) for the back-substitution.

    blocks[r] (r < n_free) is the diagonal block of camera row r; the off-diagonal block (r_a, r_b),
    r_a > r_b, of the k-th entry of ``ba_pair_script``'s walk is blocks[pair_id[k]].
    """
    nf = U.shape[0]
    blocks[:] = 0.0
    for r in range(nf):
        for a in range(6):
            for b in range(6):
                blocks[r, a, b] = U[r, a, b]
            blocks[r, a, a] *= 1.0 + lam
            rhs[6 * r + a] = ea[r, a]
    for p in range(pt_start.shape[0] - 1):
        inv_sym3(V[p], lam, Vinv[p])
    eliminate(Vinv, eb, A, B, live, mrow, pt_start, order, pair_id, blocks, rhs)


@njit(nogil=True, cache=True)
def ba_backsub(Vinv, eb, A, B, live, mrow, start, order, dcam):
    """Landmark updates δp = V*⁻¹ (ε_b − Σ_j W_jᵀ δμ_j) (M, d) from the camera updates dcam (6·n_free,), with
    W_jᵀ δμ_j = B_jᵀ (A_j δμ_j); points (d = 3) and edgelets (d = 4) alike."""
    m = start.shape[0] - 1
    d = B.shape[2]
    dp = np.zeros((m, d))
    v = np.empty(d)
    for p in range(m):
        for b in range(d):
            v[b] = eb[p, b]
        for i in range(start[p], start[p + 1]):
            k = order[i]
            r = mrow[k]
            if r < 0 or not live[k]:
                continue
            for s in range(2):
                t = 0.0
                for a in range(6):
                    t += A[k, s, a] * dcam[6 * r + a]
                for b in range(d):
                    v[b] -= B[k, s, b] * t
        for a in range(d):
            t = 0.0
            for b in range(d):
                t += Vinv[p, a, b] * v[b]
            dp[p, a] = t
    return dp


@njit(nogil=True, cache=True)
def inv_sym4(M, lam, out, L, Li):
    """out = (M with its diagonal × (1 + λ))⁻¹ by Cholesky, or zeros when that is not positive definite (as
    ``inv_sym3`` does for points). ``L``, ``Li`` are 4×4 scratch."""
    for i in range(4):
        for j in range(i + 1):
            s = M[i, j] * (1.0 + lam) if i == j else M[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if not s > 0.0:
                    out[:] = 0.0
                    return
                L[i, i] = math.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    for i in range(4):
        Li[i, i] = 1.0 / L[i, i]
        for j in range(i):
            s = 0.0
            for k in range(j, i):
                s -= L[i, k] * Li[k, j]
            Li[i, j] = s / L[i, i]
        for j in range(i + 1, 4):
            Li[i, j] = 0.0
    for i in range(4):
        for j in range(4):
            s = 0.0
            for k in range(max(i, j), 4):
                s += Li[k, i] * Li[k, j]
            out[i, j] = s


@njit(nogil=True, cache=True)
def ba_edgelet_schur(V, eb, A, B, live, lam, mrow, e_start, order, pair_id, blocks, rhs, Vinv):
    """Subtract the edgelets' W V*⁻¹ Wᵀ from the reduced system's ``blocks`` and W V*⁻¹ ε_b from ``rhs``
    (``eliminate``, as for points; ``pair_id``: the edgelets' part of ``ba_pair_script``'s walk); V*⁻¹ (E, 4, 4) is
    kept for the back-substitution (``ba_backsub``)."""
    L = np.zeros((4, 4))
    Li = np.zeros((4, 4))
    for e in range(e_start.shape[0] - 1):
        inv_sym4(V[e], lam, Vinv[e], L, Li)
    eliminate(Vinv, eb, A, B, live, mrow, e_start, order, pair_id, blocks, rhs)
