"""Tukey-biweight iteratively reweighted least squares for the camera pose (PTAM §5.4, §6.5).

Each measurement j is a level-0 pixel with noise σ_j = 2^level (PTAM §5.4); its error e_j = (û, v̂) −
CamProj(exp(μ)·E_CW·p_j) (eq. 9) is scaled by 1/σ_j. The Tukey threshold c² comes from the median of the
scaled squared errors (PTAM code ``Tukey::FindSigmaSquared``: σ = 1.4826·(1 + 5/(2n − 6))·√median,
c = 4.6851·σ), floored at ``min_sigma``² (PTAM code, ``Bundle.MinTukeySigma``); weights are (1 − e²/c²)²
inside c, 0 outside. The 6×6 normal equations, plus a stabilising prior on the diagonal (PTAM code:
``WLS::add_prior``), give μ and E_CW ← exp(μ)·E_CW (eq. 6). Full projections and Jacobians are recomputed
only every ``relinearise_every`` iterations and at the last one (PTAM §6.5); in between the predicted pixels
move linearly by J·μ (PTAM code: ``TrackerData::LinearUpdate``).

A measurement may carry a smear axis a (|a| < 1): its information is σ⁻²·(I − a·aᵀ) instead of σ⁻²·I, less along
the direction its patch was smeared by motion blur (``patch_blur.smear_axes``); its scaled squared error is
rᵀ(I − a·aᵀ)r/σ². a = 0 is PTAM's measurement.

Points are homogeneous (X, w): w = 1 for a map point, w = 0 for a panorama feature, a ray without depth
(Gauglitz et al. §3.2), whose image depends on the camera's rotation only. ``t_max`` ≥ 0 keeps the camera centre
within ``t_max`` of ``c_ref`` after every iteration: Gauglitz et al. §6.2's [R|t ≤ t_max], the rotation-only
model relative to the previous keyframe.

``pose_irls_edgelets`` runs all iterations in one call (``pose_irls`` is it without edgelets); ``normal_equations``
and ``ptam.geometry.tukey_kernels.tukey_sigma_sq`` are its parts.
The ``*_ref`` functions are the numpy references.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..camera.camproj_kernels import project_jac
from ..geometry.cholesky_kernels import cholesky_solve
from ..geometry.se3_kernels import se3_exp
from ..geometry.tukey_kernels import tukey_sigma_sq, tukey_weight


@njit(nogil=True, cache=True, inline="always")
def smeared_sq(r0, r1, a0, a1):
    """|r|² − (a·r)²: the squared error rᵀ(I − a·aᵀ)r of a measurement with smear axis a (in units of σ²)."""
    ar = a0 * r0 + a1 * r1
    return r0 * r0 + r1 * r1 - ar * ar


@njit(nogil=True, cache=True)
def normal_equations(J, r, inv_sigma, smear, w):
    """H = Σ w s² Jᵀ(I − a·aᵀ)J (6, 6) and g = Σ w s² Jᵀ(I − a·aᵀ)r (6,) for pixel Jacobians J (n, 2, 6),
    residuals r (n, 2), s = 1/σ and smear axes a (n, 2) (0: PTAM's isotropic σ)."""
    H = np.zeros((6, 6))
    g = np.zeros(6)
    ja = np.empty(6)
    for k in range(J.shape[0]):
        wk = w[k] * inv_sigma[k] * inv_sigma[k]
        if wk == 0.0:
            continue
        for a in range(6):
            ja0 = J[k, 0, a] * wk
            ja1 = J[k, 1, a] * wk
            g[a] += ja0 * r[k, 0] + ja1 * r[k, 1]
            for b in range(a, 6):
                H[a, b] += ja0 * J[k, 0, b] + ja1 * J[k, 1, b]
        a0 = smear[k, 0]
        a1 = smear[k, 1]
        if a0 == 0.0 and a1 == 0.0:  # PTAM's isotropic measurement
            continue
        ar = a0 * r[k, 0] + a1 * r[k, 1]
        for a in range(6):
            ja[a] = a0 * J[k, 0, a] + a1 * J[k, 1, a]
        for a in range(6):
            jaa = ja[a] * wk
            g[a] -= jaa * ar
            for b in range(a, 6):
                H[a, b] -= jaa * ja[b]
    for a in range(6):
        for b in range(a):
            H[a, b] = H[b, a]
    return H, g


@njit(nogil=True, cache=True)
def _linearise(cam, T, X, Xw, uv, J, valid):
    Jp = np.empty((2, 3))
    for k in range(X.shape[0]):
        wk = Xw[k]
        x = T[0, 0] * X[k, 0] + T[0, 1] * X[k, 1] + T[0, 2] * X[k, 2] + T[0, 3] * wk
        y = T[1, 0] * X[k, 0] + T[1, 1] * X[k, 1] + T[1, 2] * X[k, 2] + T[1, 3] * wk
        z = T[2, 0] * X[k, 0] + T[2, 1] * X[k, 1] + T[2, 2] * X[k, 2] + T[2, 3] * wk
        if z <= 1e-12:
            valid[k] = False
            continue
        valid[k] = True
        u, v, _ = project_jac(cam, x, y, z, Jp)
        uv[k, 0] = u
        uv[k, 1] = v
        # ∂(exp(μ)·Xc)/∂μ = [w·I | −[Xc]×]
        for r in range(2):
            J[k, r, 0] = Jp[r, 0] * wk
            J[k, r, 1] = Jp[r, 1] * wk
            J[k, r, 2] = Jp[r, 2] * wk
            J[k, r, 3] = Jp[r, 1] * -z + Jp[r, 2] * y
            J[k, r, 4] = Jp[r, 0] * z - Jp[r, 2] * x
            J[k, r, 5] = -Jp[r, 0] * y + Jp[r, 1] * x


@njit(nogil=True, cache=True)
def pose_irls(
    cam,
    T_cw,
    X,
    Xw,
    meas,
    inv_sigma,
    smear,
    n_iters,
    relinearise_every,
    min_sigma,
    prior,
    override_after,
    override_sigma_sq,
    c_ref,
    t_max,
):
    """Robust pose from world points (X, Xw) (n, 3), (n,) measured at level-0 pixels meas (n, 2) with 1/σ
    inv_sigma (n,) and smear axes ``smear`` (n, 2) (the information σ⁻²·(I − a·aᵀ): a match smeared along a is
    less certain along it, ``patch_blur.smear_axes``; zeros: PTAM's isotropic σ); the camera centre kept within
    ``t_max`` of ``c_ref`` when ``t_max`` ≥ 0.

    ``override_sigma_sq`` > 0 caps the median-based c² in iterations after ``override_after`` (PTAM code's fixed
    sigma, which PTAM uses instead of the median: the stricter of the two is kept, so many wrong matches cannot
    inflate the median and clean data keeps its tight cut); 0 keeps the median throughout (PTAM §5.4). Returns
    the pose and the last weights (n,).
    """
    none = np.zeros((0, 3))
    flat = np.zeros((0, 2))
    T, w, _ = pose_irls_edgelets(
        cam,
        T_cw,
        X,
        Xw,
        meas,
        inv_sigma,
        smear,
        none,
        flat,
        flat,
        np.zeros(0),
        n_iters,
        relinearise_every,
        min_sigma,
        prior,
        override_after,
        override_sigma_sq,
        c_ref,
        t_max,
    )
    return T, w


@njit(nogil=True, cache=True)
def clamp_centre(T, c_ref, t_max):
    """Move the centre −Rᵀt of pose T (in place) onto the ball of radius t_max about c_ref, if outside."""
    c = np.zeros(3)
    for i in range(3):
        c[i] = -(T[0, i] * T[0, 3] + T[1, i] * T[1, 3] + T[2, i] * T[2, 3])
    d2 = 0.0
    for i in range(3):
        d2 += (c[i] - c_ref[i]) ** 2
    if d2 <= t_max * t_max:
        return
    s = t_max / math.sqrt(d2)
    for i in range(3):
        c[i] = c_ref[i] + (c[i] - c_ref[i]) * s
    for r in range(3):
        T[r, 3] = -(T[r, 0] * c[0] + T[r, 1] * c[1] + T[r, 2] * c[2])


@njit(nogil=True, cache=True)
def pose_irls_edgelets(
    cam,
    T_cw,
    X,
    Xw,
    meas,
    inv_sigma,
    smear,
    E,
    e_meas,
    e_normal,
    e_inv_sigma,
    n_iters,
    relinearise_every,
    min_sigma,
    prior,
    override_after,
    override_sigma_sq,
    c_ref,
    t_max,
):
    """:func:`pose_irls` with edgelets as well (Agility §5.1): world centres E (m, 3), each found on the image
    edge through e_meas (m, 2) with unit normal e_normal (m, 2) (the predicted normal it was searched along),
    1/σ e_inv_sigma (m,). An edgelet's residual is the perpendicular distance ε = n̂·(e_meas − CamProj(·)),
    its Jacobian n̂ᵀ ∂CamProj/∂μ (eq. 11). One Tukey c² serves both: squared σ-scaled errors of points (2-D)
    and edgelets (1-D) share the median (Agility §8 gives both single-pixel variance at level 0, and §4.4 keeps
    edgelet errors in pixels to share the M-estimator). Returns the pose and the last weights of the points
    (n,) and of the edgelets (m,)."""
    n = X.shape[0]
    m = E.shape[0]
    T = T_cw.copy()
    uv = np.zeros((n, 2))
    J = np.zeros((n, 2, 6))
    valid = np.zeros(n, dtype=np.bool_)
    e_uv = np.zeros((m, 2))
    e_J = np.zeros((m, 2, 6))
    e_valid = np.zeros(m, dtype=np.bool_)
    e_w1 = np.ones(m)
    r = np.zeros((n, 2))
    er = np.zeros(m)
    w = np.zeros(n)
    ew = np.zeros(m)
    err_sq = np.zeros(n + m)
    mu = np.zeros(6)
    j = np.empty(6)  # one edgelet's Jacobian row (eq. 11)
    for it in range(n_iters):
        if it % relinearise_every == 0 or it == n_iters - 1:
            _linearise(cam, T, X, Xw, uv, J, valid)
            _linearise(cam, T, E, e_w1, e_uv, e_J, e_valid)
        else:
            _linear_update(uv, J, mu)
            _linear_update(e_uv, e_J, mu)
        k2 = 0
        for k in range(n):
            r[k, 0] = meas[k, 0] - uv[k, 0]
            r[k, 1] = meas[k, 1] - uv[k, 1]
            if valid[k]:
                err_sq[k2] = smeared_sq(r[k, 0], r[k, 1], smear[k, 0], smear[k, 1]) * inv_sigma[k] * inv_sigma[k]
                k2 += 1
        for k in range(m):
            er[k] = e_normal[k, 0] * (e_meas[k, 0] - e_uv[k, 0]) + e_normal[k, 1] * (e_meas[k, 1] - e_uv[k, 1])
            if e_valid[k]:
                err_sq[k2] = er[k] * er[k] * e_inv_sigma[k] * e_inv_sigma[k]
                k2 += 1
        if k2 == 0:
            break
        c2 = tukey_sigma_sq(err_sq[:k2], min_sigma)
        if override_sigma_sq > 0.0 and it > override_after:
            c2 = min(c2, override_sigma_sq)
        for k in range(n):
            e2 = smeared_sq(r[k, 0], r[k, 1], smear[k, 0], smear[k, 1]) * inv_sigma[k] * inv_sigma[k]
            w[k] = tukey_weight(e2, c2) if valid[k] else 0.0
        for k in range(m):
            e2 = er[k] * er[k] * e_inv_sigma[k] * e_inv_sigma[k]
            ew[k] = tukey_weight(e2, c2) if e_valid[k] else 0.0
        H, g = normal_equations(J, r, inv_sigma, smear, w)
        for k in range(m):
            wk = ew[k] * e_inv_sigma[k] * e_inv_sigma[k]
            if wk == 0.0:
                continue
            for a in range(6):
                j[a] = e_normal[k, 0] * e_J[k, 0, a] + e_normal[k, 1] * e_J[k, 1, a]
            for a in range(6):
                wa = wk * j[a]
                g[a] += wa * er[k]
                for b in range(a, 6):
                    H[a, b] += wa * j[b]
        for a in range(6):
            for b in range(a):
                H[a, b] = H[b, a]  # the edgelets added the upper triangle
            H[a, a] += prior
        mu, ok = cholesky_solve(H, g, 6, 0.0)
        if not ok:
            break
        T = se3_exp(mu) @ T
        if t_max >= 0.0:
            clamp_centre(T, c_ref, t_max)
    return T, w, ew


@njit(nogil=True, cache=True)
def _linear_update(uv, J, mu):
    """uv += J·μ: predicted pixels moved linearly between re-linearisations (PTAM code ``LinearUpdate``)."""
    for k in range(uv.shape[0]):
        for a in range(2):
            s = 0.0
            for b in range(6):
                s += J[k, a, b] * mu[b]
            uv[k, a] += s
