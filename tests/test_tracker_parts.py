"""Tracker parts: motion model, tracking quality, patch warp geometry, the patch finder, degenerate inputs."""

from dataclasses import replace

import cv2
import numpy as np
import pytest

from ptam.camera import FovCamera
from ptam.capture.frame import Frame
from ptam.config import default_config
from ptam.errors import InputError
from ptam.geometry import se3
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import Map
from ptam.patch.finder import PatchFinder
from ptam.patch.warp import patch_pixel_vectors, search_warps, template_matrices
from ptam.tracking.motion_model import MotionModel
from ptam.tracking.quality import TrackingQuality
from ptam.tracking.tracker import Tracker

CFG = default_config()
CAM = FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9)


def test_motion_model_decaying_velocity():
    mm = MotionModel(CFG.tracker)
    T0 = se3.exp(np.array([0.1, 0.0, -0.2, 0.0, 0.1, 0.0]))
    step = np.array([0.03, 0.0, 0.0, 0.0, 0.01, 0.0])
    T1 = se3.exp(step) @ T0
    mm.update(T0, T1, mean_scene_depth=3.0)
    assert np.allclose(mm.velocity, 0.9 * 0.5 * step)  # v <- 0.9 (0.5 delta + 0.5 v), v = 0
    assert mm.scaled_speed == pytest.approx(np.linalg.norm(0.45 * np.array([0.01, 0, 0, 0, 0.01, 0])))
    assert np.allclose(mm.predict(T1), se3.exp(0.45 * step) @ T1)
    for _ in range(60):  # no more motion: the camera slows and stops
        mm.update(T1, T1, 3.0)
    assert np.linalg.norm(mm.velocity) < 1e-12


def test_tracking_quality_states_and_lost():
    q = TrackingQuality(CFG.tracker)
    att = np.array([600, 250, 100, 50])
    assert q.assess(att, (att * 0.5).astype(int)) == "good"
    assert q.assess(att, np.array([150, 50, 30, 10])) == "poor"  # 0.24 overall, levels >= 2: 40/150 = 0.27
    q.reset()
    for _ in range(CFG.tracker.lost_frames):
        assert not q.lost
        assert q.assess(att, np.array([100, 0, 5, 0])) == "bad"  # large fraction 5/150 < 0.13
    assert q.lost
    assert q.assess(att, att) == "good" and not q.lost
    assert q.assess(np.zeros(4, int), np.zeros(4, int)) == "bad"
    # Gauglitz et al. §4.4: 2 of 5 patches found is PTAM-good, but too few inliers to mean a pose.
    few = np.array([5, 0, 0, 0])
    assert q.assess(few, np.array([2, 0, 0, 0])) == "good"
    assert q.assess(few, np.array([2, 0, 0, 0]), too_few_inliers=True) == "bad"


def test_patch_seen_from_its_source_keyframe_has_identity_template_warp():
    rng = np.random.default_rng(0)
    T_kf = se3.exp(np.array([0.2, -0.1, 0.3, 0.05, -0.1, 0.2]))
    n = 400
    level = rng.integers(0, 4, n).astype(np.int8)
    xy0 = rng.uniform([20, 20], [620, 460], (n, 2))
    xyL = (xy0 + 0.5) / 2.0 ** level[:, None] - 0.5
    depth = rng.uniform(1.0, 5.0, n)
    Xc = np.concatenate([CAM.unproject(xy0), np.ones((n, 1))], axis=1) * depth[:, None]
    X = se3.transform(se3.inv(T_kf), Xc)
    normal = -se3.inv(T_kf)[:3, 2]  # facing the source camera (PTAM §6.5)
    right, down = patch_pixel_vectors(
        CAM, T_kf[None], X, np.broadcast_to(normal, (n, 3)), np.zeros(n, np.int32), level, xyL
    )
    A, search_level = search_warps(CAM.kernel_params(), CFG.patch, 4, T_kf, Xc, right, down)
    # One source-level pixel is 2^L level-0 pixels: det(A)/4^L = 1, searched at the source level, M = I.
    assert np.array_equal(search_level, level)
    # (To first order: the pixel vectors are secants of the lens model over 2^L pixels, A is its tangent.)
    assert np.allclose(A / 2.0 ** level[:, None, None], np.eye(2), atol=0.02)
    assert np.allclose(template_matrices(A, search_level), np.eye(2), atol=0.02)
    # A patch half the size in the world (pixel vectors halved) covers a quarter of the area: one level finer.
    _, finer = search_warps(CAM.kernel_params(), CFG.patch, 4, T_kf, Xc, 0.5 * right, 0.5 * down)
    assert np.array_equal(finer[level > 0], level[level > 0] - 1)


def _find_at_level(finder, kf_pyr, pyr, L, src, predicted_xy, radius_px):
    """Level-L keyframe corners ``src`` searched at level L of ``pyr`` around level-0 ``predicted_xy``."""
    n = len(src)
    return finder.find(
        pyr,
        tuple(im[None] for im in kf_pyr.levels),
        np.zeros(n, np.int32),
        np.full(n, L, np.int8),
        src.astype(np.float64),
        np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
        np.full(n, L, np.int32),
        predicted_xy,
        radius_px,
        np.ones(n, bool),
    )


def test_patch_finder_finds_a_shifted_textured_patch():
    rng = np.random.default_rng(3)
    base = cv2.GaussianBlur(rng.uniform(0, 255, (480, 640)).astype(np.float32), (0, 0), 2.0)
    base = cv2.normalize(base, None, 10, 245, cv2.NORM_MINMAX)
    shift = np.array([3.3, -2.6])  # the current frame is the keyframe moved by a sub-pixel amount
    M_shift = np.float32([[1, 0, shift[0]], [0, 1, shift[1]]])
    kf_img = np.rint(base).astype(np.uint8)
    cur = np.rint(cv2.warpAffine(base, M_shift, (640, 480), flags=cv2.INTER_CUBIC)).astype(np.uint8)
    kf_pyr = Pyramid.build(kf_img, CFG.image)
    pyr = Pyramid.build(cur, CFG.image)
    L = 1
    src = kf_pyr.corners[L][
        (kf_pyr.corners[L][:, 0] > 20)
        & (kf_pyr.corners[L][:, 0] < 290)
        & (kf_pyr.corners[L][:, 1] > 20)
        & (kf_pyr.corners[L][:, 1] < 210)
    ][::7][:200]
    n = len(src)
    truth0 = (src + 0.5) * 2 - 0.5 + shift
    m = _find_at_level(PatchFinder(CFG.patch), kf_pyr, pyr, L, src, truth0 + rng.uniform(-5, 5, (n, 2)), 10.0)
    err = np.linalg.norm(m.xy[m.found] - truth0[m.found], axis=1)
    print(f"patch finder: found {m.found.sum()}/{n}, median error {np.median(err):.3f} px (level 0)")
    assert m.attempted.all() and m.found.mean() > 0.6 and m.subpix[m.found].all()
    assert np.median(err) < 0.15


def _noise_patches(finder, kf_pyr, pyr, L, rng):
    """Every 3rd level-L corner of the keyframe, searched at level L of ``pyr`` within the coarse stage's 30 px of
    its own position."""
    c = kf_pyr.corners[L]
    h, w = kf_pyr.levels[L].shape
    src = c[(c[:, 0] > 8) & (c[:, 0] < w - 8) & (c[:, 1] > 8) & (c[:, 1] < h - 8)][::3]
    at0 = (src + 0.5) * 2**L - 0.5 + rng.uniform(-3, 3, (len(src), 2))
    return _find_at_level(finder, kf_pyr, pyr, L, src, at0, float(CFG.tracker.coarse_radius_px))


@pytest.mark.parametrize("L", [2, 3])
def test_patch_finder_finds_no_chance_matches_in_white_noise(L):
    """White noise averages down to a grey-level std of 9-18 at levels 2-3, so its templates are fainter than
    PTAM's absolute limit and, under that limit alone, match some corner of any other noise image (found
    30-40 % in a tracker, all by chance). In the keyframe itself each is found at its source."""
    rng = np.random.default_rng(4)
    kf_pyr, pyr = (Pyramid.build(rng.integers(0, 256, (480, 640), dtype=np.uint8), CFG.image) for _ in range(2))
    ptam_only = PatchFinder(replace(CFG.patch, max_ssd_template_fraction=np.inf))
    chance = _noise_patches(ptam_only, kf_pyr, pyr, L, rng).found.mean()
    m = _noise_patches(PatchFinder(CFG.patch), kf_pyr, pyr, L, rng)
    itself = _noise_patches(PatchFinder(CFG.patch), kf_pyr, kf_pyr, L, rng)
    print(f"level {L}: {len(m.found)} patches; PTAM's limit alone finds {chance:.1%}, ptam {m.found.mean():.1%}")
    assert m.attempted.all() and len(m.found) >= 30
    assert chance > 0.2 and m.found.mean() < 0.02
    assert itself.found.mean() > 0.95


def test_tracker_without_map_and_with_frame_input():
    tracker = Tracker(CAM, CFG)
    img = np.full((480, 640), 128, np.uint8)
    r = tracker.track(Frame(index=7, timestamp=1.5, image=img), None)
    assert r.frame_index == 7 and r.timestamp == 1.5 and r.quality == "bad" and r.n_attempted == 0
    assert r.timings.total >= r.timings.keyframe_preparation > 0
    m = Map()
    m.add_keyframe(KeyFrame(0, Pyramid.build(img, CFG.image), 2.0, 0.1), np.eye(4))
    for _ in range(CFG.tracker.lost_frames - 1):
        r = tracker.track(img, m.snapshot())  # a map without points: nothing to measure
    assert r.quality == "bad" and r.lost and r.keyframe.nearest_keyframe == 0
    tracker.reset()
    assert not tracker.quality.lost and np.array_equal(tracker.T_cw, np.eye(4))


def test_tracker_rejects_an_image_of_the_wrong_size():
    with pytest.raises(InputError, match="does not match the camera"):
        Tracker(CAM, CFG).track(np.zeros((240, 320), np.uint8), None)


def test_bench_tracking_prints_table_1_and_one_summary_line():
    from ptam.bench.tracking_timing import run_tracking_benchmark

    lines = []
    res = run_tracking_benchmark(CFG, "two_wall_short", out=lines.append, frames=30)
    assert any(line.startswith("Patch search") and "9.8" in line for line in lines)
    keys = [
        "tracking_total_ms_median",
        "tracking_total_ms_p95",
        "pos_err_mm_median",
        "rot_err_deg_median",
        "tracked_fraction",
        "map_points",
    ]
    assert [kv.split("=")[0] for kv in lines[-1].split()] == keys
    assert res["tracked_fraction"] == 1.0 and res["pos_err_mm_median"] < 3.0 and res["map_points"] > 500
