"""The second keyframe's trail ends are aligned to sub-pixel accuracy before the initial map is built (PTAM code
``InitFromStereo``): integer trails carry 0.29 px RMS of quantisation."""

from types import SimpleNamespace

import cv2
import numpy as np

from ptam.config import load_config
from ptam.image.fast import fast_corners
from ptam.mapping.stereo_init import subpixel_second


def test_trail_ends_are_aligned_to_a_known_subpixel_shift():
    rng = np.random.default_rng(3)
    img = cv2.GaussianBlur(cv2.resize(rng.integers(0, 256, (60, 80)).astype(np.uint8), (320, 240)), (0, 0), 1.0)
    shift = np.array([2.3, -1.6])
    moved = cv2.warpAffine(img, np.array([[1, 0, shift[0]], [0, 1, shift[1]]]), (320, 240), flags=cv2.INTER_CUBIC)
    moved = np.clip(moved.astype(int) + 12, 0, 255).astype(np.uint8)  # and brighter: the offset is estimated too
    xy0 = fast_corners(img, 20, nonmax=True)
    xy0 = xy0[(xy0 > 20).all(axis=1) & (xy0[:, 0] < 300) & (xy0[:, 1] < 220)].astype(np.float64)
    xy1 = np.round(xy0 + shift)  # what an integer trail reports
    first = SimpleNamespace(levels=(img,))
    second = SimpleNamespace(levels=(moved,))
    refined, aligned = subpixel_second(first, second, xy0, xy1, load_config().patch)
    assert len(xy0) > 50 and aligned.mean() > 0.9
    err = np.linalg.norm(refined[aligned] - (xy0[aligned] + shift), axis=1)
    before = np.linalg.norm(xy1 - (xy0 + shift), axis=1)
    assert np.median(before) > 0.4
    assert np.median(err) < 0.05 and np.percentile(err, 90) < 0.15
