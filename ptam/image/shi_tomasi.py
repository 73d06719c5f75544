"""Shi-Tomasi scores and PTAM's new-point candidates (PTAM §6.2; code ``KeyFrame::MakeKeyFrame_Rest``)."""

from __future__ import annotations

import numpy as np

from .fast import fast_corners
from .shi_tomasi_kernels import shi_tomasi_scores


def shi_tomasi(img: np.ndarray, xy: np.ndarray, half_box: int) -> np.ndarray:
    """Smaller structure-tensor eigenvalue at each (x, y) of ``xy`` (K, 2); −inf where the box leaves the image."""
    xy = np.ascontiguousarray(xy, dtype=np.int32).reshape(-1, 2)
    return shi_tomasi_scores(np.ascontiguousarray(img), xy, int(half_box))


def candidates(img: np.ndarray, fast_threshold: int, image_cfg) -> tuple[np.ndarray, np.ndarray]:
    """New-point candidates of one pyramid level: maximal FAST corners at least ``candidate_border_px``
    inside the image whose Shi-Tomasi score exceeds ``shi_tomasi_min``. Returns ((K, 2) int32 xy, (K,) scores).
    """
    xy = fast_corners(img, fast_threshold, nonmax=True)
    b = image_cfg.candidate_border_px
    h, w = img.shape
    inside = (xy[:, 0] >= b) & (xy[:, 1] >= b) & (xy[:, 0] < w - b) & (xy[:, 1] < h - b)
    xy = xy[inside]
    score = shi_tomasi(img, xy, image_cfg.shi_tomasi_half_box)
    keep = score > image_cfg.shi_tomasi_min
    return xy[keep], score[keep]
