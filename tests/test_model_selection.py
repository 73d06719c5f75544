"""Model selection (Gauglitz et al. TVCG 2013 §4.2–§4.3, §6): EM for the noise, GRIC for [R|t] against [R|0],
and panorama keyframes when the camera only rotates into unmapped space."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ptam.bench.accuracy import criteria
from ptam.eval.score import score_trajectory
from ptam.geometry import se3
from ptam.map.groups import keyframe_groups
from ptam.map.map_file import load_map, save_map
from ptam.system import run_dataset
from ptam.tracking.model_selection import K_GENERAL, K_ROTATION, em_noise, gric, select_pose_model
from ptam.vocabulary import GroupKind, PoseModel, RunMode
from tests.support.cameras import CAMERAS


@pytest.mark.parametrize("sigma,gamma", [(0.5, 0.9), (1.0, 0.7), (2.0, 0.5)])
def test_em_recovers_the_noise_and_the_inlier_ratio(cfg, sigma, gamma):
    """Gaussian inliers and outliers uniform over the 20 × 20 search region (§4.2)."""
    rng = np.random.default_rng(3)
    n, side = 4000, 20.0
    inlier = rng.uniform(size=n) < gamma
    e = np.where(inlier[:, None], rng.normal(scale=sigma, size=(n, 2)), rng.uniform(-side / 2, side / 2, (n, 2)))
    sigma2, g = em_noise((e**2).sum(axis=1), side**2, cfg.model_selection)
    assert math.sqrt(sigma2) == pytest.approx(sigma, rel=0.05)
    assert g == pytest.approx(gamma, abs=0.03)


def test_gric_prefers_the_simpler_model_on_equal_errors_and_pays_for_larger_ones():
    """eq. (12): the same errors cost k·log n more for [R|t]; errors that are larger by more than that lose."""
    e2 = np.random.default_rng(0).chisquare(2, 500)
    area = 400.0
    g_gen = gric(e2, 1.0, 0.9, area, K_GENERAL)
    assert gric(e2, 1.0, 0.9, area, K_ROTATION) == pytest.approx(g_gen - 3 * math.log(500))
    assert gric(e2 * 1.1, 1.0, 0.9, area, K_ROTATION) > g_gen


def _scene(camera, rng, n=300, depth=(1.0, 2.0)):
    Xc = np.concatenate([rng.uniform(-0.6, 0.6, (n, 2)) * depth[0], rng.uniform(*depth, (n, 1))], axis=1)
    return Xc[camera.project(Xc)[:, 0] > 0]


@pytest.mark.parametrize("name", list(CAMERAS))
@pytest.mark.parametrize(
    "move_cm,expected", [(0.0, PoseModel.ROTATION), (0.5, PoseModel.ROTATION), (6.0, PoseModel.GENERAL)]
)
def test_gric_tells_rotation_from_translation(cfg, name, move_cm, expected):
    """A keyframe at the origin, 1–2 m from the scene; the camera turns by 3° and moves ``move_cm``. With
    t_max = r_fine/f · depth (about 2 cm here) a shift of 5 mm is still a panorama, one of 6 cm is not."""
    camera = CAMERAS[name]
    rng = np.random.default_rng(5)
    X = _scene(camera, rng)
    T_true = se3.exp(np.array([move_cm / 100, 0.0, 0.0, 0.0, np.radians(3.0), 0.0]))
    level = rng.integers(0, 4, len(X))
    xy = camera.project(se3.transform(T_true, X)) + rng.normal(scale=0.5, size=(len(X), 2)) * 2.0 ** level[:, None]
    t_max = cfg.tracker.fine_radius_px / camera.fx * 1.5
    T0 = se3.exp(np.array([0.0, 0.0, 0.0, 0.0, np.radians(2.5), 0.0]))
    choice = select_pose_model(
        camera,
        camera.kernel_params(),
        cfg.tracker,
        cfg.model_selection,
        T0,
        X,
        np.ones(len(X)),
        xy,
        level,
        True,
        np.zeros(3),
        t_max,
    )
    assert choice.model == expected
    err = se3.log(choice.T_cw @ se3.inv(T_true))
    assert np.degrees(np.linalg.norm(err[3:])) < 0.05
    if expected == PoseModel.GENERAL:
        assert 1e3 * np.linalg.norm(err[:3]) < 3.0


def test_rays_alone_give_a_rotation_about_the_keyframe_centre(cfg):
    """Only panorama rays in view: [R|t] cannot be estimated (§4.2), [R|0] is kept and the centre stays put."""
    camera = CAMERAS["pinhole"]
    rng = np.random.default_rng(8)
    X = _scene(camera, rng)
    T_true = se3.exp(np.array([0.0, 0.0, 0.0, 0.05, -0.2, 0.01]))
    level = rng.integers(0, 4, len(X))
    xy = camera.project(se3.transform(T_true, X)) + rng.normal(scale=0.5, size=(len(X), 2)) * 2.0 ** level[:, None]
    T0 = se3.exp(np.array([0.0, 0.0, 0.0, 0.04, -0.21, 0.0]))
    choice = select_pose_model(
        camera,
        camera.kernel_params(),
        cfg.tracker,
        cfg.model_selection,
        T0,
        X,
        np.zeros(len(X)),
        xy,
        level,
        True,
        np.zeros(3),
        0.02,
    )
    assert choice.model == PoseModel.ROTATION and math.isnan(choice.gric_general)
    assert np.degrees(np.linalg.norm(se3.log(choice.T_cw @ se3.inv(T_true))[3:])) < 0.05
    assert np.linalg.norm(se3.inv(choice.T_cw)[:3, 3]) < 1e-12


@pytest.mark.slow
def test_a_pure_rotation_into_unmapped_space_becomes_a_panorama(cfg, tmp_path):
    """desk_sweep: 10 cm sideways, then 180° of pure rotation into unmapped walls and back. With model selection
    every frame is right and the unmapped walls become panorama keyframes around an SfM keyframe's centre;
    PTAM alone (``model_selection.enabled: false``) loses them."""
    from tests.support import sequence

    d = sequence("desk_sweep")
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert s.correct_fraction >= 0.95 and s.glitches == 0
    snap = system.mapper.snapshot
    pano = np.array([k.panorama for k in snap.keyframes])
    assert pano.sum() >= 4  # 180° at ~30° a keyframe
    centres = snap.camera_centres
    sfm_to_pano = np.linalg.norm(centres[pano][:, None] - centres[~pano][None], axis=2).min(axis=1)
    assert sfm_to_pano.max() < 0.03  # every panorama keyframe at an SfM keyframe's centre (m)
    rays = snap.ray & ~snap.bad
    assert rays.sum() > 1000 and np.all(pano[snap.source_kf[rays]])
    shared = np.isin(snap.meas_kf, np.flatnonzero(pano)) & ~snap.ray[snap.meas_pt]
    assert shared.sum() > 50  # the panorama is connected to the SfM group by map points both measure
    groups = keyframe_groups(snap)
    assert [g.kind for g in groups].count(GroupKind.SFM) == 1
    panoramas = [g for g in groups if g.kind == GroupKind.PANORAMA]
    assert panoramas and all(not pano[g.keyframes[0]] and all(pano[list(g.keyframes[1:])]) for g in panoramas)
    save_map(tmp_path / "pano.npz", snap, system.camera, cfg.image.levels)
    loaded = load_map(tmp_path / "pano.npz", cfg.image).map.snapshot()
    assert np.array_equal(loaded.ray, snap.ray) and [k.panorama for k in loaded.keyframes] == list(pano)

    ptam = run_dataset(d, cfg.replace(**{"model_selection.enabled": False}), mode=RunMode.SYNC)
    p = score_trajectory(d / "groundtruth.txt", ptam.trajectory, criteria=criteria(cfg))
    assert p.correct_fraction < 0.6 and ptam.stats.lost_events >= 1
    assert not any(k.panorama for k in ptam.mapper.snapshot.keyframes)
