"""Local bundle adjustment, PTAM §6.3 eq. (11), on an exploring synthetic map."""

import numpy as np
import pytest

from ptam.bench.ba_timing import new_keyframe_start, synthetic_ba_problem
from ptam.config import default_config
from ptam.geometry import so3
from ptam.map.snapshot import camera_centres
from ptam.mapping.bundle import Bundle
from ptam.mapping.local_ba import local_bundle_adjust, local_sets

CFG = default_config().bundle
N_KF = 40


@pytest.fixture(scope="module")
def explored():
    """40 keyframes along a wall, 1 px noise, 5% outliers; the newest keyframe as the tracker delivers it
    (3 mm / 0.05° off) and the points of the newest pair with 5 cm triangulation depth errors."""
    prob = synthetic_ba_problem(N_KF, 40 * (N_KF - 1), seed=5)
    poses, points = new_keyframe_start(prob, prob.poses_true, prob.points_true, np.random.default_rng(6))
    return prob, poses, points


def test_sets_follow_eq_11(explored):
    prob, poses, _ = explored
    newest = N_KF - 1
    fixed = np.zeros(N_KF, bool)
    fixed[newest - 2] = True  # a permanently fixed keyframe among the nearest is not adjusted (PTAM code)
    s = local_sets(poses, prob.meas_kf, prob.meas_pt, len(prob.points_true), newest, 4, fixed)
    c = camera_centres(poses)
    nearest = np.argsort(np.linalg.norm(c - c[newest], axis=1))[1:5]
    X = np.zeros(N_KF, bool)
    X[nearest] = True
    X &= ~fixed
    X[newest] = True
    assert np.array_equal(s.adjust, X) and X.sum() == 4
    Z = np.isin(np.arange(len(prob.points_true)), prob.meas_pt[X[prob.meas_kf]])
    assert np.array_equal(s.points, Z)
    Y = np.isin(np.arange(N_KF), prob.meas_kf[Z[prob.meas_pt]]) & ~X
    assert np.array_equal(s.fixed, Y)
    assert Y.sum() > 5 and (~(X | Y)).sum() > 5 and 0 < Z.sum() < len(Z) // 2


def test_local_ba_touches_only_x_and_z(explored):
    prob, poses, points = explored
    newest = N_KF - 1
    res, s = local_bundle_adjust(
        Bundle(prob.camera, CFG), poses, points, prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, newest
    )
    assert res.converged and not res.failed
    still = ~s.adjust
    assert np.array_equal(res.poses[still], poses[still])  # Y and the rest: bit-identical
    assert np.array_equal(res.points[~s.points], points[~s.points])  # outside Z: bit-identical
    assert np.all(np.any(res.poses[s.adjust] != poses[s.adjust], axis=(1, 2)))
    assert np.all(np.any(res.points[s.points] != points[s.points], axis=1))
    # Outliers are reported as indices into the full measurement arrays, all of points in Z.
    assert np.all(s.points[prob.meas_pt[res.outliers]])
    flagged = np.zeros(len(prob.meas_kf), bool)
    flagged[res.outliers] = True
    in_z = s.points[prob.meas_pt]
    assert (flagged & prob.gross).sum() >= 0.95 * (prob.gross & in_z).sum()
    # Y holds the gauge, so local BA from this start reaches the optimum it reaches from the truth.
    ref, _ = local_bundle_adjust(
        Bundle(prob.camera, CFG),
        prob.poses_true,
        prob.points_true,
        prob.meas_kf,
        prob.meas_pt,
        prob.meas_xy,
        prob.meas_level,
        newest,
    )
    d_centre = np.abs(camera_centres(res.poses) - camera_centres(ref.poses)).max()
    d_rot = np.linalg.norm(so3.log(res.poses[:, :3, :3] @ np.swapaxes(ref.poses[:, :3, :3], 1, 2)), axis=1).max()
    assert d_centre < 3e-4 and np.degrees(d_rot) < 0.005
