"""Agility §4.3's aperture test of new-edgelet candidates against other keyframes (``edgelet_aperture_kernels``)."""

import numpy as np
import pytest

from ptam.geometry import se3
from ptam.mapping.edgelet_aperture_kernels import aperture_free, aperture_problem
from tests.reference.edgelet_aperture import aperture_free_ref, aperture_problem_ref
from tests.support.cameras import CAMERAS


def test_a_baseline_along_the_line_is_the_aperture_problem():
    """A line along x 1 m ahead: its planes through the origin and a centre C meet at atan(C_y / 1 m) whatever C_x,
    so a centre moved along the line (0°) or 5 cm across it (2.9°) is under the 5° gate, one 10 cm (5.7°) or 15 cm
    (8.5°) across it over the gate."""
    X = np.array([[0.0, 0.0, 1.0]])
    D = np.array([[1.0, 0.0, 0.0]])
    C = np.array([[0.1, 0.0, 0.0], [0.1, 0.05, 0.0], [0.0, 0.1, 0.0], [0.1, 0.15, 0.0]])
    got = aperture_problem(X, D, C, np.sin(np.deg2rad(5.0)))[:, 0]
    assert got.tolist() == [True, True, False, False]


@pytest.mark.parametrize("name", list(CAMERAS))
def test_aperture_kernels_match_reference(name):
    """Random candidates and keyframes around them, some candidates behind a keyframe or outside its image, some
    lines along a baseline: the same (K, N) tables as numpy."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(2)
    n, k = 400, 12
    X = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)), rng.uniform(0.5, 2.0, n)])
    D = rng.normal(size=(n, 3))
    D /= np.linalg.norm(D, axis=1, keepdims=True)
    T_jk = np.stack([se3.exp(np.concatenate([rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.6, 0.6, 3)])) for _ in range(k)])
    C = np.stack([se3.inv(T)[:3, 3] for T in T_jk])  # the keyframes' centres in k's frame
    D[:40] = C[0] / np.linalg.norm(C[0])  # lines along keyframe 0's baseline
    min_deg = 5.0
    problem = aperture_problem(X, D, C, np.sin(np.deg2rad(min_deg)))
    assert np.array_equal(problem, aperture_problem_ref(X, D, C, min_deg)) and problem[0, :40].all()
    free = aperture_free(cam.kernel_params(), T_jk, C, X, D, np.sin(np.deg2rad(min_deg)), 8.0, cam.width, cam.height)
    ref = aperture_free_ref(cam, T_jk, C, X, D, min_deg, 8.0)
    assert np.array_equal(free, ref) and 0.2 < free.mean() < 0.9, free.mean()
