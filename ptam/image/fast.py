"""FAST corner detection (PTAM §5.1, §6.2).

PTAM runs FAST-10 (libCVD ``fast_corner_detect_10``). OpenCV, the maintained library this project relies on,
offers only the 9-of-16, 7-of-12 and 5-of-8 segment tests, so we use its nearest, ``TYPE_9_16`` (project
policy: a maintained library's nearest equivalent over a hand-written detector). A 9-of-16 arc accepts a
superset of the FAST-10 corners, so at the same thresholds the per-level corner counts are somewhat higher.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..errors import InputError


def fast_corners(img: np.ndarray, threshold: int, nonmax: bool = False) -> np.ndarray:
    """FAST corners of a uint8 image as (K, 2) int32 (x, y), sorted by y then x.

    ``nonmax=False`` is the tracker's setting (PTAM §5.1: no non-maximal suppression, giving blob-like
    clusters); ``nonmax=True`` keeps only locally maximal corners, as PTAM does for new-point candidates (§6.2).
    """
    if img.dtype != np.uint8 or img.ndim != 2:
        raise InputError(f"FAST needs a 2-D uint8 image, got {img.dtype} with shape {img.shape}")
    detector = cv2.FastFeatureDetector_create(  # type: ignore[attr-defined]  # OpenCV's stubs miss it
        int(threshold), bool(nonmax), cv2.FastFeatureDetector_TYPE_9_16
    )
    keypoints = detector.detect(img)
    if not keypoints:
        return np.zeros((0, 2), np.int32)
    xy = np.rint(cv2.KeyPoint_convert(keypoints))  # type: ignore[attr-defined]
    xy = xy.astype(np.int32)
    # OpenCV scans rows in order, so this is normally already sorted; the row look-up table relies on it.
    key = xy[:, 1].astype(np.int64) * (img.shape[1] + 1) + xy[:, 0]
    if np.any(key[1:] < key[:-1]):
        xy = xy[np.argsort(key, kind="stable")]
    return xy
