"""GRIC model selection at initialisation (Gauglitz §6.1, Torr 1998): both relations' errors are first-order
geometric errors, so a homography wins on a rotation and a far plane and an essential matrix on a translating
3-D scene, at every noise level a webcam gives."""

from __future__ import annotations

import numpy as np
import pytest

from ptam.geometry import so3
from ptam.mapping.gric import em_noise, homography_sampson_sq, sampson_sq
from ptam.mapping.two_view import select_model

F = 500.0  # focal length in pixels: noise is given in pixels, errors are on the unit plane


def _matches(X: np.ndarray, R: np.ndarray, t: np.ndarray, noise_px: float, seed: int):
    rng = np.random.default_rng(seed)
    X1 = X @ R.T + t
    x0 = X[:, :2] / X[:, 2:3] + rng.normal(0, noise_px / F, (len(X), 2))
    x1 = X1[:, :2] / X1[:, 2:3] + rng.normal(0, noise_px / F, (len(X), 2))
    return x0, x1


def _points(n: int, depth: tuple[float, float], seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = rng.uniform(*depth, n)
    xy = rng.uniform(-0.35, 0.35, (n, 2)) * z[:, None]
    return np.concatenate([xy, z[:, None]], axis=1)


def test_errors_are_first_order_geometric_for_both_relations(cfg):
    """Expected squared 4-D distance is σ² per residual dimension: σ² for E (codimension 1), 2σ² for H (2)."""
    sigma = 1.0 / F
    R, t = so3.exp(np.radians([1.0, 2.0, 0.5])), np.array([0.1, 0.0, 0.0])
    X3 = _points(4000, (1.0, 3.0), 0)
    x0, x1 = _matches(X3, R, t, 1.0, 1)
    E = so3.hat(t) @ R
    assert np.mean(sampson_sq(E, x0, x1)) / sigma**2 == pytest.approx(1.0, rel=0.1)
    H = R  # a pure rotation: x1 ~ R·x0
    x0, x1 = _matches(X3, R, np.zeros(3), 1.0, 2)
    assert np.mean(homography_sampson_sq(H, x0, x1)) / sigma**2 == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize("noise_px", [0.5, 1.0, 2.0])
def test_gric_picks_h_on_rotation_and_far_plane_and_e_on_a_translating_scene(cfg, noise_px):
    c = cfg.init
    sigma = c.essential_threshold_px / F
    R = so3.exp(np.radians([0.5, 3.0, 0.3]))
    rotation = _matches(_points(600, (1.0, 3.0), 3), R, np.zeros(3), noise_px, 4)
    plane = _points(600, (10.0, 10.0), 5)  # a wall 10 m away seen across a 10 cm baseline
    far_plane = _matches(plane, R, np.array([0.1, 0.0, 0.0]), noise_px, 6)
    scene = _matches(_points(600, (0.5, 2.0), 7), R, np.array([0.15, 0.02, 0.0]), noise_px, 8)
    assert select_model(*rotation, sigma, c, F)[0] == "H"
    assert select_model(*far_plane, sigma, c, F)[0] == "H"
    assert select_model(*scene, sigma, c, F)[0] == "E"


@pytest.mark.parametrize("dim", [1, 2])
@pytest.mark.parametrize("sigma_px, inliers", [(0.5, 0.9), (1.0, 0.7), (2.0, 0.5)])
def test_em_recovers_the_noise_and_the_inlier_ratio_of_a_mixture(cfg, dim, sigma_px, inliers):
    """Gauglitz §4.2: Gaussian inliers and outliers uniform over the search region (S = 20 px). With half the
    matches wrong, the median of the errors (what Torr's σ uses) is an outlier's; EM is not misled."""
    rng = np.random.default_rng(dim)
    n, S = 2000, 20.0
    k = int(n * inliers)
    e = np.concatenate([rng.normal(0, sigma_px, (k, dim)), rng.uniform(-S / 2, S / 2, (n - k, dim))])
    ms = cfg.model_selection
    sigma2, gamma = em_noise((e**2).sum(axis=1), dim, S**dim, ms.inlier_ratio_bounds, ms.min_sigma**2, ms.em_iterations)
    assert abs(np.sqrt(sigma2) - sigma_px) < 0.1 * sigma_px
    assert abs(gamma - inliers) < 0.05
