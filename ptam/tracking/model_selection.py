"""Per-frame choice between a general pose and a rotation-only one (Gauglitz et al. TVCG 2013 §4.2, §6.2).

Both models are estimated by the tracker's M-estimator (Table 1): [R|t] from the found 3-D map points, when
there are at least ``min_sfm_points`` (Gauglitz §4.2: "a SfM group which contains sufficiently many of the
successfully tracked features"), and the rotation-only model from all found features, map points and panorama
rays (which constrain the rotation only), as [R|t ≤ t_max] about the nearest keyframe's centre (§6.2: [R|0]
itself is "rarely selected", since a real camera never keeps its centre exactly still). t_max is the translation
at which the panorama's rays, projected from the keyframe's centre, would leave the tracker's fine search
radius: α_max = r_fine / f, t_max = α_max · depth.

For each model, expectation-maximisation estimates the measurement σ and the inlier ratio γ (§4.2: Gaussian
inliers, outliers uniform over the search region), and GRIC (eq. 12, Table 2: k = 6 for [R|t], 3 for [R|0],
D − d = 2, c/v = 1/S² for both) scores it; the lower score wins. Both are scored on the same data, the found
3-D points, each model fitted to them: a ray has no depth, so neither model predicts where a translation moves
it, and with rays in the score a camera walking past the edge of the map, two thirds of its view rays, kept
[R|0] until the rotation model's t_max ran out and beyond (desk_turn_edge: 16 frames reported 23-79 mm off).
The rotation-only pose that is reported still comes from every feature, rays included (they hold the rotation
where few points are in view). Rays keep the rotation-only model's weights either way (the mapper counts them as
seen or not).
Errors are in units of the measurement's pyramid scale (σ = 2^level level-0 pixels, PTAM §5.4).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config import ModelSelectionConfig, TrackerConfig
from ..vocabulary import PoseModel
from .model_selection_kernels import ERROR_DIM, scaled_sq_errors
from .model_selection_kernels import em_noise as em_noise_kernel
from .pose_update import update_pose

K_GENERAL, K_ROTATION = 6, 3  # Gauglitz et al. Table 2: parameters of [R|t] and [R|0]


@dataclass(frozen=True)
class ModelChoice:
    """The chosen model, its pose and the Tukey weights of every measurement, and both GRIC scores (NaN when
    [R|t] could not be estimated: too few 3-D points)."""

    model: PoseModel
    T_cw: np.ndarray
    weights: np.ndarray
    gric_general: float
    gric_rotation: float


def em_noise(e2: np.ndarray, search_area: float, cfg: ModelSelectionConfig) -> tuple[float, float]:
    """σ² and inlier ratio γ of squared 2-D errors ``e2`` by EM (Gauglitz §4.2): a mixture of Gaussian inliers
    and outliers uniform over ``search_area``, clamped (§8.1)."""
    lo, hi = cfg.inlier_ratio_bounds
    e2 = np.ascontiguousarray(e2, dtype=np.float64)
    sigma2, gamma = em_noise_kernel(e2, float(search_area), lo, hi, cfg.min_sigma**2, cfg.em_iterations)
    return float(sigma2), float(gamma)


def gric(e2: np.ndarray, sigma2: float, gamma: float, search_area: float, k: int) -> float:
    """Gauglitz et al. eq. (12) with T_m of eq. (11), for an absolute pose model (c_m/v = 1/S², the model volume
    V cancels between the two models)."""
    n = len(e2)
    log_noise = ERROR_DIM * math.log(2.0 * math.pi * sigma2)
    t_m = 2.0 * math.log(gamma / (1.0 - gamma) * search_area) - log_noise
    rho = np.minimum(e2 / sigma2, t_m)
    return float(rho.sum() + n * (log_noise - 2.0 * math.log(gamma)) + k * math.log(n))


def select_pose_model(
    camera,
    cam,
    tcfg: TrackerConfig,
    cfg: ModelSelectionConfig,
    T_cw: np.ndarray,
    X: np.ndarray,
    Xw: np.ndarray,
    xy: np.ndarray,
    level: np.ndarray,
    fixed_sigma: bool,
    c_ref: np.ndarray,
    t_max: float,
    smear: np.ndarray | None = None,
) -> ModelChoice:
    """Estimate [R|t ≤ t_max] from all features (X, Xw homogeneous: Xw = 0 for rays) and [R|t] from the map
    points, starting at ``T_cw``; keep the model with the lower GRIC on the map points, both fitted to them.
    ``smear``: the matches' smear axes (``update_pose``); GRIC scores the models on PTAM's isotropic errors.
    ``cam``: the camera's kernel parameters (``camera.kernel_params()``, built once by the tracker)."""
    T_rot, w_rot = update_pose(cam, tcfg, T_cw, X, xy, level, False, fixed_sigma, Xw, c_ref, t_max, smear)
    sfm = Xw > 0
    if np.count_nonzero(sfm) < cfg.min_sfm_points:
        return ModelChoice(PoseModel.ROTATION, T_rot, w_rot, math.nan, math.nan)
    X3, xy3, level3 = X[sfm], xy[sfm], level[sfm]
    smear3 = None if smear is None else smear[sfm]
    T_gen, w_sfm = update_pose(cam, tcfg, T_cw, X3, xy3, level3, False, fixed_sigma, smear=smear3)
    T_rot3, _ = update_pose(cam, tcfg, T_cw, X3, xy3, level3, False, fixed_sigma, None, c_ref, t_max, smear3)
    area = (2.0 * tcfg.fine_radius_px) ** 2  # Table 2: S × S, the search region, in the errors' level units
    scores = []
    level_f = level3.astype(np.float64)
    for T, k in ((T_gen, K_GENERAL), (T_rot3, K_ROTATION)):
        e2 = scaled_sq_errors(cam, T, X3, np.ones(len(X3)), xy3, level_f, area)
        scores.append(gric(e2, *em_noise(e2, area, cfg), area, k))
    if scores[1] <= scores[0]:
        return ModelChoice(PoseModel.ROTATION, T_rot, w_rot, scores[0], scores[1])
    w_gen = w_rot.copy()  # rays keep their rotation-only weights: the mapper counts them as seen
    w_gen[sfm] = w_sfm
    return ModelChoice(PoseModel.GENERAL, T_gen, w_gen, scores[0], scores[1])
