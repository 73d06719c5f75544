"""Steps 4 and 6 of PTAM §5: the robust pose update from patch measurements (PTAM §5.4, §6.5).

Each measurement's noise is σ = 2^level level-0 pixels (PTAM §5.4); ``ptam.tracking.pose_kernels.pose_irls`` runs the
Tukey-biweight reweighted least squares on SE(3).
"""

from __future__ import annotations

import numpy as np

from .pose_kernels import pose_irls


def update_pose(
    cam_params,
    tracker_cfg,
    T_cw,
    X,
    xy,
    level,
    coarse: bool,
    fixed_sigma: bool = True,
    Xw: np.ndarray | None = None,
    c_ref: np.ndarray | None = None,
    t_max: float = -1.0,
    smear: np.ndarray | None = None,
):
    """New T_cw and Tukey weights (n,) from world points X (n, 3) found at level-0 pixels ``xy`` on ``level``.

    ``Xw``: homogeneous weights (1 for map points, 0 for panorama rays, whose X is then a direction); ``t_max``
    ≥ 0 keeps the camera centre within ``t_max`` of ``c_ref`` (Gauglitz et al. §6.2). ``smear``: the matches' smear
    axes (n, 2) (``patch_blur.smear_axes``), None for none.

    The coarse stage re-linearises at every iteration (PTAM code); the fine stage every
    ``relinearise_every`` iterations (PTAM §6.5). With ``tracker.tukey_override_enabled`` the last iterations
    use PTAM code's fixed Tukey σ, unless ``fixed_sigma`` is False: during rapid motion (Agility §8) blur spreads
    every match, and only the median-based σ of §5.4 adapts to it.
    """
    cfg = tracker_cfg
    if cfg.tukey_override_enabled and fixed_sigma:
        override = cfg.tukey_override_sigma_sq_coarse if coarse else cfg.tukey_override_sigma_sq_fine
    else:
        override = 0.0
    inv_sigma = np.exp2(-np.asarray(level, dtype=np.float64))
    return pose_irls(
        cam_params,
        np.ascontiguousarray(T_cw, dtype=np.float64),
        np.ascontiguousarray(X),
        np.ones(len(X)) if Xw is None else np.ascontiguousarray(Xw, dtype=np.float64),
        np.ascontiguousarray(xy, dtype=np.float64),
        inv_sigma,
        np.zeros((len(X), 2)) if smear is None else np.ascontiguousarray(smear, dtype=np.float64),
        int(cfg.irls_iterations),
        1 if coarse else int(cfg.relinearise_every),
        float(cfg.min_tukey_sigma),
        float(cfg.pose_prior),
        int(cfg.tukey_override_after),
        float(override),
        np.zeros(3) if c_ref is None else np.ascontiguousarray(c_ref, dtype=np.float64),
        float(t_max),
    )
