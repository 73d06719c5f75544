"""The ``edgelets`` section: edge features for agile tracking (Agility §4–§5, project issue #17).

Types only (see ``sections``); every default lives in ``configs/default.yaml`` with its source.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from .interval import Range


@dataclass(frozen=True)
class EdgeletConfig:
    enabled: bool
    # §4.2: measuring an edgelet in a keyframe
    length_px: Annotated[float, Range("(0, inf)")]
    samples: Annotated[int, Range("[2, inf)")]
    measure_search_px: Annotated[int, Range("[1, inf)")]
    measure_kernel_px: Annotated[float, Range("[2, inf)")]
    measure_min_contrast: Annotated[float, Range("[0, inf)")]
    measure_min_found: Annotated[int, Range("[2, inf)")]
    measure_max_rms_px: Annotated[float, Range("(0, inf)")]
    # §4.4: bundle-adjustment terms
    ba_sample_offset_px: Annotated[float, Range("(0, inf)")]
    # §5.1: blur-aware sawtooth search
    sawtooth_min_length_px: Annotated[float, Range("[2, inf)")]
    sawtooth_max_length_px: Annotated[float, Range("[2, inf)")]
    # §5.2: visibility table
    table_blur_min_px: Annotated[int, Range("[1, inf)")]
    table_blur_max_px: Annotated[int, Range("[1, inf)")]
    table_blur_step_px: Annotated[int, Range("[1, inf)")]
    table_centre_tolerance_px: Annotated[float, Range("[0, inf)")]
    table_tmin_fraction: Annotated[float, Range("(0, 1]")]
    table_rsearch_fraction: Annotated[float, Range("(0, 1]")]
    table_max_search_px: Annotated[int, Range("[1, inf)")]
    # §4.3: triangulation and the check in a third keyframe
    triangulate_min_plane_angle_deg: Annotated[float, Range("(0, 90]")]
    verify_max_distance_px: Annotated[float, Range("(0, inf)")]
    verify_max_angle_deg: Annotated[float, Range("(0, 90]")]
    # §4.3: candidates from Canny edges
    canny_blur_sigma: Annotated[float, Range("[0, inf)")]
    canny_low: Annotated[float, Range("[0, inf)")]
    canny_high: Annotated[float, Range("[0, inf)")]
    link_turn_window_px: Annotated[int, Range("[1, inf)")]
    link_max_turn_deg: Annotated[float, Range("(0, 180]")]
    candidate_max_deviation_px: Annotated[float, Range("(0, inf)")]
    candidate_min_distance_px: Annotated[float, Range("[0, inf)")]
    candidate_border_px: Annotated[int, Range("[0, inf)")]
    # §4.3: the epipolar search for a candidate in the target keyframe
    epipolar_vertices: Annotated[int, Range("[2, inf)")]
    epipolar_step_px: Annotated[float, Range("(0, inf)")]
    epipolar_min_angle_deg: Annotated[float, Range("[0, 90)")]
    aperture_retry: bool
    epipolar_dilate_px: Annotated[int, Range("[0, inf)")]
    image_cache_keyframes: Annotated[int, Range("[1, inf)")]
    hypothesis_merge_px: Annotated[float, Range("[0, inf)")]
    refine_iterations: Annotated[int, Range("[0, inf)")]
    # §5: tracking
    track_sigma_px: Annotated[float, Range("(0, inf)")]
    track_min_found: Annotated[int, Range("[1, inf)")]
    coarse_min_range_px: Annotated[float, Range("[0, inf)")]
