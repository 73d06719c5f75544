"""The SE(2) (+ offset) ESM kernel against its numpy reference, and on exactly known image motions."""

import numpy as np
import pytest

from ptam.image.esm_kernels import esm_se2
from ptam.image.sbi import gradient
from tests.reference.esm import esm_se2_ref

H, W = 30, 40
CX, CY = 0.5 * (W - 1), 0.5 * (H - 1)


def _blobs(rng, n=25):
    """A smooth random image as a function: a sum of Gaussian blobs, so warps of it are exact."""
    centres = rng.uniform([-5, -5], [W + 5, H + 5], (n, 2))
    sigma = rng.uniform(2.0, 5.0, n)
    amp = rng.uniform(-60, 60, n)

    def f(x, y):
        d2 = (x[..., None] - centres[:, 0]) ** 2 + (y[..., None] - centres[:, 1]) ** 2
        return (amp * np.exp(-0.5 * d2 / sigma**2)).sum(-1)

    return f


def _pair(rng, params):
    """Template T(x) and image I with I(c + R(θ)(x − c) + t) = T(x) − o, for params (t_x, t_y, θ, o)."""
    f = _blobs(rng)
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    T = f(xs, ys)
    tx, ty, th, o = params
    c, s = np.cos(th), np.sin(th)
    dx, dy = xs - CX - tx, ys - CY - ty  # inverse warp of the image's pixels into the template
    I = f(CX + c * dx + s * dy, CY - s * dx + c * dy) - o
    return I.astype(np.float32), T.astype(np.float32)


@pytest.mark.parametrize("robust", [False, True])
@pytest.mark.parametrize("with_offset", [False, True])
def test_kernel_matches_reference(with_offset, robust):
    rng = np.random.default_rng(1)
    for k in range(6):
        I, T = _pair(rng, rng.uniform([-3, -3, -0.1, -10], [3, 3, 0.1, 10]))
        p0 = rng.uniform([-1, -1, -0.02, -2], [1, 1, 0.02, 2]) if k % 2 else np.zeros(4)
        p, score, its = esm_se2(I, T, gradient(T), p0, 10, with_offset, robust)
        pr, score_r, its_r = esm_se2_ref(I, T, gradient(T), p0, 10, with_offset, robust)
        assert its == its_r == 10
        np.testing.assert_allclose(p, pr, rtol=0, atol=1e-6)
        assert score == pytest.approx(score_r, rel=1e-6, abs=1e-6)


def test_recovers_a_known_motion_and_offset():
    rng = np.random.default_rng(2)
    for truth in ([2.5, -1.5, np.radians(4.0), 12.0], [-4.0, 2.0, np.radians(-6.0), -8.0]):
        I, T = _pair(rng, truth)
        p, score, _ = esm_se2(I, T, gradient(T), np.zeros(4), 10, True, False)
        err = np.abs(p - truth)
        print(f"truth {np.round(truth, 3)} -> {np.round(p, 3)}, final SSD {score:.2f}")
        assert err[0] < 0.02 and err[1] < 0.02 and np.degrees(err[2]) < 0.05 and err[3] < 0.1


def test_three_parameters_without_the_offset():
    """Agility §6: SE(2) only; the offset stays zero and the motion is found as well."""
    rng = np.random.default_rng(3)
    truth = [1.5, 1.0, np.radians(3.0), 0.0]
    I, T = _pair(rng, truth)
    p, _, _ = esm_se2(I, T, gradient(T), np.zeros(4), 10, False, False)
    assert np.abs(p[:2] - truth[:2]).max() < 0.02 and abs(np.degrees(p[2] - truth[2])) < 0.05 and p[3] == 0.0


def test_a_textureless_image_stops_the_minimisation():
    T = np.zeros((H, W), np.float32)
    p, score, its = esm_se2(T, T, gradient(T), np.zeros(4), 10, True, False)
    pr, _, its_r = esm_se2_ref(T, T, gradient(T), np.zeros(4), 10, True, False)
    assert its == its_r == 0 and np.all(p == 0) and np.all(pr == 0) and score == 0.0


def test_robust_alignment_ignores_clutter_that_moves_on_its_own():
    """Agility §9.3: the small-blurry-image alignment "is susceptible to moving clutter in the image, such as a hand
    moved rapidly before the camera". A smooth bright shape (a seventh of the image) sits over the image of a known
    camera motion where the template has none; least squares follows it, the Tukey-weighted alignment does not."""
    rng = np.random.default_rng(4)
    truth = np.array([1.0, -0.5, np.radians(1.0), 0.0])
    errors = {}
    for _ in range(5):
        I, T = _pair(rng, truth)
        ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
        cx = rng.uniform(0.3, 0.7) * W
        hand = np.exp(-0.5 * (((xs - cx) / 4.0) ** 4 + ((ys - CY) / 9.0) ** 4))  # a flat-topped blob, 0..1
        I = (I * (1 - hand) + (I.mean() + 80.0) * hand).astype(np.float32)
        for robust in (False, True):
            p, _, _ = esm_se2(I, T, gradient(T), np.zeros(4), 10, False, robust)
            errors.setdefault(robust, []).append(np.hypot(*(p[:2] - truth[:2])))
    plain, robust = np.max(errors[False]), np.max(errors[True])
    print(f"translation error, worst of 5: least squares {plain:.2f} px, Tukey-weighted {robust:.3f} px")
    assert robust < 0.1 and plain > 5 * robust
