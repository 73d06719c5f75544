"""Measuring edgelets in keyframes: five perpendicular searches and a line fit (Agility §4.2, Fig. 2).

The result is an infinite image line a + λb per edgelet: ``a`` the measured centre (the foot of the predicted
centre on the fitted line), ``b`` the unit direction, oriented so that ``perp(b)`` points from dark to light.
The loop is ``edgelet_measure_kernels.measure_edgelets``; this module validates inputs and reads the config.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.edgelet_section import EdgeletConfig
from ..errors import InputError
from .edgelet_measure_kernels import measure_edgelets


@dataclass(frozen=True)
class LineMeasurements:
    """Per edgelet: measured centre ``a`` (N, 2), unit direction ``b`` (N, 2), RMS line-fit residual (px),
    samples found, the sub-pixel sample positions (N, S, 2) with their ``found`` mask, and ``ok``."""

    a: np.ndarray
    b: np.ndarray
    rms: np.ndarray
    n_found: np.ndarray
    points: np.ndarray
    found: np.ndarray
    ok: np.ndarray


def _as_xy(name: str, v: np.ndarray, n: int | None) -> np.ndarray:
    v = np.ascontiguousarray(v, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 2 or (n is not None and len(v) != n):
        raise InputError(f"edgelet measurement: {name} must be (N, 2), got shape {v.shape}")
    return v


def measure_in_keyframe(
    image: np.ndarray, centres: np.ndarray, directions: np.ndarray, normals: np.ndarray, cfg: EdgeletConfig
) -> LineMeasurements:
    """Measure predicted edgelets (image centres, directions, dark-to-light normals, each (N, 2)) in a
    full-size grey ``image`` (Agility §4.2): ``cfg.samples`` searches of ±``cfg.measure_search_px`` along an
    edge of ``cfg.length_px``, a line fit and the residual gate ``cfg.measure_max_rms_px``."""
    if image.ndim != 2:
        raise InputError(f"edgelet measurement needs a 2-D grey image, got shape {image.shape}")
    c = _as_xy("centres", centres, None)
    d = _as_xy("directions", directions, len(c))
    n = _as_xy("normals", normals, len(c))
    out = measure_edgelets(
        image,
        c,
        d,
        n,
        float(cfg.length_px),
        int(cfg.samples),
        int(cfg.measure_search_px),
        float(cfg.measure_kernel_px),
        float(cfg.measure_min_contrast),
        int(cfg.measure_min_found),
        float(cfg.measure_max_rms_px),
    )
    return LineMeasurements(*out)
