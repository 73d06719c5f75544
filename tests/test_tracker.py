"""PTAM §5 tracking on the synthetic two-wall sequence against a ground-truth map, initial pose given.

Thresholds are relative to the mean scene depth (about 3 m here): median position error ≤ 1 mm/m, maximum
≤ 5 mm/m, median rotation error ≤ 0.05°; sensor noise, motion blur and 20% displaced map points may at most
double the clean errors; a start 5 cm and 3° off converges through the coarse stage and not without it.
PTAM's own matching (sub-pixel refinement on the top level only, §5.5) is checked beside the default, which
refines every level (``tracker.fine_subpix_all_levels``).
"""

import dataclasses

import cv2
import numpy as np
import pytest

from ptam.bench.gt_map import build_gt_map
from ptam.config import default_config
from ptam.geometry import se3
from ptam.synthetic import load_scene
from ptam.tracking.tracker import Tracker
from tests.support import sequence

pytestmark = pytest.mark.slow  # replays a whole synthetic sequence

N_FRAMES = 100
CFG = default_config()
PTAM_SUBSET = dataclasses.replace(CFG, tracker=dataclasses.replace(CFG.tracker, fine_subpix_all_levels=False))


@pytest.fixture(scope="module")
def scene():
    return load_scene("two_wall_short")


@pytest.fixture(scope="module")
def frames(scene):
    seq = sequence("two_wall_short")
    return [cv2.imread(str(seq / f"rgb/{i:06d}.png"), cv2.IMREAD_GRAYSCALE) for i in range(N_FRAMES)]


@pytest.fixture(scope="module")
def gt_map(scene):
    return build_gt_map(scene, CFG, kf_every=20, frames=range(N_FRAMES))


@pytest.fixture(scope="module")
def depth(gt_map):
    return float(np.mean([k.scene_depth_mean for k in gt_map.snapshot().keyframes]))


def _track(scene, frames, snapshot, cfg=CFG, start=0, T0=None, recovered=False):
    tracker = Tracker(scene.camera, cfg)
    tracker.set_pose(se3.inv(scene.poses_T_wc[start]) if T0 is None else T0, recovered=recovered)
    results = [tracker.track(frames[i], snapshot) for i in range(start, len(frames))]
    T_wc = np.stack([r.T_wc for r in results])
    truth = scene.poses_T_wc[start : len(frames)]
    pos_mm = 1e3 * np.linalg.norm(T_wc[:, :3, 3] - truth[:, :3, 3], axis=1)
    rot_deg = np.degrees(np.linalg.norm(se3.log(se3.inv(T_wc) @ truth)[:, 3:], axis=1))
    return results, pos_mm, rot_deg


@pytest.fixture(scope="module")
def clean(scene, frames, gt_map):
    return _track(scene, frames, gt_map.snapshot())


@pytest.fixture(scope="module")
def clean_ptam(scene, frames, gt_map):
    return _track(scene, frames, gt_map.snapshot(), PTAM_SUBSET)


@pytest.fixture(scope="module")
def noisy_frames(frames):
    rng = np.random.default_rng(0)
    blur = np.full((1, 3), 1.0 / 3.0, np.float32)  # ~2 px of horizontal motion blur, the direction of travel
    return [
        np.clip(np.rint(cv2.filter2D(f.astype(np.float32), -1, blur) + rng.normal(0.0, 3.0, f.shape)), 0, 255).astype(
            np.uint8
        )
        for f in frames
    ]


def test_clean_sequence_every_frame_good_and_accurate(scene, clean, depth):
    results, pos_mm, rot_deg = clean
    print(
        f"clean: depth {depth:.2f} m, position median {np.median(pos_mm):.2f} max {pos_mm.max():.2f} mm, "
        f"rotation median {np.median(rot_deg):.4f} deg, found {np.median([r.n_found for r in results]):.0f}"
    )
    assert all(r.quality == "good" and not r.lost for r in results)
    assert np.median(pos_mm) <= 1.0 * depth
    assert pos_mm.max() <= 5.0 * depth
    assert np.median(rot_deg) <= 0.05
    r = results[-1]
    assert r.n_attempted <= CFG.tracker.max_patches and r.n_found > 0.8 * r.n_attempted
    m = r.measurements
    assert np.array_equal(np.unique(m.point_ids), np.sort(m.point_ids))  # each point measured once
    assert m.subpix[m.level == 3].any() and m.subpix[(m.level == 0) & ~m.coarse].any()
    # The camera accelerates to ~3.3 cm/frame: the coarse stage switches on once the motion model sees it.
    assert not results[0].did_coarse and results[-1].did_coarse and m.coarse.sum() == CFG.tracker.coarse_points
    assert r.keyframe.quality_good and r.keyframe.frames_since_keyframe == N_FRAMES
    assert r.keyframe.mean_scene_depth == pytest.approx(depth, rel=0.1)
    # Keyframes sit at frames 0, 20, ..., 80: the last frame's nearest is the one of frame 80.
    true_dist = np.linalg.norm(scene.poses_T_wc[N_FRAMES - 1, :3, 3] - scene.poses_T_wc[80, :3, 3])
    assert r.keyframe.nearest_keyframe == 4
    assert r.keyframe.nearest_keyframe_distance == pytest.approx(true_dist, abs=0.005)


def test_ptam_subset_refines_the_top_level_only(clean_ptam, clean, depth):
    """PTAM §5.5: sub-pixel refinement on a high-level subset; the integer matches elsewhere cost accuracy."""
    results, pos_mm, rot_deg = clean_ptam
    print(f"clean, PTAM's subset: position median {np.median(pos_mm):.2f} max {pos_mm.max():.2f} mm")
    assert all(r.quality == "good" and not r.lost for r in results)
    assert np.median(pos_mm) <= 1.0 * depth and pos_mm.max() <= 5.0 * depth and np.median(rot_deg) <= 0.05
    m = results[-1].measurements
    assert m.subpix[m.level == 3].any() and not m.subpix[(m.level < 3) & ~m.coarse].any()
    assert np.median(clean[1]) <= 0.5 * np.median(pos_mm)  # every level refined: measured 0.08 against 0.71 mm


@pytest.fixture(scope="module")
def noisy_ptam(scene, noisy_frames, gt_map):
    return _track(scene, noisy_frames, gt_map.snapshot(), PTAM_SUBSET)


def test_noise_and_motion_blur_at_most_double_the_error(scene, noisy_ptam, clean_ptam):
    """With PTAM's matching, where the integer matches' quantisation dominates the clean error."""
    results, pos_mm, rot_deg = noisy_ptam
    _, pos_clean, rot_clean = clean_ptam
    print(
        f"noisy: position median {np.median(pos_mm):.2f} max {pos_mm.max():.2f} mm, "
        f"rotation median {np.median(rot_deg):.4f} deg"
    )
    assert np.mean([r.tracked for r in results]) >= 0.99
    assert np.median(pos_mm) <= 2.0 * np.median(pos_clean)
    assert np.median(rot_deg) <= 2.0 * np.median(rot_clean)
    assert pos_mm.max() <= 2.0 * pos_clean.max()


def test_subpixel_everywhere_under_noise_and_blur(scene, noisy_frames, gt_map, clean, noisy_ptam):
    """Every level refined: without quantisation noise weighs more against the clean error (measured 0.20 against
    0.08 mm median), but the noisy error is far below PTAM's matching on the same frames (0.78 mm) and the worst
    frame within double the clean worst."""
    results, pos_mm, rot_deg = _track(scene, noisy_frames, gt_map.snapshot())
    _, pos_clean, _ = clean
    _, pos_ptam, rot_ptam = noisy_ptam
    print(f"noisy, every level refined: position median {np.median(pos_mm):.2f} max {pos_mm.max():.2f} mm")
    assert np.mean([r.tracked for r in results]) >= 0.99
    assert np.median(pos_mm) <= 0.5 * np.median(pos_ptam) and pos_mm.max() <= pos_ptam.max()
    assert np.median(rot_deg) <= 0.5 * np.median(rot_ptam)
    assert pos_mm.max() <= 2.0 * pos_clean.max()


def test_displaced_map_points_are_rejected_by_tukey(scene, frames, clean):
    rng = np.random.default_rng(1)
    m = build_gt_map(scene, CFG, kf_every=20, frames=range(N_FRAMES))
    moved = rng.choice(m.n_points_total, m.n_points_total // 5, replace=False)
    d = rng.normal(size=(len(moved), 3))
    m.set_points(moved, m.X[moved] + 0.3 * d / np.linalg.norm(d, axis=1, keepdims=True))
    results, pos_mm, rot_deg = _track(scene, frames, m.snapshot())
    _, pos_clean, rot_clean = clean
    print(
        f"20% displaced: position median {np.median(pos_mm):.2f} max {pos_mm.max():.2f} mm, "
        f"rotation median {np.median(rot_deg):.4f} deg"
    )
    assert all(r.tracked for r in results)
    assert np.median(pos_mm) <= 2.0 * np.median(pos_clean)
    assert np.median(rot_deg) <= 2.0 * np.median(rot_clean)
    assert pos_mm.max() <= 2.0 * pos_clean.max()
    is_moved = np.zeros(m.n_points_total, bool)
    is_moved[moved] = True
    meas = [r.measurements for r in results]
    found_moved = np.concatenate([x.found & is_moved[x.point_ids] for x in meas])
    inlier = np.concatenate([x.inlier for x in meas])
    assert found_moved.sum() > 500  # spurious matches of displaced points do occur ...
    assert inlier[found_moved].mean() < 0.3  # ... and most get zero Tukey weight


def _offset_start(scene, start):
    axis_t = np.array([1.0, -1.0, 1.0]) / np.sqrt(3.0)
    axis_r = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    mu = np.concatenate([0.05 * axis_t, np.radians(3.0) * axis_r])  # 5 cm and 3 degrees
    return se3.exp(mu) @ se3.inv(scene.poses_T_wc[start])


def test_coarse_stage_converges_from_5cm_3deg(scene, frames, gt_map, depth):
    start = 60
    results, pos_mm, rot_deg = _track(
        scene, frames[: start + 10], gt_map.snapshot(), start=start, T0=_offset_start(scene, start), recovered=True
    )
    print(f"offset start, coarse: position {pos_mm[:3].round(2)} mm, rotation {rot_deg[:3].round(3)} deg")
    assert results[0].did_coarse and results[0].measurements.coarse.sum() == 2 * CFG.tracker.coarse_points
    assert all(r.quality == "good" for r in results)
    assert pos_mm.max() <= 5.0 * depth and np.median(rot_deg) <= 0.05


def test_without_coarse_stage_an_offset_start_is_lost(scene, frames, gt_map):
    """What breaks: the fine stage's 10 px radius cannot bridge the ~20 px offset, so few patches are found
    (mostly spurious ones), every frame is bad, tracking is lost after lost_frames frames, and the pose never
    comes back to the truth: it drifts further away, pushed by wrong matches and the motion model."""
    start = 60
    # PTAM §5 alone: Agility's rotation estimator drops the motion model's translation, and Gauglitz's
    # rotation-only model holds the centre near a keyframe, so the pose drifts less with either.
    cfg = CFG.replace(**{"tracker.coarse_enabled": False, "rotation.enabled": False, "model_selection.enabled": False})
    results, pos_mm, rot_deg = _track(
        scene, frames[: start + 10], gt_map.snapshot(), cfg=cfg, start=start, T0=_offset_start(scene, start)
    )
    print(f"offset start, no coarse: position {pos_mm[:3].round(1)} mm, rotation {rot_deg[:3].round(2)} deg")
    assert not any(r.did_coarse for r in results)
    assert all(r.quality == "bad" for r in results)
    assert results[CFG.tracker.lost_frames - 1].lost and not results[CFG.tracker.lost_frames - 2].lost
    for r in results:  # few found overall, and almost none of the coarse-level features (PTAM §5.6's "bad")
        assert r.n_found < CFG.tracker.quality_good * r.n_attempted
        assert r.found_per_level[2:].sum() < CFG.tracker.quality_lost * r.attempted_per_level[2:].sum()
    assert pos_mm.min() > 50.0 and pos_mm[-1] > 200.0


def test_a_rotation_estimate_turned_by_clutter_is_overruled_by_the_motion_model(scene, frames, gt_map, depth):
    """Agility §9.3: something moving before the camera can turn the small-blurry-image rotation estimate. Here
    every tenth frame's estimate is turned by 8° (as a hand sweeping the image turned it by 10-18° on desk_bricks,
    benchmarks/moving_clutter.py). Agility §8's prior, the estimate alone, starts the search 8° off: those frames come
    out poor or wrong. With ``rotation.motion_model_fallback`` such a rapid prior is checked against PTAM's
    motion-model prior (§5.2) and the pass that keeps more of its patches is used: every frame stays as accurate as
    with the true estimate."""
    runs = {}
    for fallback in (False, True):
        cfg = CFG.replace(**{"rotation.motion_model_fallback": fallback})
        tracker = Tracker(scene.camera, cfg)
        estimate, count = tracker.rotation.estimate, [0]

        def turned(pyramid, estimate=estimate, count=count):
            w = estimate(pyramid)
            count[0] += 1
            return w + np.array([0.0, np.radians(8.0), 0.0]) if w is not None and count[0] % 10 == 0 else w

        tracker.rotation.estimate = turned
        tracker.set_pose(se3.inv(scene.poses_T_wc[0]))
        results = [tracker.track(frames[i], gt_map.snapshot()) for i in range(N_FRAMES)]
        T_wc = np.stack([r.T_wc for r in results])
        pos_mm = 1e3 * np.linalg.norm(T_wc[:, :3, 3] - scene.poses_T_wc[:N_FRAMES, :3, 3], axis=1)
        runs[fallback] = (results, pos_mm)
        print(
            f"fallback {fallback}: position max {pos_mm.max():.1f} mm, "
            f"{sum(r.quality != 'good' for r in results)} frames not good"
        )
    (plain, plain_mm), (checked, checked_mm) = runs[False], runs[True]
    assert sum(r.quality != "good" for r in plain) >= 5 or plain_mm.max() > 5.0 * depth
    assert all(r.quality == "good" for r in checked) and checked_mm.max() <= 5.0 * depth
