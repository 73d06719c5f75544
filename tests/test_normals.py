"""Feature normals by affine alignment (Gauglitz §5.4, project issue #18): the alignment kernel against its numpy
reference and a known warp, eq. (1) against exact plane homographies through a distorting lens, and the
normals of a rendered slanted wall against its true normal."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ptam.bench.gt_map import build_gt_map
from ptam.camera import FovCamera
from ptam.geometry import se3
from ptam.map.map import SRC_ROOT, SRC_TRACKER
from ptam.mapping.map_maker import MapMaker
from ptam.mapping.normals import normals_from_affines
from ptam.mapping.normals_kernels import align_affine
from ptam.patch.finder import frozen
from ptam.synthetic import load_scene
from tests.reference.normals import align_affine_ref

# A wall slanted 40 degrees about the vertical, 2 m ahead, and a blank sheet of paper lying on it; five views
# 0.8 m apart in all, looking at the wall's centre. PTAM's patches face their source camera: 51 degrees off.
AXIS_A = [0.766044443, 0.0, 0.642787610]
WALL = f"""\
camera: {{model: fov, width: 640, height: 480, fx: 384.0, fy: 384.0, cx: 319.5, cy: 239.5, omega: 0.9}}
frames: 5
fps: 10
rectangles:
  - {{name: wall, center: [0, 0, 2], axes: [{AXIS_A}, [0, 1, 0]], size: [4, 3],
     texture: {{type: dead_leaves, seed: 1, texel: 0.004, sizes: [0.03, 0.8], exponent: 2.5, coverage: 3, detail: 2,
               grey: [30, 240]}}}}
  - {{name: paper, center: [-0.2, 0, 1.83], axes: [{AXIS_A}, [0, 1, 0]], size: [0.5, 0.5],
     texture: {{type: constant, value: 200}}}}
trajectory:
  up: [0, -1, 0]
  keys:
    - {{frame: 0, position: [-0.4, 0, 0], look_at: [0, 0, 2]}}
    - {{frame: 4, position: [0.4, 0, 0], look_at: [0, 0, 2]}}
render:
  optics_blur_px: 1.0
  noise: {{sigma: 2.0, seed: 2}}
"""
WALL_NORMAL = -np.cross(AXIS_A, [0.0, 1.0, 0.0])  # facing the cameras (z < 0)
PAPER_POINTS = np.array(
    [[-0.2 + AXIS_A[0] * a, b, 1.83 + AXIS_A[2] * a] for a in (-0.03, 0, 0.03) for b in (-0.03, 0.03)]
)


def _degrees(n, truth):
    return np.degrees(np.arccos(np.clip(n @ truth, -1.0, 1.0)))


def _textures(rng, n_kf, shape):
    return np.stack([cv2.GaussianBlur(rng.uniform(0, 255, shape), (0, 0), 1.5) for _ in range(n_kf)])


def test_align_affine_matches_reference_and_recovers_a_known_warp():
    rng = np.random.default_rng(0)
    H, W, n = 120, 160, 40
    src = _textures(rng, 1, (H, W))[0]
    src = 255 * (src - src.min()) / np.ptp(src)
    A_true = np.array([[1.05, 0.08], [-0.04, 0.97]])
    t_true = np.array([3.3, -2.1])
    # The target sees the source through the affine (and 10 grey levels brighter): I₂(A·x + t) = I₁(x) + 10.
    tgt = cv2.warpAffine(src, np.c_[A_true, t_true], (W, H), flags=cv2.INTER_CUBIC) + 10
    levels = frozen([np.stack([src, np.clip(tgt, 0, 255)]).astype(np.uint8)])
    xy = rng.uniform(30, [W - 30, H - 30], (n, 2))
    start = xy @ A_true.T + t_true + rng.normal(0, 0.7, (n, 2))
    args = (levels, np.zeros(n, np.int32), np.zeros(n, np.int8), xy, np.ones(n, np.int32), np.zeros(n, np.int8))
    args += (np.tile(np.eye(2), (n, 1, 1)), start, 15, 30, 0.01)
    A, c, converged, ncc = align_affine(*args)
    A_r, c_r, converged_r, ncc_r = align_affine_ref(*args)
    assert np.array_equal(converged, converged_r)
    assert np.allclose(A, A_r, atol=1e-9) and np.allclose(c, c_r, atol=1e-8) and np.allclose(ncc, ncc_r, atol=1e-9)
    assert converged.all() and ncc.min() > 0.99
    assert np.abs(A - A_true).max() < 0.02  # bilinear vs cubic interpolation and 8-bit rounding
    assert np.abs(c - (xy @ A_true.T + t_true)).max() < 0.05  # pixels


def test_align_affine_random_starts_match_reference():
    """Random images, patches and starting warps: most patches are aligned to their own image from a perturbed
    start (and converge), the rest to another image or across the border (and fail)."""
    rng = np.random.default_rng(3)
    images = frozen([_textures(rng, 3, (60, 80)).astype(np.uint8), _textures(rng, 3, (30, 40)).astype(np.uint8)])
    n = 80
    src_kf, tgt_kf = rng.integers(0, 3, n).astype(np.int32), rng.integers(0, 3, n).astype(np.int32)
    own = rng.random(n) < 0.7
    tgt_kf[own] = src_kf[own]
    same = tgt_kf == src_kf
    level = rng.integers(0, 2, n).astype(np.int8)
    xy = rng.uniform(0, 1, (n, 2)) * (np.array([80, 60]) / 2.0 ** level[:, None] - 1)
    A0 = np.eye(2) + rng.normal(0, 0.03, (n, 2, 2))
    args = (images, src_kf, level, xy, tgt_kf, level, A0, xy + rng.normal(0, 0.8, (n, 2)), 9, 20, 0.02)
    out, ref = align_affine(*args), align_affine_ref(*args)
    assert np.array_equal(out[2], ref[2])
    assert 0.3 * n < out[2].sum() < 0.9 * n
    for a, b in zip(out, ref):
        assert np.allclose(a, b, atol=1e-8)
    found = out[2] & same
    assert np.abs(out[0][found] - np.eye(2)).max() < 1e-3 and out[3][found].min() > 0.99  # a patch finds itself
    assert out[3][out[2] & ~same].max() < 0.8  # what converges elsewhere matches poorly


def test_normals_from_affines_inverts_eq1_through_the_lens():
    """Exact pixel affines of plane homographies seen through PTAM's FOV lens give back the planes' normals."""
    cam = FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9)
    rng = np.random.default_rng(1)
    m = 20
    T1 = np.stack([se3.exp(rng.normal(0, 0.2, 6)) for _ in range(m)])
    T2 = np.stack([se3.exp(rng.normal(0, 0.2, 6)) @ T for T in T1])
    Xc1 = np.c_[rng.uniform(-1, 1, (m, 2)), rng.uniform(2, 4, m)]
    X = np.einsum("mij,mj->mi", se3.inv(T1)[:, :3, :3], Xc1) + se3.inv(T1)[:, :3, 3]
    n_true = -Xc1 / np.linalg.norm(Xc1, axis=1, keepdims=True) + rng.normal(0, 0.4, (m, 3))
    n_true /= np.linalg.norm(n_true, axis=1, keepdims=True)
    n_true *= -np.sign(np.sum(n_true * Xc1, axis=1))[:, None]

    def view2(k, uv):  # pixel in view 1 -> its ray meets the plane -> pixel in view 2
        ray = np.append(cam.unproject(uv[None])[0], 1.0)
        P1 = ray * (n_true[k] @ Xc1[k]) / (n_true[k] @ ray)
        T21 = T2[k] @ se3.inv(T1[k])
        return cam.project((T21[:3, :3] @ P1 + T21[:3, 3])[None])[0]

    A = np.zeros((m, 2, 2))
    eps = 1e-4
    for k in range(m):
        uv = cam.project(Xc1[k][None])[0]
        for j in range(2):
            d = np.eye(2)[j] * eps
            A[k, :, j] = (view2(k, uv + d) - view2(k, uv - d)) / (2 * eps)
    n, _ = normals_from_affines(cam, T1, T2, X, A)
    assert np.max(np.degrees(np.arccos(np.clip(np.sum(n * n_true, axis=1), -1, 1)))) < 1e-3


@pytest.fixture(scope="module")
def make_wall(tmp_path_factory, cfg):
    """Builds the wall's map: keyframes with true poses, every point measured where it projects in the other
    views, and a few points in the middle of the blank paper (level 0: their patches see no texture)."""
    path = tmp_path_factory.mktemp("normals") / "wall.yaml"
    path.write_text(WALL)
    scene = load_scene(path)
    cam = scene.camera

    def make():
        m = build_gt_map(scene, cfg, kf_every=1)
        uv0 = cam.project(se3.transform(m.kf_T_cw[0], PAPER_POINTS))
        paper = m.add_points(PAPER_POINTS, -m.kf_T_cw[0][2, :3], 0, 0, uv0)
        m.add_measurements(0, paper, uv0, 0, SRC_ROOT)
        for k in range(m.n_keyframes):
            uv = cam.project(se3.transform(m.kf_T_cw[k], m.X))
            seen = np.flatnonzero(cam.in_image(uv, cfg.image.candidate_border_px) & (m.source_kf != k))
            m.add_measurements(k, seen, uv[seen], m.source_level[seen], SRC_TRACKER)
        return cam, m, paper

    return make


@pytest.fixture(scope="module")
def estimated(make_wall, cfg):
    """The wall's map before, and its MapMaker after running to idle with normal estimation on."""
    cam, m, paper = make_wall()
    before = m.snapshot()
    mm = MapMaker(cam, cfg.replace(**{"normals.enabled": True}), m)
    mm.run_until_idle()
    return before, mm, paper


def test_wall_normals_are_within_10_degrees_after_5_keyframes(estimated):
    before, mm, paper = estimated
    wall_points = np.setdiff1d(before.good_point_indices, paper)
    assert len(wall_points) > 500 and before.n_keyframes == 5
    assert np.median(_degrees(before.normal[wall_points], WALL_NORMAL)) > 45  # PTAM §6.5: facing the source camera
    err = _degrees(mm.snapshot.normal[wall_points], WALL_NORMAL)
    assert (err < 10).mean() >= 0.8  # the acceptance
    assert np.median(err) < 3
    assert mm.step() is False  # every pair aligned once: the mapper idles
    stats = mm.normals.stats
    assert stats["batches"] > 0 and stats["estimates"] > 0.9 * stats["aligned"]


def test_flat_texture_gets_no_estimate(estimated):
    before, mm, paper = estimated
    assert np.array_equal(mm.snapshot.normal[paper], before.normal[paper])  # still facing the source camera
    assert len(mm.snapshot.meas_pt[np.isin(mm.snapshot.meas_pt, paper)]) > 2 * len(paper)  # they had pairs to align


def test_disabled_estimator_does_nothing(make_wall, cfg):
    cam, m, _ = make_wall()
    before = m.snapshot()
    mm = MapMaker(cam, cfg.replace(**{"normals.enabled": False}), m)
    assert mm.step() is False
    assert mm.normals.stats["batches"] == 0 and np.array_equal(mm.snapshot.normal, before.normal)


def test_set_normals_replaces_normals_and_bumps_the_version():
    from ptam.errors import PtamError
    from ptam.image.pyramid import Pyramid
    from ptam.map.keyframe import KeyFrame
    from ptam.map.map import Map
    from tests.support import config

    m = Map()
    with pytest.raises(PtamError):
        m.set_normals([0], [[0.0, 0.0, -1.0]])
    m.add_keyframe(KeyFrame(0, Pyramid.build(np.zeros((96, 128), np.uint8), config().image), 2.0, 0.5), np.eye(4))
    m.add_points(np.ones((3, 3)), [0.0, 0.0, -1.0], 0, 0, np.zeros((3, 2)))
    v = m.version
    n = np.array([[0.0, 0.6, -0.8], [0.6, 0.0, -0.8]])
    m.set_normals([0, 2], n)
    assert m.version == v + 1
    assert np.array_equal(m.snapshot().normal, [n[0], [0.0, 0.0, -1.0], n[1]])
    with pytest.raises(PtamError):
        m.set_normals([0, 1], np.zeros((3, 3)))


@pytest.mark.slow
def test_two_wall_short_map_normals_match_the_walls(cfg):
    """The whole system on two_wall_short: the estimated normals against the true planes (ray-cast from each
    point's source keyframe at its true pose), compared in the source camera's frame."""
    from ptam.bench.accuracy import criteria
    from ptam.eval.score import score_trajectory
    from ptam.system import run_dataset
    from tests.support import sequence

    run_cfg = cfg.replace(**{"normals.enabled": True})
    seq = sequence("two_wall_short")
    system = run_dataset(seq, run_cfg, mode="sync")
    score = score_trajectory(seq / "groundtruth.txt", system.trajectory, criteria=criteria(run_cfg))
    assert score.correct >= 0.95 * score.n_groundtruth
    m, scene = system.mapper.map, load_scene("two_wall_short")
    pts = np.flatnonzero(~m.bad & ~m.ray)
    src = m.source_kf[pts]
    n_est = np.einsum("mij,mj->mi", m.kf_T_cw[src, :3, :3], m.normal[pts])  # source camera frame
    estimated = np.abs(n_est - [0.0, 0.0, -1.0]).max(axis=1) > 1e-9  # no longer facing the source camera
    normals = np.array([r.normal for r in scene.rectangles])
    origins = np.array([r.origin for r in scene.rectangles])
    n_true = np.zeros_like(n_est)
    for k in np.unique(src):
        T_wc = scene.poses_T_wc[np.argmin(np.abs(scene.timestamps - m.keyframes[k].timestamp))]
        sel = src == k
        uv = (m.source_xy[pts[sel]] + 0.5) * np.exp2(m.source_level[pts[sel]])[:, None] - 0.5
        X, _, hit = scene.raycast(T_wc, uv)
        assert hit.all()
        rect = np.argmin(np.abs(np.einsum("mi,ri->mr", X, normals) - np.sum(origins * normals, axis=1)), axis=1)
        rays = scene.camera.unproject_rays(uv)
        n_c = normals[rect] @ T_wc[:3, :3]  # R_cw · n
        n_true[sel] = -np.sign(np.sum(n_c * rays, axis=1))[:, None] * n_c
    err = np.degrees(np.arccos(np.clip(np.sum(n_est * n_true, axis=1), -1.0, 1.0)))
    assert estimated.mean() > 0.8
    assert (err[estimated] < 10).mean() >= 0.9 and np.median(err[estimated]) < 3
