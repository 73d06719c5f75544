"""AR scene logic: eyes that follow the camera, the aim-and-shoot game (PTAM §7.5), the refreshed plane (§6.1)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from ptam.ar.ar_plane import ArPlane
from ptam.ar.eyes import Eyes
from ptam.ar.game import TargetGame
from ptam.ar.scenes import make_scene
from ptam.config import load_config
from ptam.errors import InputError
from ptam.geometry import se3, so3


@pytest.fixture(scope="module")
def cfg():
    return load_config()


def _looking_at(position, target):
    """T_pc (camera→plane) of a camera at ``position`` whose optical axis passes through ``target``."""
    z = np.asarray(target, float) - position
    z /= np.linalg.norm(z)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return se3.from_Rt(np.stack([x, np.cross(z, x), z], axis=1), position)


def test_eyes_turn_to_the_camera_at_the_limited_rate(cfg):
    eyes = Eyes(cfg.ar)
    camera = np.array([0.6, -0.3, 0.5])
    rate = cfg.ar.eye_turn_rate
    to_cam = camera - eyes.positions
    to_cam /= np.linalg.norm(to_cam, axis=1, keepdims=True)
    start = np.degrees(np.arccos(np.clip((eyes.gaze * to_cam).sum(axis=1), -1, 1)))
    frames = int(math.ceil(np.radians(start.max()) / rate)) + 2
    prev = eyes.gaze
    for _ in range(frames):
        eyes.look_at(camera)
        step = np.arccos(np.clip((eyes.gaze * prev).sum(axis=1), -1, 1))
        assert step.max() <= rate + 1e-9
        prev = eyes.gaze
    err = np.degrees(np.arccos(np.clip((eyes.gaze * to_cam).sum(axis=1), -1, 1)))
    print(f"eyes {start.round(1)} deg off the camera turn onto it in {frames} frames: {err.max():.2e} deg left")
    assert start.min() > 30 and err.max() < 1e-4


def test_dwelling_on_a_target_hits_it_after_the_dwell_frames(cfg):
    game = TargetGame(cfg.ar, 0.25)
    k = 1
    target = game.centres[k]
    T_pc = _looking_at(target + [0.1, -0.2, 0.6], target)
    for frame in range(1, cfg.ar.dwell_frames + 1):
        game.step(T_pc, 0.0)  # dt = 0: the targets stand still
        if frame < cfg.ar.dwell_frames:
            assert game.aimed == k and game.hits == 0
            assert game.dwell_fraction == pytest.approx(frame / cfg.ar.dwell_frames)
    assert game.hits == 1 and len(game.bursts) == 1
    assert np.allclose(game.bursts[0, :2], target[:2])
    assert np.abs(game.pos[k]).max() == pytest.approx(cfg.ar.arena_half_size - cfg.ar.target_radius)  # restarts


def test_the_optical_axis_meets_the_plane_as_the_cross_hair_and_fire_hits(cfg):
    game = TargetGame(cfg.ar, 0.25)
    aim = np.array([0.3, -0.2, 0.0])
    game.step(_looking_at(np.array([0.1, 0.3, 0.7]), aim), 0.0)
    assert np.allclose(game.aim, aim[:2]) and game.aimed == -1
    target = game.centres[2]
    game.fire()
    game.step(_looking_at(target + [0.0, 0.2, 0.5], target), 0.0)
    assert game.hits == 1  # a key press hits at once
    game.fire()
    game.step(_looking_at(np.array([0.1, 0.3, 0.7]), aim), 0.0)
    assert game.hits == 1  # firing at the empty plane misses


def test_targets_roll_in_on_the_eyes_and_bite(cfg):
    game = TargetGame(cfg.ar, 0.25)
    T_pc = _looking_at(np.array([2.0, 2.0, 1.0]), np.array([2.0, 2.0, 0.0]))  # aiming far outside the arena
    d0 = np.linalg.norm(game.pos, axis=1)
    for _ in range(10):
        game.step(T_pc, 1.0 / 30)
    d1 = np.linalg.norm(game.pos, axis=1)
    speed = (d0 - d1) * 30 / 10
    print(f"approach speeds {speed.round(3)} (target_speed {cfg.ar.target_speed})")
    assert np.all(speed > math.cos(math.radians(cfg.ar.target_wander_deg)) * cfg.ar.target_speed - 1e-9)
    for _ in range(int(2 * cfg.ar.arena_half_size / cfg.ar.target_speed * 30)):
        game.step(T_pc, 1.0 / 30)
    assert game.bites >= cfg.ar.target_count and game.hits == 0


_FIRST_KEYFRAME = object()


def _snapshot(X, T_cw, first=_FIRST_KEYFRAME):
    return SimpleNamespace(
        X=X,
        good_point_indices=np.arange(len(X)),
        ray=np.zeros(len(X), bool),  # no panorama features: every point has a depth
        n_points=len(X),
        n_keyframes=1,
        kf_T_cw=T_cw[None],
        keyframes=(first,),
    )


def test_plane_is_refitted_when_the_map_grows_and_content_stays_anchored(cfg):
    rng = np.random.default_rng(0)
    plane = ArPlane(cfg.init, cfg.ar.plane_refresh_growth)
    # The initial map: points on z = 0 (as initialisation leaves them).
    X0 = np.concatenate([rng.uniform(-0.5, 0.5, (300, 2)), np.zeros((300, 1))], axis=1)
    T_cw = se3.inv(_looking_at(np.array([0.0, 0.0, 1.0]), np.zeros(3)))
    assert not plane.maybe_refresh(_snapshot(X0, T_cw))
    # The grown map: bundle adjustment tilted the true surface by 3 degrees and lifted it by 2 cm.
    tilt = se3.from_Rt(so3.exp(np.array([math.radians(3.0), 0.0, 0.0])), [0.0, 0.0, 0.02])
    X1 = np.concatenate([rng.uniform(-0.8, 0.8, (700, 2)), np.zeros((700, 1))], axis=1) @ tilt[:3, :3].T + tilt[:3, 3]
    outliers = rng.uniform([-0.5, -0.5, 0.2], [0.5, 0.5, 0.5], (100, 3))
    assert not plane.maybe_refresh(_snapshot(X1[:550], T_cw))  # grown less than 2x
    assert plane.maybe_refresh(_snapshot(np.concatenate([X1, outliers]), T_cw))
    Xp = X1 @ plane.T_pw[:3, :3].T + plane.T_pw[:3, 3]
    T_wp = se3.inv(plane.T_pw)
    print(f"refit: surface |z| max {np.abs(Xp[:, 2]).max():.2e}, origin moved {T_wp[:3, 3].round(4)}")
    assert np.abs(Xp[:, 2]).max() < 1e-9
    # The old origin dropped onto the new plane: moved along the new normal only, by the plane's offset there.
    assert T_wp[2, 2] > 0.99 and np.linalg.norm(np.cross(T_wp[:3, 3], T_wp[:3, 2])) < 1e-9
    assert np.linalg.norm(T_wp[:3, 3]) == pytest.approx(0.02 * math.cos(math.radians(3.0)), abs=1e-6)
    assert np.dot(T_wp[:3, 0], [1.0, 0.0, 0.0]) > 0.99 and plane.refits == 1  # the x axis kept
    # A reset map (a new first keyframe) is aligned to z = 0 again by its initialisation.
    assert not plane.maybe_refresh(_snapshot(X0, T_cw, first=object()))
    assert np.array_equal(plane.T_pw, np.eye(4))


def test_unknown_scene_is_a_clear_error(cfg):
    with pytest.raises(InputError, match="unknown AR scene 'teapot'"):
        make_scene("teapot", cfg.ar)


def test_panorama_rays_do_not_move_the_plane(cfg):
    """Rays (Gauglitz et al. §3.2) sit at a guessed depth: a panorama of a wall that outnumbers the desk's points
    must not become the dominant plane."""
    rng = np.random.default_rng(1)
    plane = ArPlane(cfg.init, cfg.ar.plane_refresh_growth)
    X0 = np.concatenate([rng.uniform(-0.5, 0.5, (300, 2)), np.zeros((300, 1))], axis=1)
    T_cw = se3.inv(_looking_at(np.array([0.0, 0.0, 1.0]), np.zeros(3)))
    assert not plane.maybe_refresh(_snapshot(X0, T_cw))
    desk = np.concatenate([rng.uniform(-0.8, 0.8, (400, 2)), np.zeros((400, 1))], axis=1)
    wall = np.concatenate([rng.uniform(-1, 1, (900, 1)), np.full((900, 1), 1.0), rng.uniform(0, 1, (900, 1))], axis=1)
    snap = _snapshot(np.concatenate([desk, wall]), T_cw)
    snap.ray = np.arange(len(snap.X)) >= len(desk)
    assert plane.maybe_refresh(snap)
    Xp = desk @ plane.T_pw[:3, :3].T + plane.T_pw[:3, 3]
    assert np.abs(Xp[:, 2]).max() < 1e-9  # the desk, not the panorama's wall
