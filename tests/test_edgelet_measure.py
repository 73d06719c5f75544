"""Agility §4.2: measuring edgelets in a keyframe (five perpendicular searches, line fit, residual gate)."""

import cv2
import numpy as np
import pytest

from ptam.edgelet.edgelet import perp
from ptam.edgelet.edgelet_measure import measure_in_keyframe
from ptam.edgelet.edgelet_measure_kernels import measure_edgelets
from ptam.errors import InputError
from tests.reference.edgelet_measure import measure_edgelets_ref
from tests.reference.edgelet_scenes import edge_image


@pytest.fixture(scope="module")
def ecfg(cfg):
    return cfg.edgelets


def _texture(rng, h, w):
    img = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 2.0)
    img = (img - img.min()) / (img.max() - img.min()) * 255.0
    return img.astype(np.uint8)


def test_kernel_matches_reference_on_random_data():
    rng = np.random.default_rng(0)
    img = _texture(rng, 120, 160)
    n = 600
    c = rng.uniform([-5, -5], [165, 125], (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.5, 3.0, (n, 1))
    nrm = perp(d) * rng.choice([-1.0, 1.0], (n, 1)) + rng.normal(0, 0.2, (n, 2))
    args = (18.0, 5, 5, 4.0, 5.0, 3, 0.6)
    got = measure_edgelets(img, c, d, nrm, *args)
    ref = measure_edgelets_ref(img, c, d, nrm, *args)
    a, b, rms, n_found, points, found, ok = got
    assert np.array_equal(found, ref[5]) and np.array_equal(n_found, ref[3]) and np.array_equal(ok, ref[6])
    assert 50 < ok.sum() < n and found.sum() > n
    assert np.allclose(points, ref[4], atol=1e-9)
    fit = n_found >= 2
    assert np.allclose(a[fit], ref[0][fit], atol=1e-7) and np.allclose(b[fit], ref[1][fit], atol=1e-7)
    assert np.allclose(rms[fit], ref[2][fit], atol=1e-7)


def _line_truth(rng):
    ang = rng.uniform(0, 2 * np.pi)
    n = np.array([np.cos(ang), np.sin(ang)])  # dark -> light
    p0 = np.array([80.0, 60.0]) + rng.uniform(-1, 1, 2)
    return n, p0, np.array([n[1], -n[0]])  # perp(d) = n


def test_measures_straight_edges_to_a_tenth_of_a_pixel(ecfg):
    rng = np.random.default_rng(1)
    dist, ang = [], []
    for k in range(40):
        n, p0, d = _line_truth(rng)
        img = edge_image(160, 120, p0, n, 50, 170, noise=1.0, seed=k)
        turn = np.deg2rad(rng.uniform(-5, 5))
        dp = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]]) @ d
        c = p0 + rng.uniform(-3, 3) * n + rng.uniform(-4, 4) * d
        m = measure_in_keyframe(img, c[None], dp[None], perp(dp)[None], ecfg)
        assert m.ok[0] and m.n_found[0] == 5
        dist.append(abs((m.a[0] - p0) @ n))
        ang.append(np.degrees(np.arccos(min(1.0, m.b[0] @ d))))  # b oriented like d: the polarity is kept
        assert abs((c - m.a[0]) @ m.b[0]) < 1e-9  # a is the foot of the predicted centre
    # Area-sampled, unblurred edges (the hardest case: aliased); measured max 0.066 px and 0.49°.
    assert max(dist) < 0.08 and max(ang) < 0.6, (max(dist), max(ang))


def test_wrong_polarity_far_edges_and_curves_are_rejected(ecfg):
    n, p0, d = np.array([1.0, 0.0]), np.array([80.2, 60.0]), np.array([0.0, -1.0])
    img = edge_image(160, 120, p0, n, 50, 170)
    c = p0[None]
    assert measure_in_keyframe(img, c, d[None], n[None], ecfg).ok[0]
    assert not measure_in_keyframe(img, c, -d[None], -n[None], ecfg).ok[0]  # light -> dark: wrong polarity
    far = c + 6.5 * n  # beyond the ±5 px search
    assert not measure_in_keyframe(img, far, d[None], n[None], ecfg).ok[0]
    # A disc of radius 12 px: its rim is a strongly curved edge, rejected by the residual gate.
    yy, xx = np.mgrid[0:120, 0:160]
    disc = np.where(np.hypot(xx - 80, yy - 60) < 12, 170, 50).astype(np.uint8)
    disc = cv2.GaussianBlur(disc, (0, 0), 0.7)
    m = measure_in_keyframe(disc, np.array([[92.0, 60.0]]), np.array([[0.0, 1.0]]), np.array([[-1.0, 0.0]]), ecfg)
    assert m.n_found[0] == 5 and m.rms[0] > ecfg.measure_max_rms_px and not m.ok[0]


def test_bad_input_is_refused(ecfg):
    with pytest.raises(InputError):
        measure_in_keyframe(np.zeros((10, 10, 3), np.uint8), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), ecfg)
    with pytest.raises(InputError):
        measure_in_keyframe(np.zeros((10, 10), np.uint8), np.zeros((2, 2)), np.zeros((1, 2)), np.zeros((2, 2)), ecfg)
