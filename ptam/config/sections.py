"""Typed configuration sections: one frozen dataclass per section of ``configs/default.yaml``.

The dataclasses carry types only; every default value lives in the YAML file, commented with its source.
``load_config`` overlays ``--config`` files and ``--set section.key=value`` overrides, rejecting unknown
keys (with a "did you mean" suggestion), values of the wrong type, and numbers outside their field's
:class:`Range` with a :class:`ConfigError`.

Every numeric field (int, float, or a list of them) is ``Annotated[type, Range("[lo, hi)")]``: the values it
may take, in interval notation (``[`` / ``]`` closed, ``(`` / ``)`` open; ``inf`` and ``pi`` allowed as ends).
A list field's range applies to each element, and ``length`` fixes its number of elements. NaN is never in
range, and an infinite value only where a closed bracket admits it. A new numeric field needs a range
(``tests/test_input_validation.py`` checks it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from ..vocabulary import EssentialMethod, RunMode, SearchLevelRule
from .app_sections import ArConfig, CalibrateConfig, SynthCalibrationConfig, ViewerConfig
from .edgelet_section import EdgeletConfig
from .interval import Range
from .model_section import ModelSelectionConfig
from .normals_section import NormalsConfig
from .tracks_section import TracksConfig

__all__ = [
    "ArConfig",
    "CalibrateConfig",
    "Config",
    "EdgeletConfig",
    "ModelSelectionConfig",
    "NormalsConfig",
    "Range",
    "SynthCalibrationConfig",
    "TracksConfig",
    "ViewerConfig",
]


@dataclass(frozen=True)
class ImageConfig:
    levels: Annotated[int, Range("[1, 16]")]
    fast_thresholds: Annotated[list[int], Range("[0, 255]")]
    shi_tomasi_half_box: Annotated[int, Range("[1, inf)")]
    shi_tomasi_min: Annotated[float, Range("[0, inf)")]
    candidate_border_px: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class PatchConfig:
    size: Annotated[int, Range("[2, inf)")]
    max_ssd_per_pixel: Annotated[float, Range("(0, inf)")]
    max_ssd_template_fraction: Annotated[float, Range("(0, inf]")]
    det_min: Annotated[float, Range("(0, inf)")]
    det_max: Annotated[float, Range("(0, inf)")]
    subpix_iterations: Annotated[int, Range("[0, inf)")]
    subpix_converge_px: Annotated[float, Range("(0, inf)")]
    search_level_rule: SearchLevelRule


@dataclass(frozen=True)
class TrackerConfig:
    max_patches: Annotated[int, Range("[1, inf)")]
    coarse_points: Annotated[int, Range("[0, inf)")]
    coarse_min_points: Annotated[int, Range("[0, inf)")]
    coarse_radius_px: Annotated[float, Range("(0, inf)")]
    coarse_min_velocity: Annotated[float, Range("[0, inf)")]
    fine_radius_px: Annotated[float, Range("(0, inf)")]
    fine_radius_after_coarse_px: Annotated[float, Range("(0, inf)")]
    irls_iterations: Annotated[int, Range("[1, inf)")]
    relinearise_every: Annotated[int, Range("[1, inf)")]
    min_tukey_sigma: Annotated[float, Range("(0, inf)")]
    quality_good: Annotated[float, Range("[0, 1]")]
    quality_lost: Annotated[float, Range("[0, 1]")]
    lost_frames: Annotated[int, Range("[0, inf)")]
    max_keyframe_distance_baselines: Annotated[float, Range("(0, inf)")]
    valid_radius_factor: Annotated[float, Range("(0, inf)")]
    motion_decay: Annotated[float, Range("[0, 1]")]
    motion_blend: Annotated[float, Range("[0, 1]")]
    motion_period_window: Annotated[int, Range("[1, inf)")]
    motion_gap_frames: Annotated[float, Range("[1, inf)")]
    motion_max_gap_frames: Annotated[float, Range("[1, inf)")]
    coarse_enabled: bool
    coarse_min_level: Annotated[int, Range("[0, inf)")]
    fine_subpix_min_level: Annotated[int, Range("[0, inf)")]
    fine_subpix_all_levels: bool
    fine_subpix_blur_fraction: Annotated[float, Range("[0, 1]")]
    exposure_fraction: Annotated[float, Range("[0, inf)")]
    blur_gate_patch_widths: Annotated[float, Range("(0, inf]")]
    blur_corner_fraction: Annotated[float, Range("[0, inf]")]
    smear_variance: Annotated[float, Range("[0, inf)")]
    recovery_coarse_factor: Annotated[int, Range("[1, inf)")]
    pose_prior: Annotated[float, Range("[0, inf)")]
    tukey_override_enabled: bool
    tukey_override_after: Annotated[int, Range("[0, inf)")]
    tukey_override_sigma_sq_coarse: Annotated[float, Range("(0, inf)")]
    tukey_override_sigma_sq_fine: Annotated[float, Range("(0, inf)")]
    image_margin_px: Annotated[float, Range("[0, inf)")]
    scene_depth_min_points: Annotated[int, Range("[0, inf)")]
    quality_large_min_level: Annotated[int, Range("[0, inf)")]
    quality_large_min_attempted: Annotated[int, Range("[0, inf)")]
    shuffle_seed: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class RotationConfig:
    enabled: bool
    blur_sigma: Annotated[float, Range("(0, inf)")]
    iterations: Annotated[int, Range("[1, inf)")]
    intensity_offset: bool
    robust: bool
    motion_model_fallback: bool
    keep_axial_velocity: bool
    sample_radius_px: Annotated[float, Range("(0, inf)")]


@dataclass(frozen=True)
class RelocConfig:
    enabled: bool
    blur_sigma: Annotated[float, Range("(0, inf)")]
    iterations: Annotated[int, Range("[1, inf)")]
    max_score: Annotated[float, Range("[0, inf)")]
    suspend_when_rapid: bool
    rapid_rotation_deg: Annotated[float, Range("[0, 180]")]
    confirm_frames: Annotated[int, Range("[1, inf)")]
    confirm_inlier_fraction: Annotated[float, Range("[0, 1]")]


@dataclass(frozen=True)
class CaptureConfig:
    default_fps: Annotated[float, Range("(0, inf)")]
    camera_size: Annotated[list[int], Range("[1, inf)", length=2)]
    camera_fps: Annotated[float, Range("(0, inf)")]
    video_missing_frames_tolerance: Annotated[int, Range("[0, inf)")]
    dc1394_mode: str
    dc1394_iso_speed: Annotated[int, Range("[100, 3200]")]
    dc1394_dma_buffers: Annotated[int, Range("[1, inf)")]
    dc1394_frame_timeout_s: Annotated[float, Range("(0, inf)")]


@dataclass(frozen=True)
class InitConfig:
    max_trails: Annotated[int, Range("[1, inf)")]
    trail_half_patch: Annotated[int, Range("[1, inf)")]
    trail_search_radius_px: Annotated[int, Range("[1, inf)")]
    trail_global_gain: bool
    trail_rotation_prior: bool
    trail_max_ssd: Annotated[int, Range("[0, inf)")]
    trail_backward_tolerance_px2: Annotated[int, Range("[0, inf)")]
    min_trails: Annotated[int, Range("[0, inf)")]
    auto_min_disparity_rel_focal: Annotated[float, Range("(0, inf)")]
    min_matches: Annotated[int, Range("[5, inf)")]
    min_inliers: Annotated[int, Range("[1, inf)")]
    essential_method: EssentialMethod
    essential_threshold_px: Annotated[float, Range("(0, inf)")]
    ransac_confidence: Annotated[float, Range("(0, 1)")]
    ransac_seed: Annotated[int, Range("[0, 2147483647]")]
    gric_min_sigma_px: Annotated[float, Range("(0, inf)")]
    gric_lambda3: Annotated[float, Range("(0, inf)")]
    inlier_sigmas: Annotated[float, Range("(0, inf)")]
    triangulation_max_error_px: Annotated[float, Range("(0, inf)")]
    min_parallax_deg: Annotated[float, Range("[0, 180)")]
    homography_ambiguity_ratio: Annotated[float, Range("(0, 1]")]
    homography_resolve_ambiguity: bool
    homography_ambiguity_alpha: Annotated[float, Range("(0, 1]")]
    max_ba_rounds: Annotated[int, Range("[0, inf)")]
    track_frames_between: bool
    max_history_frames: Annotated[int, Range("[0, inf)")]
    history_pnp_max_error_px: Annotated[float, Range("(0, inf)")]
    baseline_m: Annotated[float, Range("(0, inf)")]
    plane_ransac_iterations: Annotated[int, Range("[1, inf)")]
    plane_inlier_distance: Annotated[float, Range("(0, inf)")]
    plane_seed: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class MapperConfig:
    tracker_feedback_frames: Annotated[int, Range("[1, inf)")]
    kf_min_frames: Annotated[int, Range("[0, inf)")]
    kf_min_frames_fps: Annotated[float, Range("[0, inf)")]
    kf_max_queue: Annotated[int, Range("[1, inf)")]
    kf_dist_wiggle_mult: Annotated[float, Range("(0, inf)")]
    candidate_min_dist_px: Annotated[float, Range("[0, inf)")]
    epipolar_far_depth_mult: Annotated[float, Range("(0, inf)")]
    epipolar_min_z: Annotated[float, Range("(0, inf)")]
    epipolar_min_line_length: Annotated[float, Range("[0, inf)")]
    epipolar_along_margin: Annotated[float, Range("[0, inf)")]
    epipolar_along_clip: Annotated[float, Range("(0, inf)")]
    epipolar_box_samples: Annotated[int, Range("[2, inf)")]
    epipolar_band_px: Annotated[float, Range("[0, inf)")]
    refind_radius_px: Annotated[int, Range("[1, inf)")]
    bad_point_min_outliers: Annotated[int, Range("[0, inf)")]
    local_ba_min_keyframes: Annotated[int, Range("[1, inf)")]
    outlier_min_good_measurements: Annotated[int, Range("[0, inf)")]
    unfinished_ba_outliers: bool


@dataclass(frozen=True)
class EvalConfig:
    max_time_diff_s: Annotated[float, Range("[0, inf)")]
    rpe_delta_s: Annotated[float, Range("(0, inf)")]
    correct_mm: Annotated[float, Range("(0, inf)")]
    correct_deg: Annotated[float, Range("(0, 180]")]
    align_gate_factor: Annotated[float, Range("(0, inf)")]
    align_segments: Annotated[int, Range("[1, inf)")]


@dataclass(frozen=True)
class GtMapConfig:
    kf_every: Annotated[int, Range("[1, inf)")]
    max_points: Annotated[int, Range("[1, inf)")]
    min_distance_px: Annotated[float, Range("[0, inf)")]
    planarity_tol: Annotated[float, Range("[0, inf)")]
    seed: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class BundleConfig:
    lambda_initial: Annotated[float, Range("(0, inf)")]
    lambda_decrease: Annotated[float, Range("(0, 1)")]
    lambda_increase_initial: Annotated[float, Range("(1, inf)")]
    lambda_increase_growth: Annotated[float, Range("[1, inf)")]
    lambda_max: Annotated[float, Range("(0, inf)")]
    max_iterations: Annotated[int, Range("[1, inf)")]
    converge_squared_update: Annotated[float, Range("[0, inf)")]
    min_tukey_sigma: Annotated[float, Range("(0, inf)")]
    hold_scale: bool
    hold_underdetermined: bool
    tukey_from_points: bool
    local_neighbours: Annotated[int, Range("[0, inf)")]
    dense_max_cameras: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class SyntheticConfig:
    cache_dir: str
    render_threads: Annotated[int, Range("[1, inf)")]


@dataclass(frozen=True)
class SystemConfig:
    mode: RunMode
    mapper_idle_wait_s: Annotated[float, Range("(0, inf)")]
    async_waits_for_local_ba: bool
    report_poor_poses: bool
    report_edgelet_held_poses: bool
    mapper_wait_max_s: Annotated[float, Range("(0, inf)")]
    map_checkpoint_keyframes: Annotated[int, Range("[0, inf)")]
    output_flush_s: Annotated[float, Range("(0, inf)")]
    latency_window_frames: Annotated[int, Range("[1, inf)")]
    background_nice: Annotated[int, Range("[0, 19]")]
    warm_up_frames: Annotated[int, Range("[0, inf)")]


@dataclass(frozen=True)
class Config:
    image: ImageConfig
    patch: PatchConfig
    tracker: TrackerConfig
    rotation: RotationConfig
    reloc: RelocConfig
    capture: CaptureConfig
    init: InitConfig
    mapper: MapperConfig
    bundle: BundleConfig
    eval: EvalConfig
    gtmap: GtMapConfig
    synthetic: SyntheticConfig
    system: SystemConfig
    calibrate: CalibrateConfig
    synth_calibration: SynthCalibrationConfig
    viewer: ViewerConfig
    ar: ArConfig
    model_selection: ModelSelectionConfig
    edgelets: EdgeletConfig
    normals: NormalsConfig
    tracks: TracksConfig

    def replace(self, **changes: str) -> Config:
        """A copy with ``section.key`` values changed, e.g. ``cfg.replace(**{"tracker.max_patches": 500})``."""
        from .loader import apply_overrides  # the loader builds Configs; sections must not import it at load

        return apply_overrides(self, [f"{k}={_yaml_scalar(v)}" for k, v in changes.items()])


def _yaml_scalar(v) -> str:
    """``v`` as the YAML an override parses back to it: strings quoted, infinities as ``.inf``."""
    if isinstance(v, str):
        return repr(v)
    if isinstance(v, float) and math.isinf(v):
        return ".inf" if v > 0 else "-.inf"
    return str(v)
