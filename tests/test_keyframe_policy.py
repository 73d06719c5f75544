"""When an SfM keyframe is due (Gauglitz et al. §4.3 condition 3 against PTAM §6.2): the median triangulation angle
of the frame's inliers, or PTAM's camera distance over mean depth, against the first stereo pair's ratio."""

from types import SimpleNamespace

import numpy as np
import pytest

from ptam.config import load_config
from ptam.geometry import se3
from ptam.system.keyframe_policy import KeyframePolicy
from ptam.tracking.track_result import KeyframeCandidate

WIGGLE = 0.1  # the first pair's baseline over its depth: 0.1 m at 1 m


def _policy(by_angle: bool, X: np.ndarray) -> KeyframePolicy:
    cfg = load_config(overrides=[f"model_selection.keyframe_by_angle={str(by_angle).lower()}"])
    snapshot = SimpleNamespace(X=X, ray=np.zeros(len(X), bool), camera_centres=np.zeros((1, 3)))
    mapper = SimpleNamespace(snapshot=snapshot, wiggle_depth_normalised=WIGGLE)
    mapper.need_new_keyframe = lambda dist, depth: dist / depth > cfg.mapper.kf_dist_wiggle_mult * WIGGLE
    policy = KeyframePolicy()
    policy.cfg, policy.mapper = cfg, mapper
    return policy


def _frame_at(centre: np.ndarray, X: np.ndarray):
    """A frame looking along +z from ``centre`` that found every point (the keyframe is at the origin)."""
    T_cw = se3.inv(se3.from_Rt(np.eye(3), centre))
    depth = float(np.mean(X[:, 2] - centre[2]))
    n = len(X)
    meas = SimpleNamespace(point_ids=np.arange(n), found=np.ones(n, bool), inlier=np.ones(n, bool))
    kf = KeyframeCandidate(True, 30, 0, float(np.linalg.norm(centre)), depth, 0.1)
    return SimpleNamespace(T_cw=T_cw, measurements=meas, keyframe=kf)


@pytest.fixture
def plane():
    g = np.linspace(-0.4, 0.4, 9)
    x, y = np.meshgrid(g, g)
    return np.c_[x.ravel(), y.ravel(), np.ones(x.size)]


@pytest.mark.parametrize("by_angle", [True, False])
def test_a_sideways_move_beyond_the_first_pairs_ratio_is_due_by_either_rule(plane, by_angle):
    policy = _policy(by_angle, plane)
    assert policy._baseline_grown(_frame_at(np.array([0.12, 0.0, 0.0]), plane))
    assert not policy._baseline_grown(_frame_at(np.array([0.08, 0.0, 0.0]), plane))


def test_a_move_along_the_view_gains_distance_but_not_triangulation_angle(plane):
    forward = np.array([0.0, 0.0, 0.2])  # distance over depth 0.25; median angle 0.077 rad
    assert _policy(False, plane)._baseline_grown(_frame_at(forward, plane))
    assert not _policy(True, plane)._baseline_grown(_frame_at(forward, plane))
