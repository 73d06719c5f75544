"""Two-view initialisation geometry and the dominant plane (PTAM §6.1) on exact synthetic matches."""

import dataclasses

import numpy as np
import pytest

from ptam.camera import FovCamera
from ptam.config import load_config
from ptam.geometry import se3, so3
from ptam.mapping.dominant_plane import fit_dominant_plane, plane_aligner
from ptam.mapping.two_view import AmbiguousPair, InitFailure, estimate_two_view

CAM = FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9)
CFG = load_config().init


def _scene(rng, n=600):
    # A wall at z = 3 with 20% of points on a second plane, seen from the origin.
    uv = rng.uniform([20, 20], [620, 460], size=(n, 2))
    rays = CAM.unproject(uv)
    depth = np.where(rng.random(n) < 0.8, 3.0, 2.2 + 0.3 * rays[:, 0])
    return np.concatenate([rays, np.ones((n, 1))], axis=1) * depth[:, None]


def test_relative_pose_and_points_from_integer_trails():
    rng = np.random.default_rng(0)
    X = _scene(rng)
    T = se3.exp(np.array([0.3, 0.02, 0.01, 0.0, 0.03, 0.01]))  # 30 cm sideways at 3 m: ~6 deg parallax
    xy0 = np.round(CAM.project(X))
    xy1 = np.round(CAM.project(se3.transform(T, X)))
    xy1[:30] += rng.uniform(-40, 40, (30, 2))  # gross mismatches
    res = estimate_two_view(CAM, xy0, xy1, CFG)
    t_true = T[:3, 3] / np.linalg.norm(T[:3, 3])
    assert np.degrees(np.arccos(np.clip(res.T_c1c0[:3, 3] @ t_true, -1, 1))) < 1.0
    assert np.degrees(np.linalg.norm(so3.log(res.T_c1c0[:3, :3] @ T[:3, :3].T))) < 0.1
    assert res.inliers[:30].sum() <= 2 and res.inliers[30:].mean() > 0.9
    scale = np.linalg.norm(T[:3, 3])
    err = np.linalg.norm(res.X0 * scale - X[res.inliers], axis=1)
    assert np.median(err) < 0.03  # 1 % of depth from half-pixel quantisation


def test_rotation_only_is_refused():
    rng = np.random.default_rng(1)
    X = _scene(rng)
    T = se3.exp(np.array([0.0, 0.0, 0.0, 0.0, 0.12, 0.0]))
    xy0 = CAM.project(X)
    xy1 = CAM.project(se3.transform(T, X))
    inside = CAM.in_image(xy1)
    with pytest.raises(InitFailure, match="too little parallax|no translation"):
        estimate_two_view(CAM, xy0[inside], xy1[inside], CFG)


FLOOR_MOVE = se3.exp(np.array([-0.17, -0.035, -0.18, -0.019, -0.005, 0.0035]))


def _floor_pair(seed: int, off_floor: int = 0):
    """Integer trails of a floor 1.04 m below a camera looking along it, which moves 25 cm over it (desk_corner
    filmed at 10 fps), and of ``off_floor`` points 1.5-2.5 m ahead above the floor."""
    rng = np.random.default_rng(seed)
    uv = rng.uniform([20, 300], [620, 460], size=(150, 2))
    rays = np.concatenate([CAM.unproject(uv), np.ones((150, 1))], axis=1)
    X = rays * (1.04 / rays[:, 1])[:, None]
    up = np.concatenate([CAM.unproject(rng.uniform([20, 200], [620, 300], (off_floor, 2))), np.ones((off_floor, 1))], 1)
    X = np.concatenate([X, up * rng.uniform(1.5, 2.5, (off_floor, 1))])
    Xc = se3.transform(FLOOR_MOVE, X)
    xy0, xy1 = CAM.project(X), CAM.project(Xc)
    seen = (Xc[:, 2] > 0.1) & CAM.in_image(xy1)
    return np.round(xy0[seen]), np.round(xy1[seen])


def _turn_error_deg(res) -> float:
    return float(np.degrees(np.linalg.norm(so3.log(res.T_c1c0[:3, :3] @ FLOOR_MOVE[:3, :3].T))))


def test_an_ambiguous_homography_is_no_initialisation():
    """Over the floor alone both decompositions of the homography put every point in front of both cameras
    (Faugeras and Lustman's two-way ambiguity), and every point fits both. PTAM's tie-break, the Sampson error under
    each one's E, is then decided by the trails' rounding: on 30 pairs it returns a map turned 13.6-14° on 10 (the
    rest within 0.1°). Here each of them waits for a later pair (``AmbiguousPair``). With 12 points off the floor,
    which fit the right decomposition only, the pair is taken, and right."""
    ptam = dataclasses.replace(CFG, homography_resolve_ambiguity=True)
    errors = []
    for seed in range(30):
        xy0, xy1 = _floor_pair(seed)
        with pytest.raises(AmbiguousPair, match="decompositions fit equally"):
            estimate_two_view(CAM, xy0, xy1, CFG)
        errors.append(_turn_error_deg(estimate_two_view(CAM, xy0, xy1, ptam)))
    errors = np.array(errors)
    assert np.sum(errors > 13.0) == 10 and np.all((errors < 0.1) | (errors > 13.0))
    taken = [estimate_two_view(CAM, *_floor_pair(seed, off_floor=12), CFG) for seed in range(1, 11)]
    assert sum(res.model == "H" for res in taken) == 9  # GRIC takes E for one
    assert max(_turn_error_deg(res) for res in taken) < 0.1


def test_too_few_trails():
    with pytest.raises(InitFailure, match="too few trails"):
        estimate_two_view(CAM, np.zeros((5, 2)), np.zeros((5, 2)), CFG)


def test_dominant_plane_and_aligner():
    rng = np.random.default_rng(2)
    n_true = so3.exp(np.array([0.3, -0.2, 0.1])) @ np.array([0.0, 0.0, 1.0])
    basis = np.linalg.svd(n_true[None])[2][1:]
    P = rng.uniform(-1, 1, (400, 2)) @ basis + np.array([0.1, 0.2, 1.0]) + rng.normal(0, 0.002, (400, 1)) * n_true
    clutter = rng.uniform(-1, 1, (150, 3)) + [0, 0, 1.5]
    plane = fit_dominant_plane(np.concatenate([P, clutter]), CFG.plane_inlier_distance, CFG.plane_ransac_iterations, 0)
    assert abs(abs(plane.normal @ n_true) - 1) < 1e-4
    assert plane.inliers[:400].mean() > 0.99 and plane.inliers[400:].mean() < 0.2
    cam = np.array([0.0, 0.0, -2.0])
    T = plane_aligner(plane, cam)
    assert np.max(np.abs(se3.transform(T, P)[:, 2])) < 0.01
    assert se3.transform(T, cam[None])[0, 2] > 0
