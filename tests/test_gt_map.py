import numpy as np
import pytest
from scipy.spatial import cKDTree

from ptam.bench.gt_map import build_gt_map
from ptam.config import default_config
from ptam.errors import InputError
from ptam.geometry import se3
from ptam.image.pyramid import level_to_zero, zero_to_level
from ptam.synthetic import load_scene
from ptam.synthetic.scene import Scene

CFG = default_config()


@pytest.fixture(scope="module")
def scene():
    return load_scene("two_wall_short")


@pytest.fixture(scope="module")
def gt(scene):
    # ~880 points qualify in these three keyframes: a cap of 800 exercises the subset
    return build_gt_map(scene, CFG, kf_every=20, max_points=800, frames=range(0, 60))


def test_points_lie_on_the_surface_at_their_source_pixel(scene, gt):
    s = gt.snapshot()
    assert s.n_keyframes == 3 and np.array_equal([k.timestamp for k in s.keyframes], scene.timestamps[[0, 20, 40]])
    assert np.allclose(s.kf_T_cw, se3.inv(scene.poses_T_wc[[0, 20, 40]]))
    assert s.n_points == 800 and np.all(np.bincount(s.source_level, minlength=4) > 10)
    src0 = level_to_zero(s.source_xy, s.source_level)
    T = s.kf_T_cw[s.source_kf]
    Xc = np.einsum("nij,nj->ni", T[:, :3, :3], s.X) + T[:, :3, 3]
    uv = scene.camera.project(Xc)
    assert np.abs(uv - src0).max() < 0.01  # px, reprojection into the source keyframe
    for k in range(s.n_keyframes):
        at = s.source_kf == k
        X, depth, hit = scene.raycast(scene.poses_T_wc[20 * k], uv[at])
        assert hit.all() and np.abs(depth - Xc[at, 2]).max() < 1e-6  # m
        assert np.abs(X - s.X[at]).max() < 1e-6
        assert np.allclose(s.normal[at], -scene.poses_T_wc[20 * k][:3, 2])  # facing the source camera
        assert abs(s.keyframes[k].scene_depth_mean - Xc[at, 2].mean()) < 0.05 * Xc[at, 2].mean()
    # one measurement per point, in its source keyframe, at its source level and pixel
    assert np.array_equal(s.meas_pt, np.arange(s.n_points))
    assert np.array_equal(s.meas_kf, s.source_kf) and np.array_equal(s.meas_level, s.source_level)
    assert np.abs(s.meas_xy - src0).max() < 1e-12


def test_no_near_duplicate_points(scene, gt):
    """PTAM's ThinCandidates rule: a new level-L point is >= min_distance_px (level pixels) from every point
    the keyframe already sees at level L or L+1, and from the other new points of its level."""
    s = gt.snapshot()
    d = CFG.gtmap.min_distance_px
    for k in range(s.n_keyframes):
        Xc = se3.transform(s.kf_T_cw[k], s.X)
        for L in range(4):
            new = (s.source_kf == k) & (s.source_level == L)
            older = (s.source_kf < k) & np.isin(s.source_level, [L, L + 1]) & (Xc[:, 2] > 0)
            coarser_new = (s.source_kf == k) & (s.source_level == L + 1)
            busy = zero_to_level(scene.camera.project(Xc[older | coarser_new]), L)
            if new.sum() > 1:
                dist, _ = cKDTree(s.source_xy[new]).query(s.source_xy[new], k=2)
                assert dist[:, 1].min() >= d
            if len(busy) and new.any():
                dist, _ = cKDTree(busy).query(s.source_xy[new])
                assert dist.min() >= d - 1e-9


def test_a_keyframe_over_mapped_ground_adds_no_point_but_keeps_its_depth(scene):
    """A keyframe whose every corner lies near a point already in the map (a camera back over mapped ground) is a
    keyframe without new points; its depth sample is the surface under all its corners, as in a fresh view."""
    once = build_gt_map(scene, CFG, kf_every=1, frames=[0]).snapshot()
    twice = build_gt_map(scene, CFG, kf_every=1, frames=[0, 0]).snapshot()
    assert twice.n_keyframes == 2 and twice.n_points == once.n_points > 300
    assert np.array_equal(twice.source_kf, np.zeros(once.n_points))
    first, again = twice.keyframes
    assert again.scene_depth_mean == first.scene_depth_mean == once.keyframes[0].scene_depth_mean
    assert again.scene_depth_sigma == first.scene_depth_sigma
    z = se3.transform(twice.kf_T_cw[0], twice.X)[:, 2]
    assert abs(first.scene_depth_mean - z.mean()) < 0.01 * z.mean()  # the points' mean depth, within 1 %


def test_frames_without_a_corner_on_a_surface_make_no_keyframe(scene):
    blank = dict(
        scene.spec, rectangles=[dict(r, texture={"type": "constant", "value": 128}) for r in scene.spec["rectangles"]]
    )
    with pytest.raises(InputError, match="sees a corner"):
        build_gt_map(Scene("blank", blank), CFG, kf_every=20, frames=range(0, 60))


def test_bad_arguments(scene):
    with pytest.raises(InputError):
        build_gt_map(scene, CFG, kf_every=0)
    with pytest.raises(InputError):
        build_gt_map(scene, CFG, frames=[scene.n_frames])
