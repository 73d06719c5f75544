"""The keyframe images the edgelet job keeps between jobs (``edgelet_images``): the same images as made afresh,
made once per keyframe, the least recently used dropped beyond the configured count, never another map's."""

import dataclasses

import cv2
import numpy as np

from ptam.edgelet import maximal_edgels, smoothed
from ptam.mapping.edgelet_images import EdgeImages
from tests.support import config
from tests.support.cameras import CAMERAS
from tests.support.edgelet_scene import keyframe_map

POSITIONS = np.array([[0.15, 0.0, 0.01], [0.0, 0.15, -0.01], [-0.1, -0.08, 0.03], [0.0, 0.0, 0.0]])


def test_images_are_made_once_and_the_least_recently_used_dropped():
    cfg = config()
    e = dataclasses.replace(cfg.edgelets, image_cache_keyframes=2)
    m = keyframe_map(CAMERAS["pinhole"], cfg.image, POSITIONS)
    images = EdgeImages(e)
    image = m.keyframes[1].pyramid.levels[0]
    sm = smoothed(image, e)
    grown = cv2.dilate(maximal_edgels(sm, e), np.ones((3, 3), np.uint8))  # epipolar_dilate_px = 1
    assert e.epipolar_dilate_px == 1 and grown.any()
    assert np.array_equal(images.smoothed(m, 1), sm) and np.array_equal(images.maximal(m, 1), grown)
    first = images.maximal(m, 1)
    assert images.maximal(m, 1) is first and images.smoothed(m, 1) is images.smoothed(m, 1)  # made once
    s0 = images.smoothed(m, 0)
    images.smoothed(m, 1)  # 1 used last: 0 is the least recently used
    images.smoothed(m, 2)  # over the count of two: 0 dropped, 1 kept
    assert images.maximal(m, 1) is first
    assert images.smoothed(m, 0) is not s0  # made again (and 2 dropped)
    other = keyframe_map(CAMERAS["pinhole"], cfg.image, POSITIONS[::-1])  # another map: its keyframe 1 differs
    assert not np.array_equal(other.keyframes[1].pyramid.levels[0], image)
    assert np.array_equal(images.smoothed(other, 1), smoothed(other.keyframes[1].pyramid.levels[0], e))
