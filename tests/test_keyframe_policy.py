"""When an SfM keyframe is due (Gauglitz et al. §4.3 condition 3 against PTAM §6.2): the median triangulation angle
of the frame's inliers, or PTAM's camera distance over mean depth, against the first stereo pair's ratio; PTAM §6.2's
spacing at other frame rates; and which rapid frames Agility §10 keeps from the map."""

from types import SimpleNamespace

import numpy as np
import pytest

from ptam.bench.accuracy import run_accuracy
from ptam.config import load_config
from ptam.geometry import se3
from ptam.system.keyframe_policy import KeyframePolicy
from ptam.tracking.blur_evidence import shows_blur
from ptam.tracking.motion_model import FrameGaps
from ptam.tracking.track_result import KeyframeCandidate
from ptam.vocabulary import RunMode

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


@pytest.mark.parametrize("fps, frames", [(10.0, 7), (30.0, 20), (60.0, 40)])
def test_ptams_twenty_frames_between_keyframes_last_two_thirds_of_a_second_at_any_frame_rate(fps, frames):
    policy = KeyframePolicy()
    policy.cfg = load_config()
    policy.tracker = SimpleNamespace(gaps=FrameGaps(policy.cfg.tracker.motion_period_window))
    assert policy._min_frames() == 20  # no frame period seen yet: PTAM's count
    for i in range(5):
        policy.tracker.gaps.frames(i / fps)
    assert policy._min_frames() == frames
    policy.cfg = load_config(overrides=["mapper.kf_min_frames_fps=0"])
    assert policy._min_frames() == 20  # PTAM: frames, whatever their rate


def _tracked(pyramid, inliers: int, snapshot, cfg):
    """A tracked frame as the policy sees it: ``sharp`` as the tracker judges it (``blur_evidence``)."""
    meas = SimpleNamespace(found=np.arange(1000) < inliers, inlier=np.ones(1000, bool))
    sharp = not shows_blur(pyramid, snapshot, np.eye(4), cfg.tracker.blur_corner_fraction)
    return SimpleNamespace(sharp=sharp, measurements=meas)


def test_a_sharp_rapid_frame_is_mapped_only_if_more_than_the_coarse_stage_posed_it():
    """Agility §10 keeps a rapid frame out of the map unless its image kept its corners (``blur_evidence``); then
    it must also rest on more than the coarse stage's few features (PTAM §5.5)."""
    cfg = load_config()
    keyframe = SimpleNamespace(pyramid=SimpleNamespace(corners=[np.zeros((1000, 2))]))
    snapshot = SimpleNamespace(n_keyframes=1, keyframes=[keyframe], nearest_keyframe=lambda T: (0, 0.0))
    sharp, smeared = (SimpleNamespace(corners=[np.zeros((n, 2))]) for n in (900, 200))
    policy = KeyframePolicy()
    policy.cfg = cfg
    for pyramid, inliers, mappable in (
        (sharp, cfg.tracker.coarse_points, False),
        (sharp, cfg.tracker.coarse_points + 1, True),
        (smeared, 500, False),
    ):
        assert policy._rapid_but_mappable(_tracked(pyramid, inliers, snapshot, cfg)) == mappable
    policy.cfg = load_config(overrides=["tracker.blur_corner_fraction=.inf"])  # Agility §10: no rapid keyframe
    assert not policy._rapid_but_mappable(_tracked(sharp, 1000, snapshot, policy.cfg))


TEN_FPS_CORNER = """\
extends: two_wall
description: two_wall's corner filmed at 10 fps (sharp frames), the turn rapid throughout (3.9 degrees a frame)
frames: 80
fps: 10.0
trajectory:
  keys:
  - {frame: 0.0, position: [-6.35, -3.0, 3], look_at: [-6.35, 0, 3]}
  - {frame: 13.333, position: [-6.0, -3.0, 3], look_at: [-6.0, 0, 3]}
  - {frame: 28.333, position: [-4.5, -3.0, 3], look_at: [-4.5, 0, 3]}
  - {frame: 34.167, position: [-3.926, -3.114, 3], look_at: [-2.778, -0.342, 3]}
  - {frame: 40.0, position: [-3.439, -3.439, 3], look_at: [0, 0, 3]}
  - {frame: 45.833, position: [-3.114, -3.926, 3], look_at: [-0.342, -2.778, 3]}
  - {frame: 51.667, position: [-3.0, -4.5, 3], look_at: [0, -4.5, 3]}
  - {frame: 79.667, position: [-3.0, -7.3, 3], look_at: [0, -7.3, 3]}
"""


@pytest.mark.slow
def test_a_sharp_turn_at_10fps_is_mapped_as_it_happens(tmp_path):
    """two_wall's corner at 10 fps: the 90 degree turn takes 23 frames, every one of them rapid, and the view leaves
    the first wall within six. With PTAM's twenty frames counted at 10 fps (two seconds), blur expected on every
    rapid frame and none of them made a keyframe (Agility §10), the map never reaches the second wall: tracking
    fails in the turn (40 % correct, 9 glitches, 243 mm ATE). With the spacing in time and the sharp rapid frames
    tracked as sharp and mapped, one map follows the whole path (100 %, 0 glitches, 2.0 mm)."""
    scene = tmp_path / "two_wall_10fps_corner.yaml"
    scene.write_text(TEN_FPS_CORNER)
    cfg = load_config()
    ptam = run_accuracy(
        cfg.replace(**{"mapper.kf_min_frames_fps": 0.0, "tracker.blur_corner_fraction": float("inf")}),
        str(scene),
        RunMode.SYNC,
    )
    run = run_accuracy(cfg, str(scene), RunMode.SYNC)
    a, b = ptam.score, run.score
    print(f"PTAM: correct {a.correct_fraction:.3f}, glitches {a.glitches}; now {b.correct_fraction:.3f}, {b.glitches}")
    assert a.correct_fraction < 0.5 and a.glitches >= 5 and a.ate_rmse_m > 0.1
    assert b.correct_fraction >= 0.98 and b.glitches == 0 and b.ate_rmse_m < 0.004
