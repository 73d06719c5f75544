"""Model selection's kernels (Gauglitz et al. §4.2) against their numpy references."""

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.tracking.model_selection_kernels import em_noise, scaled_sq_errors
from tests.reference.model_selection import em_noise_ref, scaled_sq_errors_ref
from tests.support.cameras import CAMERAS


@pytest.mark.parametrize("name", list(CAMERAS))
def test_scaled_errors_match_the_reference(name):
    """Points and rays (w = 0), some behind the camera, on every lens model; errors scaled by each level."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(7)
    n = 2000
    X = np.concatenate([rng.uniform(-1.0, 1.0, (n, 2)), rng.uniform(-0.5, 4.0, (n, 1))], axis=1)
    Xw = np.where(rng.uniform(size=n) < 0.2, 0.0, 1.0)
    T = se3.exp(np.array([0.02, -0.01, 0.03, 0.01, -0.02, 0.005]))
    xy = rng.uniform(0, 640, (n, 2))
    level = rng.integers(0, 4, n).astype(np.float64)
    e2 = scaled_sq_errors(cam.kernel_params(), T, X, Xw, xy, level, 400.0)
    ref = scaled_sq_errors_ref(cam, T, X, Xw, xy, level, 400.0)
    assert (ref == 400.0).sum() > 50  # the sample has points behind the camera
    assert np.allclose(e2, ref, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("gamma", [0.3, 0.7, 0.95])
def test_em_matches_the_reference(gamma):
    rng = np.random.default_rng(11)
    n = 3000
    inlier = rng.uniform(size=n) < gamma
    e = np.where(inlier[:, None], rng.normal(scale=0.8, size=(n, 2)), rng.uniform(-10, 10, (n, 2)))
    e2 = (e**2).sum(axis=1)
    got = em_noise(e2, 400.0, 0.05, 0.99, 0.01, 10)
    assert np.allclose(got, em_noise_ref(e2, 400.0, 0.05, 0.99, 0.01, 10), rtol=1e-10)
