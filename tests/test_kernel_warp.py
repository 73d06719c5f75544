"""The affine-warp / search-level kernel against its numpy reference, and A against finite differences."""

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.patch.warp_kernels import RULE_CLOSEST, RULE_PTAM_CODE, warp_matrices
from tests.reference.warp import warp_matrices_ref
from tests.support.cameras import CAMERAS


def _points(rng, n):
    X = np.concatenate([rng.uniform(-1.0, 1.0, (n, 2)), rng.uniform(1.0, 4.0, (n, 1))], axis=1)
    scale = 10.0 ** rng.uniform(-3.5, -1.0, (n, 1))  # pixel footprints from tiny to huge -> every level
    return X, rng.normal(size=(n, 3)) * scale, rng.normal(size=(n, 3)) * scale


@pytest.mark.parametrize("name", list(CAMERAS))
@pytest.mark.parametrize("rule", [RULE_CLOSEST, RULE_PTAM_CODE])
def test_warp_kernel_matches_reference(name, rule):
    cam = CAMERAS[name]
    rng = np.random.default_rng(11)
    T = se3.exp(np.array([0.05, 0.02, -0.1, 0.1, -0.05, 0.2]))
    Xw, right, down = _points(rng, 2000)
    Xc = se3.transform(T, Xw)
    A, det, level = warp_matrices(cam.kernel_params(), T, Xc, right, down, 4, 0.25, 3.0, rule)
    A_r, det_r, level_r = warp_matrices_ref(cam, T, Xc, right, down, 4, 0.25, 3.0, rule)
    assert np.allclose(A, A_r, rtol=1e-10, atol=1e-12)
    assert np.allclose(det, det_r, rtol=1e-9, atol=1e-15)
    assert np.array_equal(level, level_r)
    for L in range(-1, 4):  # every level, and rejections, occur in the sample
        assert (level == L).sum() > 20
    ok = level >= 0
    d = det[ok] / 4.0 ** level[ok]
    assert d.min() >= 0.25 and d.max() <= 3.0
    if rule == RULE_CLOSEST:
        inner = ok & (level > 0) & (level < 3)
        d = det[inner] / 4.0 ** level[inner]
        assert d.min() >= 0.5 - 1e-12 and d.max() <= 2.0 + 1e-12


def test_warp_columns_are_projected_pixel_displacements():
    cam = CAMERAS["fov"]
    rng = np.random.default_rng(2)
    T = se3.exp(np.array([0.05, 0.02, -0.1, 0.1, -0.05, 0.2]))
    Xw = np.array([[0.3, -0.2, 2.0], [-0.5, 0.4, 3.0]])
    right, down = rng.normal(size=(2, 3)) * 1e-3, rng.normal(size=(2, 3)) * 1e-3
    A, _, _ = warp_matrices(cam.kernel_params(), T, se3.transform(T, Xw), right, down, 4, 0.25, 3.0, RULE_CLOSEST)
    eps = 1e-4
    for k in range(2):
        for col, d in enumerate((right[k], down[k])):
            fd = (
                cam.project(se3.transform(T, Xw[k] + eps * d)[None])[0]
                - cam.project(se3.transform(T, Xw[k] - eps * d)[None])[0]
            ) / (2 * eps)
            assert np.allclose(A[k, :, col], fd, rtol=1e-6)
