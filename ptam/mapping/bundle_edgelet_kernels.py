"""Bundle-adjustment kernels for edgelets: their 4-DOF blocks in PTAM's Schur-complement LM (Agility §4.4).

``ba_edgelet_along`` places the two virtual sample points of eq. 6 ±5 px from the projected centre at the current
state. An edgelet is eliminated exactly like a point (PTAM §6.3, Hartley & Zisserman A6.4), with 4×4 blocks
instead of 3×3: per measurement the two perpendicular distances ε_n (eq. 7) and their Jacobians ∂ε/∂μ_K (2×6, eq. 8) and
∂ε/∂μ_E (2×4, eq. 9) come from ``ptam.edgelet.edgelet_ba_kernels.edgelet_ba_terms``; here they are weighted by
the Tukey biweight and accumulated:

* ``ba_edgelet_linearise``: camera blocks U (6×6, added to the points' U), edgelet blocks V (4×4), camera-edgelet
  blocks W = AᵀB (6×4) and the gradients ε_a, ε_b. ε is predicted − measured, the points' error measured −
  predicted; the gradients take −ε so that one step solves both.
* ``ba_edgelet_schur``: S −= Σ W V*⁻¹ Wᵀ over every camera pair that shares an edgelet and the reduced
  right-hand side, V* the diagonal × (1 + λ); it continues the walk of ``ba_pair_script`` after the points.
* ``ba_edgelet_backsub``: δμ_E = V*⁻¹ (ε_b − Σ Wᵀ δμ_K).

Per Agility §8 every distance has unit (one-pixel) variance. The numpy references are in
``tests/reference/bundle_edgelets.py``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac


@njit(nogil=True, cache=True)
def ba_edgelet_along(cam, poses, frames, mcam, medg, offset_px, along):
    """Eq. 6: the E-frame z of each measurement's two sample points, ∓``offset_px``/|d|, |d| the image length of a
    unit step along the edgelet (eq. 5) at its centre in that keyframe; ``along`` (M, 2) is written."""
    J = np.empty((2, 3))
    for k in range(mcam.shape[0]):
        T = poses[mcam[k]]
        E = frames[medg[k]]
        X = T[0, 0] * E[0, 3] + T[0, 1] * E[1, 3] + T[0, 2] * E[2, 3] + T[0, 3]
        Y = T[1, 0] * E[0, 3] + T[1, 1] * E[1, 3] + T[1, 2] * E[2, 3] + T[1, 3]
        Z = T[2, 0] * E[0, 3] + T[2, 1] * E[1, 3] + T[2, 2] * E[2, 3] + T[2, 3]
        dx = T[0, 0] * E[0, 2] + T[0, 1] * E[1, 2] + T[0, 2] * E[2, 2]
        dy = T[1, 0] * E[0, 2] + T[1, 1] * E[1, 2] + T[1, 2] * E[2, 2]
        dz = T[2, 0] * E[0, 2] + T[2, 1] * E[1, 2] + T[2, 2] * E[2, 2]
        _, _, ok = project_jac(cam, X, Y, Z, J)
        if not ok:  # the centre is behind the camera: the measurement is invalid (edgelet_ba_terms)
            along[k, 0] = 0.0
            along[k, 1] = 0.0
            continue
        du = J[0, 0] * dx + J[0, 1] * dy + J[0, 2] * dz
        dv = J[1, 0] * dx + J[1, 1] * dy + J[1, 2] * dz
        z = offset_px / max(math.sqrt(du * du + dv * dv), 1e-12)
        along[k, 0] = -z
        along[k, 1] = z


@njit(nogil=True, cache=True)
def ba_edgelet_linearise(err, Jp, Je, e2, bad, use, c2, mrow, medg, U, ea, V, eb, W, live):
    """Add the Tukey-weighted edgelet terms (M measurements, ``err`` (M, 2), ``Jp`` (M, 2, 6), ``Je`` (M, 2, 4),
    ``e2`` = |err|², ``bad`` = behind the camera) to U, ε_a (free camera rows ``mrow``, −1 fixed) and set V, ε_b
    (per edgelet ``medg``) and W (per measurement); ``live`` (out) marks the measurements in the system."""
    V[:] = 0.0
    eb[:] = 0.0
    for k in range(err.shape[0]):
        live[k] = False
        W[k] = 0.0
        if not use[k] or bad[k] or e2[k] >= c2:
            continue
        live[k] = True
        # Square root of the Tukey weight on the errors and the Jacobians, as for points (PTAM code).
        sw = 1.0 - e2[k] / c2
        e = medg[k]
        r = mrow[k]
        for s in range(2):
            res = -sw * err[k, s]
            for a in range(4):
                ja = sw * Je[k, s, a]
                for b in range(a + 1):
                    V[e, a, b] += ja * sw * Je[k, s, b]
                eb[e, a] += ja * res
            if r < 0:
                continue
            for a in range(6):
                pa = sw * Jp[k, s, a]
                for b in range(6):
                    U[r, a, b] += pa * sw * Jp[k, s, b]
                ea[r, a] += pa * res
                for b in range(4):
                    W[k, a, b] += pa * sw * Je[k, s, b]
    for e in range(V.shape[0]):
        for a in range(4):
            for b in range(a):
                V[e, b, a] = V[e, a, b]


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
def _sub_wvwt4(blocks, q, WVa, W, kb):
    """blocks[q] −= WVa · W[kb]ᵀ (6×4 · 4×6)."""
    for a in range(6):
        for b in range(6):
            s = 0.0
            for c in range(4):
                s += WVa[a, c] * W[kb, b, c]
            blocks[q, a, b] -= s


@njit(nogil=True, cache=True)
def ba_edgelet_schur(V, eb, W, live, lam, mrow, e_start, order, pair_id, blocks, rhs, Vinv):
    """Subtract the edgelets' W V*⁻¹ Wᵀ from the reduced system's ``blocks`` and W V*⁻¹ ε_b from ``rhs``; V*⁻¹
    (E, 4, 4) is kept for the back-substitution. ``order`` lists the measurements by edgelet (``e_start``), then
    camera row; ``pair_id`` is the edgelets' part of ``ba_pair_script``'s walk."""
    WVa = np.empty((6, 4))
    L = np.zeros((4, 4))
    Li = np.zeros((4, 4))
    q = 0
    for e in range(e_start.shape[0] - 1):
        inv_sym4(V[e], lam, Vinv[e], L, Li)
        Vi = Vinv[e]
        for ia in range(e_start[e], e_start[e + 1]):
            ka = order[ia]
            ra = mrow[ka]
            if ra < 0:
                continue
            if live[ka]:
                for a in range(6):
                    for b in range(4):
                        s = 0.0
                        for c in range(4):
                            s += W[ka, a, c] * Vi[c, b]
                        WVa[a, b] = s
                    rhs[6 * ra + a] -= (
                        WVa[a, 0] * eb[e, 0] + WVa[a, 1] * eb[e, 1] + WVa[a, 2] * eb[e, 2] + (WVa[a, 3] * eb[e, 3])
                    )
                _sub_wvwt4(blocks, ra, WVa, W, ka)
            for ib in range(e_start[e], ia):
                kb = order[ib]
                if mrow[kb] < 0:
                    continue
                pid = pair_id[q]
                q += 1
                if live[ka] and live[kb]:
                    _sub_wvwt4(blocks, pid, WVa, W, kb)


@njit(nogil=True, cache=True)
def ba_edgelet_backsub(Vinv, eb, W, live, mrow, e_start, order, dcam):
    """Edgelet updates δμ_E = V*⁻¹ (ε_b − Σ_j W_jᵀ δμ_j) (E, 4) from the camera updates dcam (6·n_free,)."""
    n = e_start.shape[0] - 1
    de = np.zeros((n, 4))
    v = np.empty(4)
    for e in range(n):
        for b in range(4):
            v[b] = eb[e, b]
        for i in range(e_start[e], e_start[e + 1]):
            k = order[i]
            r = mrow[k]
            if r < 0 or not live[k]:
                continue
            for a in range(6):
                d = dcam[6 * r + a]
                for b in range(4):
                    v[b] -= W[k, a, b] * d
        for a in range(4):
            de[e, a] = Vinv[e, a, 0] * v[0] + Vinv[e, a, 1] * v[1] + Vinv[e, a, 2] * v[2] + Vinv[e, a, 3] * v[3]
    return de
