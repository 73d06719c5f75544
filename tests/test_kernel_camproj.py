"""The numba projection kernels against the numpy camera models."""

import numpy as np
import pytest

from ptam.camera.camproj_kernels import project_points, project_points_jac, undistort_points
from tests.reference.camera import undistort_ref
from tests.support.cameras import CAMERAS


@pytest.mark.parametrize("name", list(CAMERAS))
def test_kernel_matches_numpy_model(name):
    cam = CAMERAS[name]
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.uniform(-3.0, 3.0, (500, 2)), rng.uniform(-1.0, 5.0, (500, 1))], axis=1)
    X[0] = [0.0, 0.0, 2.0]
    uv, J, valid = project_points_jac(cam.kernel_params(), X)
    uv2, valid2 = project_points(cam.kernel_params(), X)
    ref_valid = cam.valid(X)
    assert np.array_equal(valid, ref_valid) and np.array_equal(valid2, ref_valid)
    front = X[:, 2] > 0
    # Relative tolerance: radtan's polynomial sends far off-axis points to pixel values of 1e6 and more.
    assert np.allclose(uv[front], cam.project(X[front]), rtol=1e-12, atol=1e-9)
    assert np.allclose(uv2[front], uv[front], rtol=1e-12, atol=1e-9)
    assert np.allclose(J[front], cam.project_jacobian(X[front]), rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_undistort_kernel_matches_numpy_and_inverts_distort(name):
    """Over the whole image (and 20 % beyond it): the kernel (FOV in closed form, the others by Gauss–Newton) agrees
    with the vectorised numpy Gauss–Newton and with the model's own inverse to 1e-12, and distorting its result
    gives back the input to 1e-12 (normalised units, ~1e-9 px)."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(5)
    uv = rng.uniform([-0.2 * cam.width, -0.2 * cam.height], [1.2 * cam.width, 1.2 * cam.height], (2000, 2))
    xy_d = np.column_stack([(uv[:, 0] - cam.cx) / cam.fx, (uv[:, 1] - cam.cy) / cam.fy])
    xy = undistort_points(cam.kernel_params(), np.ascontiguousarray(xy_d), 30, 1e-14)
    assert np.allclose(xy, undistort_ref(cam, xy_d), rtol=0.0, atol=1e-12)
    assert np.allclose(xy, cam.undistort(xy_d), rtol=0.0, atol=1e-12)
    assert np.abs(cam.distort(xy) - xy_d).max() < 1e-12
