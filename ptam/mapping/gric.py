"""Torr's Geometric Robust Information Criterion for choosing between two-view relations.

GRIC = Σ ρ(e²/σ²) + λ₁·d·n + λ₂·k with ρ(x) = min(x, λ₃·(r − d)), λ₁ = log r, λ₂ = log(r·n), λ₃ = 2,
where r = 4 is the dimension of a two-view correspondence, d the dimension of the model's manifold and
k its number of parameters (Torr 1998; used for E versus H by Gauglitz et al. §6.1). Lower is better.
A homography (d = 2, k = 8) explains a planar scene or a rotation with fewer degrees of freedom per point
than an essential matrix (d = 3, k = 5), which is what makes the choice decisive on planar desks, where the
essential matrix is ill-conditioned.
"""

from __future__ import annotations

import numpy as np

R_DIM = 4
# (d, k): the rotation homography K·R·K⁻¹ is a homography with Table 2's k = 3 of [R|0] (Gauglitz et al.).
MODELS = {"E": (3, 5), "H": (2, 8), "R": (2, 3)}


def gric(sq_errors: np.ndarray, sigma: float, model: str, lambda3: float) -> float:
    d, k = MODELS[model]
    n = len(sq_errors)
    rho = np.minimum(np.asarray(sq_errors) / (sigma * sigma), lambda3 * (R_DIM - d))
    return float(rho.sum() + np.log(R_DIM) * d * n + np.log(R_DIM * n) * k)


def sampson_sq(E: np.ndarray, x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """First-order geometric error² of matches (unit-plane (n, 2)) under x1ᵀ·E·x0 = 0."""
    h0 = np.concatenate([x0, np.ones((len(x0), 1))], axis=1)
    h1 = np.concatenate([x1, np.ones((len(x1), 1))], axis=1)
    Ex0 = h0 @ E.T
    Etx1 = h1 @ E
    num = (h1 * Ex0).sum(axis=1) ** 2
    den = Ex0[:, 0] ** 2 + Ex0[:, 1] ** 2 + Etx1[:, 0] ** 2 + Etx1[:, 1] ** 2
    return num / np.maximum(den, 1e-300)


def homography_sampson_sq(H: np.ndarray, x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """First-order geometric error² of matches (unit-plane (n, 2)) under x1 ~ H·x0: the squared distance of the
    4-D correspondence to the homography's manifold (Hartley & Zisserman §4.2.6), the same error Sampson's
    gives an essential matrix, as GRIC needs (Torr 1998). The symmetric transfer error is about twice it, which
    made GRIC prefer E on planar scenes."""
    h0 = np.concatenate([x0, np.ones((len(x0), 1))], axis=1)
    a = h0 @ H.T  # H·x0
    u, v = x1[:, 0], x1[:, 1]
    e = np.stack([v * a[:, 2] - a[:, 1], a[:, 0] - u * a[:, 2]], axis=1)
    # Jacobian of e with respect to (x0, y0, u, v), one 2x4 per match.
    J = np.zeros((len(x0), 2, 4))
    J[:, 0, 0] = v * H[2, 0] - H[1, 0]
    J[:, 0, 1] = v * H[2, 1] - H[1, 1]
    J[:, 0, 3] = a[:, 2]
    J[:, 1, 0] = H[0, 0] - u * H[2, 0]
    J[:, 1, 1] = H[0, 1] - u * H[2, 1]
    J[:, 1, 2] = -a[:, 2]
    S = J @ np.swapaxes(J, 1, 2)
    det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        q = (S[:, 1, 1] * e[:, 0] ** 2 - 2 * S[:, 0, 1] * e[:, 0] * e[:, 1] + S[:, 0, 0] * e[:, 1] ** 2) / det
    return np.where(np.isfinite(q) & (det > 0), q, np.inf)


# Gauglitz et al. §6.1, Table 2, with the frame area L×L (common to every model) dropped: the error dimension
# D − d and the inlier volume c (px^(D−d)) in units of the disparity range Δ; the outlier volume v is S×S.
RELATIONS = {"E": (1, 5), "H": (2, 8), "R": (2, 3)}  # (D − d, k); c = Δ for E, 1 otherwise
CHI2_MEDIAN = {1: 0.4549, 2: 1.3863}  # medians of χ² with one and two degrees of freedom (the latter 2·ln 2)


def em_noise(e2: np.ndarray, dim: int, outlier_volume: float, bounds, min_sigma2: float, iterations: int):
    """σ² and inlier ratio γ of squared ``dim``-dimensional errors (px²) by EM (Gauglitz §4.2): Gaussian inliers,
    outliers uniform over ``outlier_volume`` (v / c); γ clamped to ``bounds`` and σ² to ``min_sigma2`` (§8.1).
    The tracker's 2-D kernel (``tracking.model_selection_kernels.em_noise``) is the same EM for absolute poses."""
    lo, hi = bounds
    e2 = np.minimum(np.asarray(e2, np.float64), 1e12)  # a degenerate match's infinite error: an outlier
    sigma2 = max(float(np.median(e2)) / CHI2_MEDIAN[dim], min_sigma2)
    gamma = 0.5 * (lo + hi)
    for _ in range(iterations):
        p_in = gamma * (2.0 * np.pi * sigma2) ** (-0.5 * dim) * np.exp(-e2 / (2.0 * sigma2))
        r = p_in / (p_in + (1.0 - gamma) / outlier_volume)
        gamma = min(max(float(r.mean()), lo), hi)
        sigma2 = max(float((r * e2).sum()) / (dim * max(float(r.sum()), 1e-12)), min_sigma2)
    return sigma2, gamma


def gric_eq12(e2: np.ndarray, model: str, disparity_range: float, search: float, ms) -> float:
    """Gauglitz et al. eq. (12) for a two-view relation (``model`` in RELATIONS) of squared errors ``e2`` (px²):
    σ and γ by EM, the disparity range Δ expected for E and the side S of the search region in pixels. ``ms``:
    the model-selection config (EM iterations, σ floor, γ bounds)."""
    dim, k = RELATIONS[model]
    c = disparity_range if model == "E" else 1.0
    v_over_c = search * search / c
    sigma2, gamma = em_noise(e2, dim, v_over_c, ms.inlier_ratio_bounds, ms.min_sigma**2, ms.em_iterations)
    n = len(e2)
    log_noise = dim * np.log(2.0 * np.pi * sigma2)
    t_m = 2.0 * np.log(gamma / (1.0 - gamma) * v_over_c) - log_noise
    rho = np.minimum(np.asarray(e2) / sigma2, t_m)
    return float(rho.sum() + n * (log_noise + 2.0 * np.log(c / gamma)) + k * np.log(n))
