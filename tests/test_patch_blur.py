"""The blur a patch is expected to suffer (Agility eq. 10 for points) and the gate on it (``tracking.patch_blur``)."""

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.tracking.patch_blur import patch_blur, patch_smear, searchable, smear_axes
from tests.reference.patch_blur import patch_blur_ref
from tests.support.cameras import CAMERAS

MOVED = se3.exp(np.array([0.05, -0.02, 0.01, 0.1, -0.2, 0.05]))  # a pose and an exposure motion for the kernels
MOTION = np.array([0.01, -0.004, 0.006, 0.02, -0.03, 0.01])


def _points(rng, n=200):
    return np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(-0.4, 0.4, n), rng.uniform(0.8, 2.5, n)])


def test_blur_is_the_image_motion_during_the_exposure():
    """For a small motion γ the predicted blur equals the displacement of the projection between the poses
    T and exp(γ)·T, to first order: within 1 % on every lens model."""
    rng = np.random.default_rng(3)
    T = se3.exp(np.array([0.02, -0.01, 0.03, 0.01, 0.02, -0.01]))
    gamma = np.array([0.004, -0.002, 0.001, 0.002, -0.003, 0.001])
    for name, cam in CAMERAS.items():
        Xc = _points(rng)
        X = se3.transform(se3.inv(T), Xc)
        moved = cam.project(se3.transform(se3.exp(gamma) @ T, X)) - cam.project(Xc)
        blur = patch_blur(cam, T, X, np.ones(len(X)), gamma)
        np.testing.assert_allclose(blur, np.linalg.norm(moved, axis=1), rtol=0.01, err_msg=name)
        assert blur.min() > 0.5  # the motion is not negligible


def test_kernel_matches_the_numpy_reference():
    """Points and rays, on every lens model, to 1e-12 of the largest blur."""
    rng = np.random.default_rng(5)
    T, gamma = MOVED, MOTION
    for name, cam in CAMERAS.items():
        X = se3.transform(se3.inv(T), _points(rng, 300))
        w = (rng.random(300) < 0.8).astype(float)
        X[w == 0] /= np.linalg.norm(X[w == 0], axis=1, keepdims=True)
        ref = patch_blur_ref(cam, T, X, w, gamma)
        blur = patch_blur(cam, T, X, w, gamma)
        assert np.abs(blur - ref).max() < 1e-12 * ref.max(), name
        assert ref.min() > 0.1  # both kinds move


def test_a_ray_is_not_blurred_by_translation():
    rng = np.random.default_rng(4)
    cam = CAMERAS["pinhole"]
    T = np.eye(4)
    X = _points(rng)
    translation = np.array([0.05, 0.02, 0.0, 0.0, 0.0, 0.0])
    assert np.all(patch_blur(cam, T, X, np.zeros(len(X)), translation) == 0.0)
    assert np.all(patch_blur(cam, T, X, np.ones(len(X)), translation) > 5.0)
    rotation = np.array([0.0, 0.0, 0.0, 0.0, 0.02, 0.0])  # 1.15 degrees about y: ~fx * 0.02 px near the centre
    blur = patch_blur(cam, T, X / np.linalg.norm(X, axis=1, keepdims=True), np.zeros(len(X)), rotation)
    np.testing.assert_allclose(blur, patch_blur(cam, T, X, np.ones(len(X)), rotation), rtol=1e-12)


def test_the_gate_is_one_patch_width_at_the_search_level():
    blur = np.array([8.0, 8.5, 16.0, 17.0, 64.0, 65.0])
    level = np.array([0, 0, 1, 1, 3, 3])
    np.testing.assert_array_equal(searchable(blur, level, 8, 1.0), [True, False, True, False, True, False])
    assert searchable(blur, level, 8, np.inf).all()


def test_smear_axes_add_the_smear_variance_along_the_smear_only():
    """The information σ⁻²·(I − a·aᵀ) of ``smear_axes`` is the inverse of a covariance with σ² = 4^level across
    the smear and σ² + v·|s|² along it; no smear (or none known) leaves PTAM's σ⁻²·I."""
    smear = np.array([[12.0, 5.0], [0.0, -3.0], [0.0, 0.0], [np.inf, np.inf]])
    level = np.array([0, 2, 1, 0])
    v = 1.0 / 12.0
    a = smear_axes(smear, level, v)
    np.testing.assert_array_equal(a[2:], 0.0)
    for k in range(2):
        sigma2 = 4.0 ** level[k]
        cov = np.linalg.inv((np.eye(2) - np.outer(a[k], a[k])) / sigma2)
        along = smear[k] / np.linalg.norm(smear[k])
        across = np.array([-along[1], along[0]])
        assert along @ cov @ along == pytest.approx(sigma2 + v * smear[k] @ smear[k], rel=1e-12)
        assert across @ cov @ across == pytest.approx(sigma2, rel=1e-12)
        assert along @ cov @ across == pytest.approx(0.0, abs=1e-9)


def test_smear_is_the_blur_with_its_direction():
    rng = np.random.default_rng(6)
    T, gamma = MOVED, MOTION
    for name, cam in CAMERAS.items():
        X = se3.transform(se3.inv(T), _points(rng, 100))
        Xc = se3.transform(T, X)
        moved = cam.project(se3.transform(se3.exp(1e-4 * gamma) @ T, X)) - cam.project(Xc)
        smear = patch_smear(cam, T, X, np.ones(len(X)), gamma)
        np.testing.assert_allclose(1e-4 * smear, moved, rtol=1e-3, atol=1e-9, err_msg=name)
        np.testing.assert_array_equal(np.hypot(smear[:, 0], smear[:, 1]), patch_blur(cam, T, X, np.ones(len(X)), gamma))
