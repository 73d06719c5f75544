"""Candidate edgelets in a new keyframe (Agility §4.3, first steps).

Canny edge extraction (OpenCV) on the Gaussian-smoothed keyframe image; a linker that follows the edgels and
breaks chains at high curvature; chains cut into edgelet-length segments (``edgel_linker_kernels``). Each
straight-enough segment gets its polarity from the image gradient at its centre (the direction is signed so
that ``perp(direction)`` points from dark to light), is refined by a direct measurement (§4.2, the Canny
edgels being displaced by the smoothing), and is rejected when it lies within ``candidate_min_distance_px``
of an edgelet already in the map (their image centres are given). ``maximal_edgels`` gives the image of all
maximal edgels, suppressed by the hysteresis or not, which the epipolar search of §4.3 matches against; both
take the image ``smoothed`` once.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from ..config.edgelet_section import EdgeletConfig
from ..errors import InputError
from .edge_sample_kernels import sobel_at
from .edgel_linker_kernels import link_edgels, split_chains
from .edgelet import perp
from .edgelet_measure import measure_in_keyframe

_SOBEL_L2 = True  # OpenCV Canny with the L2 gradient magnitude (the thresholds are in its units)


@dataclass(frozen=True)
class EdgeletCandidates:
    """Measured candidates: image ``centre`` (N, 2), unit ``direction`` (N, 2) with ``perp(direction)`` dark →
    light, and the line-fit ``rms`` (N,) px."""

    centre: np.ndarray
    direction: np.ndarray
    rms: np.ndarray

    @property
    def normal(self) -> np.ndarray:
        return perp(self.direction)

    def __len__(self) -> int:
        return len(self.centre)


def smoothed(image: np.ndarray, cfg: EdgeletConfig) -> np.ndarray:
    if image.ndim != 2 or image.dtype != np.uint8:
        raise InputError(f"edgelet candidates need a 2-D uint8 image, got {image.dtype} {image.shape}")
    s = cfg.canny_blur_sigma
    return cv2.GaussianBlur(image, (0, 0), s) if s > 0 else image


def canny_edges(smoothed_image: np.ndarray, cfg: EdgeletConfig) -> np.ndarray:
    """Canny's edgels linked by hysteresis (the candidates' source, §4.3) of a ``smoothed`` image."""
    return cv2.Canny(smoothed_image, cfg.canny_low, cfg.canny_high, L2gradient=_SOBEL_L2)


def maximal_edgels(smoothed_image: np.ndarray, cfg: EdgeletConfig) -> np.ndarray:
    """Every non-maximum-suppressed edgel above Canny's low threshold (no hysteresis) of a ``smoothed`` image."""
    return cv2.Canny(smoothed_image, cfg.canny_low, cfg.canny_low, L2gradient=_SOBEL_L2)


def segment_edgels(edges: np.ndarray, cfg: EdgeletConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edgelet-length segments of the linked, curvature-broken chains: centre, unit direction, max deviation."""
    points, starts = link_edgels(edges)
    min_cos = float(np.cos(np.deg2rad(cfg.link_max_turn_deg)))
    return split_chains(points, starts, float(cfg.length_px), int(cfg.link_turn_window_px), min_cos)


def gradient_at(smoothed_image: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The 3×3 Sobel gradient (N, 2) of a ``smoothed`` image at the nearest pixels to ``xy`` (inside the image by
    at least one pixel), computed there only (cv2.Sobel's values there; ``edge_sample_kernels.sobel_at``)."""
    return sobel_at(smoothed_image, np.ascontiguousarray(np.reshape(xy, (-1, 2)), dtype=np.float64))


def extract_candidates(
    image: np.ndarray,
    cfg: EdgeletConfig,
    existing_centres: np.ndarray | None = None,
    smoothed_image: np.ndarray | None = None,
) -> EdgeletCandidates:
    """Candidate edgelets of a full-size keyframe ``image`` away from ``existing_centres`` (K, 2) (§4.3);
    ``smoothed_image``: the image ``smoothed`` once already, if so."""
    sm = smoothed(image, cfg) if smoothed_image is None else smoothed_image
    centre, direction, deviation = segment_edgels(canny_edges(sm, cfg), cfg)
    b = cfg.candidate_border_px
    H, W = image.shape
    keep = (deviation <= cfg.candidate_max_deviation_px) & (centre[:, 0] >= b) & (centre[:, 1] >= b)
    keep &= (centre[:, 0] <= W - 1 - b) & (centre[:, 1] <= H - 1 - b)
    centre, direction = centre[keep], direction[keep]
    grad = gradient_at(sm, centre)
    direction = direction * np.where(np.sum(perp(direction) * grad, axis=-1) < 0, -1.0, 1.0)[:, None]
    m = measure_in_keyframe(image, centre, direction, perp(direction), cfg)
    centre, direction, rms = m.a[m.ok], m.b[m.ok], m.rms[m.ok]
    if existing_centres is not None and len(existing_centres) and len(centre):
        dist, _ = cKDTree(np.asarray(existing_centres, dtype=np.float64)).query(centre, k=1)
        far = dist >= cfg.candidate_min_distance_px
        centre, direction, rms = centre[far], direction[far], rms[far]
    return EdgeletCandidates(centre, direction, rms)
