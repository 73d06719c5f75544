"""Local bundle adjustment, PTAM §6.3 eq. (11): adjust the newest keyframe, its neighbours and their points.

X = the newest keyframe and the ``local_neighbours`` (4) keyframes nearest to it (camera-centre distance,
PTAM code ``KeyFrameLinearDist``); permanently fixed keyframes among the neighbours are left out (PTAM code).
Z = every point measured in a keyframe of X. Y = every other keyframe that measures a point of Z; it is held
fixed, and all measurements of Z's points are used ("using *all* of the measurements ever made of these
points"). Keyframes outside X ∪ Y and points outside Z are not touched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..map.snapshot import camera_centres
from .bundle import AbortFlag, Bundle, BundleResult


@dataclass(frozen=True)
class LocalSets:
    adjust: np.ndarray  # (N,) bool, X minus permanently fixed keyframes: the poses that move
    fixed: np.ndarray  # (N,) bool, Y: fixed keyframes that measure a point of Z
    points: np.ndarray  # (M,) bool, Z


def local_sets(
    kf_T_cw: np.ndarray,
    meas_kf: np.ndarray,
    meas_pt: np.ndarray,
    n_points: int,
    newest: int,
    neighbours: int,
    fixed_keyframes: np.ndarray | None = None,
) -> LocalSets:
    """The sets X, Y, Z of eq. (11) for the keyframe ``newest``."""
    kf_T_cw = np.asarray(kf_T_cw, dtype=np.float64)
    n = len(kf_T_cw)
    if not 0 <= newest < n:
        raise InputError(f"local bundle adjustment: newest keyframe {newest} not in [0, {n})")
    fixed_keyframes = np.zeros(n, bool) if fixed_keyframes is None else np.asarray(fixed_keyframes, bool)
    meas_kf = np.asarray(meas_kf, dtype=np.int64)
    meas_pt = np.asarray(meas_pt, dtype=np.int64)
    if meas_kf.shape != meas_pt.shape or (
        meas_kf.size
        and not (meas_kf.min() >= 0 and meas_kf.max() < n and meas_pt.min() >= 0 and meas_pt.max() < n_points)
    ):
        raise InputError("local bundle adjustment: measurement keyframe/point indices out of range")
    centres = camera_centres(kf_T_cw)
    dist = np.linalg.norm(centres - centres[newest], axis=1)
    dist[newest] = np.inf
    nearest = np.argsort(dist, kind="stable")[: min(neighbours, n - 1)]
    in_x = np.zeros(n, bool)
    in_x[nearest[~fixed_keyframes[nearest]]] = True
    in_x[newest] = True
    Z = np.zeros(n_points, bool)
    Z[meas_pt[in_x[meas_kf]]] = True
    Y = np.zeros(n, bool)
    Y[meas_kf[Z[meas_pt]]] = True
    Y &= ~in_x
    return LocalSets(adjust=in_x & ~fixed_keyframes, fixed=Y, points=Z)


def local_bundle_adjust(
    bundle: Bundle,
    kf_T_cw,
    points,
    meas_kf,
    meas_pt,
    meas_xy,
    meas_level,
    newest: int,
    fixed_keyframes=None,
    abort: AbortFlag = None,
) -> tuple[BundleResult, LocalSets]:
    """Run eq. (11) around ``newest``; returns the bundle result (full-size arrays) and the sets used."""
    sets = local_sets(kf_T_cw, meas_kf, meas_pt, len(points), newest, bundle.cfg.local_neighbours, fixed_keyframes)
    result = bundle.adjust(
        kf_T_cw,
        points,
        meas_kf,
        meas_pt,
        meas_xy,
        meas_level,
        fixed_poses=~sets.adjust,
        adjust_points=sets.points,
        abort=abort,
    )
    return result, sets
