import cv2
import numpy as np

from ptam.config import default_config
from ptam.image.fast import fast_corners
from ptam.image.shi_tomasi import candidates, shi_tomasi
from ptam.image.shi_tomasi_kernels import shi_tomasi_scores
from tests.reference.shi_tomasi import shi_tomasi_ref


def test_kernel_matches_reference_on_random_inputs():
    rng = np.random.default_rng(0)
    for half in (1, 3, 5):
        img = rng.integers(0, 256, (50, 70)).astype(np.uint8)
        xy = np.stack([rng.integers(-2, 72, 400), rng.integers(-2, 52, 400)], axis=1).astype(np.int32)
        k = shi_tomasi_scores(img, xy, half)
        r = shi_tomasi_ref(img, xy, half)
        assert np.array_equal(np.isinf(k), np.isinf(r)) and np.isinf(k).sum() > 0
        f = np.isfinite(r)
        assert np.allclose(k[f], r[f], rtol=1e-12, atol=1e-9)


def test_score_is_smallest_eigenvalue_with_ptam_scaling():
    # A ramp I = 2x + 3y: dx = 4, dy = 6 everywhere, a rank-one tensor -> smaller eigenvalue 0.
    y, x = np.mgrid[0:30, 0:30]
    ramp = (2 * x + 3 * y).astype(np.uint8)
    assert abs(shi_tomasi(ramp, [[15, 15]], 3)[0]) < 1e-9
    # A random patch: score == smaller eigenvalue of the PTAM-normalised structure tensor.
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (30, 30)).astype(np.uint8)
    I = img.astype(np.float64)
    dx = I[12:19, 13:20] - I[12:19, 11:18]
    dy = I[13:20, 12:19] - I[11:18, 12:19]
    M = np.array([[np.sum(dx * dx), np.sum(dx * dy)], [np.sum(dx * dy), np.sum(dy * dy)]]) / (2 * 49)
    assert np.isclose(shi_tomasi(img, [[15, 15]], 3)[0], np.linalg.eigvalsh(M)[0], rtol=1e-12)


def test_corner_beats_edge_beats_flat():
    img = np.zeros((40, 120), np.uint8)
    img[10:30, 10:30] = 200  # a square: corner at (10, 10)
    img[:, 60:] = 200  # a vertical edge at x = 60
    img[:, 90:] = 50  # ... and a flat region beyond x = 90 (an edge at 90 too; sample away from it)
    s = shi_tomasi(img, [[10, 10], [60, 20], [105, 20]], 3)
    assert s[0] > 1000 and abs(s[1]) < 1e-9 and s[2] == 0.0
    assert s[0] > s[1] >= s[2]


def test_candidates_are_maximal_scored_and_inside_border():
    cfg = default_config().image
    rng = np.random.default_rng(2)
    img = cv2.GaussianBlur(rng.integers(0, 256, (240, 320)).astype(np.uint8), (0, 0), 2).astype(np.float64)
    img = np.clip((img - img.mean()) * 5 + 128, 0, 255).astype(np.uint8)
    xy, score = candidates(img, 15, cfg)
    nms = fast_corners(img, 15, nonmax=True)
    assert 100 < len(xy) < len(nms)
    assert np.all(score > cfg.shi_tomasi_min)
    b = cfg.candidate_border_px
    assert xy[:, 0].min() >= b and xy[:, 1].min() >= b and xy[:, 0].max() < 320 - b and xy[:, 1].max() < 240 - b
    assert set(map(tuple, xy.tolist())) <= set(map(tuple, nms.tolist()))
