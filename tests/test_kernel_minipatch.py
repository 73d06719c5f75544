"""The trail patch-search kernel against its numpy reference, and on a known image shift."""

import numpy as np

from ptam.image.fast import fast_corners
from ptam.image.pyramid import row_lut
from ptam.tracking.minipatch_kernels import minipatch_find
from tests.reference.minipatch import minipatch_find_ref


def _texture(rng, h=120, w=160):
    import cv2

    img = rng.integers(0, 256, (h // 4, w // 4)).astype(np.uint8)
    return cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)


def test_kernel_matches_reference_and_finds_a_shift():
    rng = np.random.default_rng(0)
    big = _texture(rng, 140, 180)
    src = np.ascontiguousarray(big[10:130, 10:170])
    dst = np.ascontiguousarray(big[7:127, 14:174])  # content moves by (-4, +3)
    src_xy = fast_corners(src, 10, nonmax=True)
    src_xy = src_xy[(src_xy[:, 0] > 12) & (src_xy[:, 0] < 147) & (src_xy[:, 1] > 12) & (src_xy[:, 1] < 107)]
    corners = fast_corners(dst, 10, nonmax=False)
    lut = row_lut(corners, dst.shape[0])
    for gain in (1.0, 1.1):
        found, ok = minipatch_find(src, src_xy, dst, src_xy, corners, lut, 10, 4, 9999, gain)
        found_r, ok_r = minipatch_find_ref(src, src_xy, dst, src_xy, corners, 10, 4, 9999, gain)
        assert np.array_equal(ok, ok_r) and np.array_equal(found[ok], found_r[ok_r])
        if gain == 1.0:
            assert ok.sum() > 0.8 * len(src_xy)
        shift = found[ok] - src_xy[ok]
        assert np.mean(np.all(shift == [-4, 3], axis=1)) > 0.95


def test_gain_compensated_trails_survive_a_change_of_exposure():
    """The same shift, the second image 15 % brighter: plain SSD (PTAM code) loses nearly every match, the
    gain-compensated SSD keeps them at the right shift."""
    rng = np.random.default_rng(0)
    big = _texture(rng, 140, 180)
    src = np.ascontiguousarray(big[10:130, 10:170])
    dst = np.ascontiguousarray(np.clip(big[7:127, 14:174] * 1.15, 0, 255).astype(np.uint8))
    src_xy = fast_corners(src, 10, nonmax=True)
    src_xy = src_xy[(src_xy[:, 0] > 12) & (src_xy[:, 0] < 147) & (src_xy[:, 1] > 12) & (src_xy[:, 1] < 107)]
    corners = fast_corners(dst, 10, nonmax=False)
    lut = row_lut(corners, dst.shape[0])
    _, ok_plain = minipatch_find(src, src_xy, dst, src_xy, corners, lut, 10, 4, 9999, 1.0)
    found, ok = minipatch_find(src, src_xy, dst, src_xy, corners, lut, 10, 4, 9999, 1.15)
    assert ok_plain.mean() < 0.1 and ok.mean() > 0.8
    assert np.mean(np.all(found[ok] - src_xy[ok] == [-4, 3], axis=1)) > 0.95
