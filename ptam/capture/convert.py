"""Turn a decoded OpenCV image into the (grey, colour) pair a :class:`Frame` carries."""

from __future__ import annotations

import cv2
import numpy as np


def grey_and_colour(img: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey uint8 (H, W) and the BGR original (or None for grey input). 16-bit input keeps its top byte."""
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise ValueError(f"unsupported image depth {img.dtype}")
    if img.ndim == 2:
        return img, None
    if img.shape[2] == 1:
        return img[:, :, 0], None
    if img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), img
