"""Turn a decoded 8-bit OpenCV image into the (grey, colour) pair a :class:`Frame` carries (PTAM §7: 8bpp
greyscale for tracking, colour for display)."""

from __future__ import annotations

import cv2
import numpy as np


def grey_and_colour(img: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey uint8 (H, W) and the BGR original, or None when the input is already grey."""
    if img.ndim == 2:
        return img, None
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), img
