"""The epipolar search kernel against its numpy reference on random data."""

import numpy as np

from ptam.image.pyramid import row_lut
from ptam.mapping.epipolar_kernels import epipolar_search
from tests.reference.epipolar import epipolar_search_ref


def test_kernel_matches_reference():
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (60, 80)).astype(np.uint8)
    corners = np.stack([rng.integers(0, 80, 400), rng.integers(0, 60, 400)], axis=1).astype(np.int32)
    corners = corners[np.lexsort((corners[:, 0], corners[:, 1]))]
    plane = (corners - [40.0, 30.0]) / 50.0
    n = 40
    templates = rng.normal(0, 30, (n, 8, 8)).astype(np.float32)
    templates -= templates.mean(axis=(1, 2), keepdims=True)
    # Half the templates are copies of image patches at corners, so some searches succeed.
    for k in range(0, n, 2):
        x, y = corners[rng.integers(50, 350)]
        x, y = np.clip(x, 4, 75), np.clip(y, 4, 55)
        p = img[y - 4 : y + 4, x - 4 : x + 4].astype(np.float32)
        templates[k] = p - p.mean()
    ang = rng.uniform(0, np.pi, n)
    along = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    normal = np.stack([along[:, 1], -along[:, 0]], axis=1)
    dist = rng.uniform(-0.3, 0.3, n)
    lo = rng.uniform(-1.0, -0.2, n)
    hi = rng.uniform(0.2, 1.0, n)
    max_perp = np.full(n, 0.2)
    # Half the candidates search the whole image, half a random box (partly outside the image).
    box = np.tile([-5, -5, 90, 70], (n, 1))
    box[1::2, :2] = rng.integers(-10, 50, (n // 2, 2))
    box[1::2, 2:] = box[1::2, :2] + rng.integers(5, 60, (n // 2, 2))
    lut = row_lut(corners, img.shape[0])
    best, score = epipolar_search(img, corners, plane, lut, box, templates, normal, dist, along, lo, hi, max_perp, 1e9)
    best_r, score_r = epipolar_search_ref(
        img, corners, plane, box, templates, normal, dist, along, lo, hi, max_perp, 1e9
    )
    assert (best >= 0).sum() > n // 4
    assert np.array_equal(best, best_r)
    ok = best >= 0
    assert np.allclose(score[ok], score_r[ok], rtol=1e-6, atol=1e-2)
