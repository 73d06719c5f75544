"""Ground-truth maps of synthetic sequences, so the tracker can be tested and benchmarked without a mapper.

Keyframes every ``kf_every`` frames carry their true poses. New points are chosen per keyframe and level as
PTAM's mapper chooses candidates (§6.2; code ``KeyFrame::MakeKeyFrame_Rest`` and ``MapMaker::ThinCandidates``):
maximal FAST corners with a Shi-Tomasi score above threshold, away from points the keyframe already sees at the
same or the next coarser level. Two ground-truth-only rules keep the map clean: candidates are thinned to
``min_distance_px`` apart (greedy by score), and a patch must lie on one surface plane. Instead of epipolar
search and triangulation, each point's position is the scene surface hit by the ray through its pixel. Its
patch normal faces the source camera (PTAM §6.5).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError
from ..geometry import se3
from ..image.pyramid import Pyramid, level_to_zero, zero_to_level
from ..image.shi_tomasi import candidates
from ..map.keyframe import KeyFrame
from ..map.map import SRC_ROOT, Map


def build_gt_map(scene, cfg, kf_every: int | None = None, max_points: int | None = None, frames=None) -> Map:
    """A :class:`Map` with keyframes at ``frames[::kf_every]`` (default: all frames of the scene) and their true
    poses, and every point PTAM's candidate rules allow, each measured in its source keyframe. If there are more
    than ``max_points``, a random subset (seeded, so spatially unbiased and reproducible) is kept. A frame with no
    corner on a scene surface (blank or smeared by motion blur) is no keyframe; none at all is an error."""
    g = cfg.gtmap
    kf_every = g.kf_every if kf_every is None else int(kf_every)
    max_points = g.max_points if max_points is None else int(max_points)
    frames = np.arange(scene.n_frames) if frames is None else np.asarray(frames, dtype=np.int64).reshape(-1)
    if kf_every < 1 or max_points < 1:
        raise InputError(f"gt map: kf_every and max_points must be positive, got {kf_every}, {max_points}")
    if frames.size == 0 or frames.min() < 0 or frames.max() >= scene.n_frames:
        raise InputError(f"gt map: frames must be non-empty indices below {scene.n_frames}")

    keyframes, poses = [], []
    X = np.zeros((0, 3))
    kf_of, level_of, xy_of = np.zeros(0, np.int32), np.zeros(0, np.int8), np.zeros((0, 2))
    for f in frames[::kf_every]:
        T_wc = np.asarray(scene.poses_T_wc[f], dtype=np.float64)
        pyr = Pyramid.build(scene.render_frame(int(f)), cfg.image)
        new_xy, new_level, new_X, depths = _pick_points(scene, cfg, pyr, T_wc, X, level_of)
        if not depths.size:  # no corner on any surface (blank or blurred): PTAM makes no keyframe of it either
            continue
        keyframes.append(
            KeyFrame(len(keyframes), pyr, *KeyFrame.depth_stats(depths), timestamp=float(scene.timestamps[f]))
        )
        poses.append(se3.inv(T_wc))
        X = np.concatenate([X, new_X])
        xy_of = np.concatenate([xy_of, new_xy])
        level_of = np.concatenate([level_of, new_level])
        kf_of = np.concatenate([kf_of, np.full(len(new_X), len(keyframes) - 1, np.int32)])

    if not keyframes:
        raise InputError(f"gt map: none of frames {frames[0]}-{frames[-1]} sees a corner on a scene surface")
    keep = np.arange(len(X))
    if len(X) > max_points:
        keep = np.sort(np.random.default_rng(g.seed).choice(len(X), max_points, replace=False))
    m = Map()
    for kf, T_cw in zip(keyframes, poses):
        m.add_keyframe(kf, T_cw)
    normal = -np.stack(poses)[kf_of[keep], 2, :3]  # the source camera's optical axis, reversed
    pts = m.add_points(X[keep], normal, kf_of[keep], level_of[keep], xy_of[keep])
    m.add_measurements(kf_of[keep], pts, level_to_zero(xy_of[keep], level_of[keep]), level_of[keep], SRC_ROOT)
    return m


def _pick_points(scene, cfg, pyr: Pyramid, T_wc: np.ndarray, X: np.ndarray, level: np.ndarray):
    """New points of one keyframe given the earlier points (``X``, source ``level``): per level, the candidates
    away from busy positions, thinned, whose patch lies on one plane. Returns (xy at their level, level, X world)
    and the depths of all candidates' surface hits (the keyframe's depth sample, PTAM's depths of the points it
    measures: also those near points already in the map, which add no new point)."""
    g = cfg.gtmap
    Xc = se3.transform(se3.inv(T_wc), X)
    seen = Xc[:, 2] > 0
    busy_uv = scene.camera.project(Xc[seen])
    busy_level = level[seen]
    half_patch = 0.5 * cfg.patch.size
    out_xy, out_level, out_X, depths = [], [], [], []
    # Coarse levels first, so finer levels see the points just placed one level up (ThinCandidates' rule).
    for L in reversed(range(cfg.image.levels)):
        xy, score = candidates(pyr.levels[L], cfg.image.fast_thresholds[L], cfg.image)
        depths.append(_surface_depths(scene, T_wc, level_to_zero(xy, L)))
        busy = (busy_level == L) | (busy_level == L + 1)
        if busy.any() and len(xy):
            dist, _ = cKDTree(zero_to_level(busy_uv[busy], L)).query(xy, distance_upper_bound=g.min_distance_px)
            xy, score = xy[~np.isfinite(dist)], score[~np.isfinite(dist)]
        xy, _ = _thin(xy, score, g.min_distance_px)
        P, ok = _surface_points(scene, T_wc, xy, L, half_patch, g.planarity_tol)
        out_xy.append(xy[ok].astype(np.float64))
        out_level.append(np.full(int(ok.sum()), L, np.int8))
        out_X.append(P[ok])
        busy_uv = np.concatenate([busy_uv, level_to_zero(xy[ok], L)])
        busy_level = np.concatenate([busy_level, out_level[-1]])
    return np.concatenate(out_xy), np.concatenate(out_level), np.concatenate(out_X), np.concatenate(depths)


def _thin(xy: np.ndarray, score: np.ndarray, d: float):
    """Greedy non-maximal suppression by score: visiting candidates from the best, keep one unless a kept one
    lies within ``d`` pixels. Computed in rounds (every candidate that beats all its undecided neighbours is
    kept, its neighbours dropped), which gives the same set as the sequential greedy pass."""
    n = len(xy)
    if n < 2:
        return xy, score
    pairs = cKDTree(xy).query_pairs(d - 1e-9, output_type="ndarray")
    rank = np.empty(n, np.int64)
    rank[np.lexsort((np.arange(n), -score))] = np.arange(n)  # 0 = best; ties broken by index
    hi = np.where(rank[pairs[:, 0]] < rank[pairs[:, 1]], pairs[:, 0], pairs[:, 1])
    lo = pairs[:, 0] + pairs[:, 1] - hi
    undecided = np.ones(n, bool)
    kept = np.zeros(n, bool)
    while undecided.any():
        live = undecided[hi] & undecided[lo]
        beaten = np.zeros(n, bool)
        beaten[lo[live]] = True
        new = undecided & ~beaten
        kept |= new
        undecided &= ~new
        undecided[lo[new[hi]]] = False
        undecided[hi[new[lo]]] = False
    return xy[kept], score[kept]


def _surface_depths(scene, T_wc: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The z-depths of the scene surface hit by the rays through level-0 pixels ``uv``, where they hit."""
    if not len(uv):
        return np.zeros(0)
    X, _, hit = scene.raycast(T_wc, uv)
    depth = se3.transform(se3.inv(T_wc), np.asarray(X, dtype=np.float64))[:, 2]  # z, whatever the raycaster gives
    return depth[np.asarray(hit, dtype=bool) & (depth > 0)]


def _surface_points(scene, T_wc: np.ndarray, xy: np.ndarray, L: int, half_patch: float, tol: float):
    """World points hit by the rays through level-L pixels ``xy``, and whether the whole patch around each lies on
    one plane: the rays through four corners symmetric about the centre on the normalised image plane hit too, and
    the centre's inverse depth equals their mean within ``tol`` (inverse depth is affine over the normalised image
    of a plane)."""
    n = len(xy)
    if not n:
        return np.zeros((0, 3)), np.zeros(0, bool)
    cam = scene.camera
    s = float(1 << L)
    uv = level_to_zero(xy, L)
    centre = cam.unproject(uv)
    signs = np.array([[-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]])
    corners = (centre[:, None, :] + signs[None] * (half_patch * s / np.array([cam.fx, cam.fy]))).reshape(-1, 2)
    corners_uv = cam.project(np.concatenate([corners, np.ones((len(corners), 1))], axis=1))
    X, _, hit = scene.raycast(T_wc, np.concatenate([uv, corners_uv]))
    X, hit = np.asarray(X, dtype=np.float64), np.asarray(hit, dtype=bool)
    depth = se3.transform(se3.inv(T_wc), X)[:, 2]  # z-depth, whatever the raycaster reports
    ok = hit & (depth > 0)
    corner_ok = ok[n:].reshape(n, 4).all(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv_c = 1.0 / depth[:n]
        inv_mean = (1.0 / depth[n:].reshape(n, 4)).mean(axis=1)
        planar = np.abs(inv_mean - inv_c) <= tol * inv_c
    return X[:n], ok[:n] & corner_ok & planar
