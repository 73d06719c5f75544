"""Panorama keyframes (Gauglitz et al. TVCG 2013 §3.2, §4.3): features without depth.

A keyframe added under rotation-only motion has no baseline to any keyframe, so new features cannot be
triangulated; they become rays from its camera centre. Each is a map point flagged ``ray``, placed on its ray at
the keyframe's scene depth only so that it can be drawn and tested for visibility; the tracker uses its
direction alone (homogeneous w = 0), and bundle adjustment neither moves nor uses it. Candidates are chosen as
for map points (PTAM §6.2): FAST corners with a Shi-Tomasi score, away from the keyframe's measurements.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..image.pyramid import level_to_zero, zero_to_level
from ..image.shi_tomasi import candidates
from ..map.map import SRC_ROOT, Map


def new_point_levels(n_levels: int) -> tuple[int, ...]:
    """PTAM code (AddKeyFrameFromTopOfQueue): new points are sought at the coarsest level first, then fine to
    coarse; (3, 0, 1, 2) for PTAM's four levels."""
    return (n_levels - 1, *range(n_levels - 1))


def free_candidates(m: Map, k: int, level: int, image_cfg, min_dist_px: float) -> np.ndarray:
    """PTAM code ``ThinCandidates``: keyframe k's corner candidates on ``level`` (level pixels), without those
    within ``min_dist_px`` of its measurements on that level (a distance transform of the measured pixels
    instead of PTAM's all-pairs loop)."""
    img = m.keyframes[k].pyramid.levels[level]
    xy, _ = candidates(img, image_cfg.fast_thresholds[level], image_cfg)
    busy = (m.meas_kf == k) & (m.meas_level == level)
    if busy.any() and len(xy):
        h, w = img.shape
        b = np.rint(zero_to_level(m.meas_xy[busy], level)).astype(np.int64)
        b = b[(b[:, 0] >= 0) & (b[:, 1] >= 0) & (b[:, 0] < w) & (b[:, 1] < h)]
        free = np.full((h, w), 255, np.uint8)
        free[b[:, 1], b[:, 0]] = 0
        dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        xy = xy[dist[xy[:, 1], xy[:, 0]] >= min_dist_px]
    return xy


def add_ray_points(m: Map, camera, k: int, level: int, image_cfg, min_dist_px: float) -> np.ndarray:
    """New panorama features of keyframe k on ``level``: rays through its free corner candidates. Returns
    their point indices."""
    xy = free_candidates(m, k, level, image_cfg, min_dist_px)
    if len(xy) == 0:
        return np.zeros(0, np.int64)
    xy0 = level_to_zero(xy.astype(np.float64), level)
    T = m.kf_T_cw[k]
    depth = m.keyframes[k].scene_depth_mean
    unit = camera.unproject(xy0)
    Xc = np.concatenate([unit, np.ones((len(unit), 1))], axis=1) * depth
    X = (Xc - T[:3, 3]) @ T[:3, :3]  # camera → world: Rᵀ(Xc − t)
    normal = np.broadcast_to(-T[2, :3], (len(X), 3))  # facing the camera, parallel to its image plane (§6.5)
    ids = m.add_points(X, normal, k, level, xy.astype(np.float64), ray=True)
    m.add_measurements(k, ids, xy0, level, SRC_ROOT)
    return ids
