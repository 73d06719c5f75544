"""The four-level image pyramid with FAST corners and row look-up tables (PTAM §4, §5.1, §6.5).

Pixel centres are at integer coordinates on every level. A level-L pixel covers a 2^L × 2^L block of
level-0 pixels, so x_L = (x_0 + 0.5) / 2^L − 0.5 (PTAM code: ``LevelZeroPos`` / ``LevelNPos``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..errors import ConfigError, InputError
from .fast import fast_corners


def half_sample(img: np.ndarray) -> np.ndarray:
    """Half-size image by 2×2 box averaging, an odd last row/column dropped (libCVD ``halfSample``, PTAM §4).

    Each output pixel is the rounded mean (a + b + c + d + 2) // 4. libCVD's generic path truncates instead
    and its SSE2 path (taken by PTAM for 640-wide images) rounds two pairwise averages; the rounded mean is
    the unbiased choice between the two. OpenCV's exact-2× ``INTER_AREA`` computes precisely this (the test
    checks it against the integer formula) and releases the GIL.
    """
    if img.dtype != np.uint8 or img.ndim != 2:
        raise InputError(f"half_sample needs a 2-D uint8 image, got {img.dtype} with shape {img.shape}")
    h, w = img.shape[0] // 2, img.shape[1] // 2
    if h == 0 or w == 0:
        raise InputError(f"image of shape {img.shape} is too small to half-sample")
    return cv2.resize(img[: 2 * h, : 2 * w], (w, h), interpolation=cv2.INTER_AREA)


def row_lut(corners: np.ndarray, height: int) -> np.ndarray:
    """(height + 1,) int32: index of the first corner with y ≥ row; entry ``height`` is K (PTAM §6.5)."""
    return np.searchsorted(corners[:, 1], np.arange(height + 1), side="left").astype(np.int32)


def _scale(level) -> np.ndarray:
    s = np.exp2(np.asarray(level, dtype=np.float64))
    return s[..., None] if s.ndim else s


def level_to_zero(xy: np.ndarray, level) -> np.ndarray:
    """Level-L pixel coordinates (N, 2) -> level-0 pixel coordinates; ``level`` a scalar or one per row."""
    return (np.asarray(xy, dtype=np.float64) + 0.5) * _scale(level) - 0.5


def zero_to_level(xy: np.ndarray, level) -> np.ndarray:
    """Level-0 pixel coordinates (N, 2) -> level-L pixel coordinates; ``level`` a scalar or one per row."""
    return (np.asarray(xy, dtype=np.float64) + 0.5) / _scale(level) - 0.5


@dataclass(frozen=True)
class Pyramid:
    """Images (level L is 2^L smaller), FAST corners per level (sorted by y then x) and row look-up tables.

    All arrays are read-only: a pyramid is shared between the tracker, keyframes and the mapper.
    """

    levels: tuple[np.ndarray, ...]
    corners: tuple[np.ndarray, ...]
    row_lut: tuple[np.ndarray, ...]

    @classmethod
    def build(cls, img: np.ndarray, image_cfg) -> Pyramid:
        """PTAM §5.1 (code ``KeyFrame::MakeKeyFrame_Lite``): half-sample, FAST without NMS per level."""
        n = image_cfg.levels
        if len(image_cfg.fast_thresholds) != n:
            raise ConfigError(
                f"config: image.fast_thresholds needs {n} values (one per level), got {len(image_cfg.fast_thresholds)}"
            )
        img = np.asarray(img)
        if img.dtype != np.uint8 or img.ndim != 2:
            raise InputError(f"pyramid needs a 2-D uint8 greyscale image, got {img.dtype} with shape {img.shape}")
        if min(img.shape) >> (n - 1) < 8:
            raise InputError(f"image of shape {img.shape} is too small for a {n}-level pyramid")
        levels = [np.array(img, order="C", copy=True)]  # ours to freeze, never the caller's
        for _ in range(1, n):
            levels.append(half_sample(levels[-1]))
        corners = [fast_corners(im, t, nonmax=False) for im, t in zip(levels, image_cfg.fast_thresholds)]
        luts = [row_lut(c, im.shape[0]) for c, im in zip(corners, levels)]
        for a in (*levels, *corners, *luts):
            a.setflags(write=False)
        return cls(tuple(levels), tuple(corners), tuple(luts))

    @property
    def n_levels(self) -> int:
        return len(self.levels)
