"""The map-point projection/visibility kernel against its numpy reference."""

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.tracking.projection_kernels import project_map_points
from tests.reference.projection import project_map_points_ref
from tests.support.cameras import CAMERAS


@pytest.mark.parametrize("name", list(CAMERAS))
def test_projection_kernel_matches_reference(name):
    cam = CAMERAS[name]
    rng = np.random.default_rng(5)
    X = np.concatenate([rng.uniform(-4.0, 4.0, (3000, 2)), rng.uniform(-1.0, 6.0, (3000, 1))], axis=1)
    T = se3.exp(np.array([0.1, -0.2, 0.3, 0.05, -0.1, 0.02]))
    idx = rng.permutation(len(X))[:2000]
    for margin, factor in ((0.0, 1.5), (12.0, 1.0)):
        Xc, uv, vis = project_map_points(cam.kernel_params(), T, X, idx, cam.width, cam.height, margin, factor)
        Xc_r, uv_r, vis_r = project_map_points_ref(cam, T, X, idx, margin, factor)
        assert np.allclose(Xc, Xc_r, atol=1e-12)
        assert np.array_equal(vis, vis_r)
        assert 200 < vis.sum() < len(idx)  # the sample covers both visible and invisible points
        assert np.allclose(uv[vis], uv_r[vis], atol=1e-9)
