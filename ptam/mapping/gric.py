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
MODELS = {"E": (3, 5), "H": (2, 8)}


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


def transfer_sq(H: np.ndarray, x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """Symmetric transfer error² (mean of both directions) of matches under x1 ~ H·x0."""

    def apply(M, x):
        h = np.concatenate([x, np.ones((len(x), 1))], axis=1) @ M.T
        with np.errstate(divide="ignore", invalid="ignore"):
            return h[:, :2] / h[:, 2:3]

    e1 = ((apply(H, x0) - x1) ** 2).sum(axis=1)
    e0 = ((apply(np.linalg.inv(H), x1) - x0) ** 2).sum(axis=1)
    out = 0.5 * (e0 + e1)
    return np.where(np.isfinite(out), out, np.inf)
