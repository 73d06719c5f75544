"""Panorama keyframes (Gauglitz et al. TVCG 2013 §3.2, §4.3): features without depth.

A keyframe added under rotation-only motion has no baseline to any keyframe, so new features cannot be
triangulated; they become rays from its camera centre. Each is a map point flagged ``ray``, placed on its ray at
the keyframe's scene depth only so that it can be drawn and tested for visibility; the tracker uses its
direction alone (homogeneous w = 0), and bundle adjustment neither moves nor uses it. Candidates are chosen as
for map points (PTAM §6.2): FAST corners with a Shi-Tomasi score, away from the keyframe's measurements. A ray
that an SfM keyframe finds along its epipolar segment, far enough off its keyframe's centre, is triangulated and
becomes a map point (:func:`triangulate_rays`).
"""

from __future__ import annotations

import cv2
import numpy as np

from ..geometry import se3
from ..image.pyramid import level_to_zero, zero_to_level
from ..image.shi_tomasi import candidates
from ..map.keyframe import KeyFrame
from ..map.map import SRC_EPIPOLAR, SRC_ROOT, Map
from .epipolar import epipolar_matches


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


def held_panorama_keyframes(m: Map, ms_cfg) -> np.ndarray:
    """The keyframes bundle adjustment holds at their poses as panorama keyframes (Gauglitz et al. §5.2: SfM groups
    are adjusted, panoramas are not). With ``adjust_panorama_keyframes`` a panorama keyframe whose rays gained depth
    (§4.3: the panorama group becomes SfM) and which measures old points of the SfM group, ``min_sfm_points`` of
    each as for [R|t] (§4.2), is adjusted with the group: held while the group moves, its measurements of those
    points stop agreeing with it (desk_turn_edge: 3000 of 19000 measurements flagged, and a global BA that took
    three runs of up to 20 iterations, during which an async tracker drifted 20-40 mm on the unadjusted new points).
    Old points alone may crowd a corner of its view (desk_sweep: 10 in 20 x 90 px), which cannot hold a 6-DOF pose:
    BA could not factorise."""
    held = KeyFrame.panorama_flags(m.keyframes)
    if not ms_cfg.adjust_panorama_keyframes:
        return held
    n, k = m.n_points_total, m.n_keyframes
    gained = ~m.ray[:n] & ~m.bad[:n]  # a panorama keyframe's own features are rays until they gain depth
    own = np.bincount(m.source_kf[:n][gained], minlength=k)
    sfm = ~held[m.source_kf[m.meas_pt]] & ~m.bad[m.meas_pt]  # old points: from SfM keyframes
    others = np.bincount(m.meas_kf[sfm], minlength=k)
    return held & ((own < ms_cfg.min_sfm_points) | (others < ms_cfg.min_sfm_points))


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


def triangulate_rays(m: Map, camera, k: int, cfg, plane_corners, min_angle: float) -> np.ndarray:
    """Gauglitz et al. §4.3: a panorama group that gains baseline becomes SfM. A ray cannot be found by projecting it
    into a translated view (it has no depth, and its parallax leaves the tracker's search window), so the rays in
    view of SfM keyframe k are sought as PTAM §6.2 seeks a new point: their source patch along the epipolar segment
    of their ray in k, by zero-mean SSD at FAST corners of the same level, refined to sub-pixel, then triangulated.
    A ray has no depth of its own; the segment is cut to k's scene depth prior (mean ± σ of what k measured, PTAM's
    prior for new points), which the nearby panorama keyframe shares: over all of PTAM's range (the baseline to 40
    baselines) a third of the matches on a repetitive wall were wrong, against 4 % with the prior
    (tests/test_ray_triangulation.py). Only panorama keyframes whose centre lies ``min_angle`` (radians: the first
    stereo pair's baseline over depth) of parallax from k's are searched. k's pose was estimated from the SfM
    group's points, so the points come in its frame and scale (the median distance ratio by which §4.3 scales an
    E-connected group is 1 here). ``plane_corners(k, level)``: k's FAST corners on the unit plane. Returns the new
    points' indices."""
    made = [(np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros(0, np.int64))]
    if m.keyframes[k].panorama:
        return made[0][0]
    n = m.n_points_total
    rays = np.flatnonzero(m.ray[:n] & ~m.bad[:n])
    T, C = m.kf_T_cw, m.camera_centres
    Xc = se3.transform(T[k], m.X[rays])  # drawn at their keyframe's scene depth
    rays = rays[(Xc[:, 2] > 0) & camera.in_image(camera.project(Xc))]
    target = m.keyframes[k]
    for p in np.unique(m.source_kf[rays]):
        kf = m.keyframes[p]
        if np.linalg.norm(C[k] - C[p]) < min_angle * kf.scene_depth_mean:
            continue
        for level in np.unique(m.source_level[rays]):
            ids = rays[(m.source_kf[rays] == p) & (m.source_level[rays] == level)]
            if not len(ids):
                continue
            xy = m.source_xy[ids]
            found = epipolar_matches(
                camera, T[p], T[k], kf.pyramid, target.pyramid, target.scene_depth_mean, target.scene_depth_sigma,
                int(level), xy, plane_corners(k, int(level)), cfg,
            )  # fmt: skip
            if not len(found.X):
                continue
            hit = ids[found.candidate]
            m.place_rays(hit, found.X)
            made.append((hit, found.tgt_xy, np.full(len(hit), level)))
    hit, xy, level = (np.concatenate(parts) for parts in zip(*made))
    # A ray's own prediction ignores parallax: what the tracker or a refind measured of it in k is replaced.
    taken = np.zeros(n, bool)
    taken[hit] = True
    m.remove_measurements((m.meas_kf == k) & taken[m.meas_pt])
    m.add_measurements(k, hit, xy, level, SRC_EPIPOLAR)
    return hit
