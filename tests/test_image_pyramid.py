import cv2
import numpy as np
import pytest

from ptam.config import default_config
from ptam.errors import ConfigError, InputError
from ptam.image.fast import fast_corners
from ptam.image.pyramid import Pyramid, half_sample, level_to_zero, row_lut, zero_to_level
from tests.support.views import texture


def test_half_sample_matches_rounded_box_mean_and_drops_odd_edge():
    rng = np.random.default_rng(1)
    for shape in [(480, 640), (61, 83), (2, 3)]:
        img = rng.integers(0, 256, shape).astype(np.uint8)
        s = img[: shape[0] // 2 * 2, : shape[1] // 2 * 2].astype(np.int64)
        ref = (s[0::2, 0::2] + s[1::2, 0::2] + s[0::2, 1::2] + s[1::2, 1::2] + 2) // 4
        out = half_sample(img)
        assert out.dtype == np.uint8 and out.shape == (shape[0] // 2, shape[1] // 2)
        assert np.array_equal(out, ref)


def test_pyramid_sizes_values_corners_and_row_lut():
    cfg = default_config().image
    img = texture()
    pyr = Pyramid.build(img, cfg)
    assert [im.shape for im in pyr.levels] == [(480, 640), (240, 320), (120, 160), (60, 80)]
    assert np.array_equal(pyr.levels[0], img) and pyr.levels[0] is not img
    for L in range(1, 4):
        assert np.array_equal(pyr.levels[L], half_sample(pyr.levels[L - 1]))
    for L, (im, c, lut) in enumerate(zip(pyr.levels, pyr.corners, pyr.row_lut)):
        assert c.dtype == np.int32 and c.shape[1] == 2 and len(c) > 100
        assert np.array_equal(c, fast_corners(im, cfg.fast_thresholds[L]))
        order = np.lexsort((c[:, 0], c[:, 1]))
        assert np.array_equal(order, np.arange(len(c)))  # sorted by y, then x
        # PTAM §6.5 row LUT: lut[r] = first corner with y >= r, lut[H] = K
        assert lut.dtype == np.int32 and lut.shape == (im.shape[0] + 1,)
        for r in (0, 7, im.shape[0] // 2, im.shape[0] - 1, im.shape[0]):
            assert lut[r] == np.count_nonzero(c[:, 1] < r)
        for a in (im, c, lut):
            assert not a.flags.writeable
    assert np.array_equal(pyr.row_lut[0], row_lut(pyr.corners[0], 480))


def test_fast_counts_on_textured_and_flat_images():
    img = texture(seed=3)
    raw = fast_corners(img, 10)
    nms = fast_corners(img, 10, nonmax=True)
    # FAST-9 at threshold 10 on this high-contrast texture: dense blobs without NMS, ~20x fewer with NMS.
    assert 50_000 < len(raw) < 200_000
    assert 1_000 < len(nms) < len(raw) // 10
    # every maximal corner is also a corner of the raw set
    raw_keys = set(map(tuple, raw.tolist()))
    assert all(tuple(p) in raw_keys for p in nms.tolist())
    assert len(fast_corners(np.full((120, 160), 77, np.uint8), 10)) == 0
    # a slightly blurred bright square: a cluster per corner without NMS, exactly one response each with NMS
    sq = np.zeros((60, 60), np.uint8)
    sq[20:40, 20:40] = 200
    sq = cv2.GaussianBlur(sq, (0, 0), 1.0)
    c = fast_corners(sq, 20, nonmax=True)
    assert c.tolist() == [[21, 21], [38, 21], [21, 38], [38, 38]]
    assert len(fast_corners(sq, 20)) > 4 * 4


def test_level_coordinate_convention():
    xy0 = np.array([[0.0, 0.0], [-0.5, -0.5], [10.25, 3.0]])
    for L in range(4):
        assert np.allclose(level_to_zero(zero_to_level(xy0, L), L), xy0)
    # level-L pixel 0 is centred on the 2^L x 2^L block of level-0 pixels 0..2^L-1
    assert np.allclose(level_to_zero([[0, 0]], 3), [[3.5, 3.5]])
    assert np.allclose(zero_to_level([[-0.5, -0.5]], 2), [[-0.5, -0.5]])
    per_row = level_to_zero([[1.0, 2.0], [1.0, 2.0]], np.array([0, 2]))
    assert np.allclose(per_row, [[1.0, 2.0], [5.5, 9.5]])


def test_bad_input():
    cfg = default_config().image
    with pytest.raises(InputError):
        Pyramid.build(np.zeros((480, 640), np.float32), cfg)
    with pytest.raises(InputError):
        Pyramid.build(np.zeros((30, 40), np.uint8), cfg)
    with pytest.raises(ConfigError):
        Pyramid.build(np.zeros((480, 640), np.uint8), default_config().replace(**{"image.levels": 3}).image)
