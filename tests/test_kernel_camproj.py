"""The numba projection kernels against the numpy camera models."""

import numpy as np
import pytest

from ptam.camera.camproj_kernels import project_points, project_points_jac
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
