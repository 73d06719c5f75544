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
from dataclasses import dataclass, field
from typing import Annotated

from ..vocabulary import (
    ArScene,
    CalibrationLoss,
    ChessboardDetector,
    DistortionModel,
    EssentialMethod,
    RunMode,
    SearchLevelRule,
)

_ENDS = {"inf": math.inf, "-inf": -math.inf, "pi": math.pi}


@dataclass(frozen=True)
class Range:
    """The allowed values of a numeric config field, e.g. ``Range("(0, inf)")`` or ``Range("[0, 1]")``."""

    interval: str
    length: int | None = None  # list fields: the number of elements, if fixed
    lo: float = field(init=False)
    hi: float = field(init=False)
    lo_closed: bool = field(init=False)
    hi_closed: bool = field(init=False)

    def __post_init__(self) -> None:
        text = self.interval.strip()
        ends = [e.strip() for e in text[1:-1].split(",")]
        if text[:1] not in ("[", "(") or text[-1:] not in ("]", ")") or len(ends) != 2:
            raise ValueError(f"Range: expected an interval like '[0, inf)', got {self.interval!r}")
        lo, hi = (_ENDS[e] if e in _ENDS else float(e) for e in ends)
        if not lo < hi:
            raise ValueError(f"Range: empty interval {self.interval!r}")
        for name, value in (("lo", lo), ("hi", hi), ("lo_closed", text[0] == "["), ("hi_closed", text[-1] == "]")):
            object.__setattr__(self, name, value)

    def __contains__(self, value: float) -> bool:
        above = value >= self.lo if self.lo_closed else value > self.lo
        below = value <= self.hi if self.hi_closed else value < self.hi
        return bool(above and below)  # NaN: both comparisons are false

    def __str__(self) -> str:
        return self.interval


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
    mapper_wait_max_s: Annotated[float, Range("(0, inf)")]
    map_checkpoint_keyframes: Annotated[int, Range("[0, inf)")]
    output_flush_s: Annotated[float, Range("(0, inf)")]
    latency_window_frames: Annotated[int, Range("[1, inf)")]


@dataclass(frozen=True)
class CalibrateConfig:
    detector: ChessboardDetector
    fast_check: bool
    subpix_window_frac: Annotated[float, Range("(0, 1]")]
    subpix_window_max_px: Annotated[int, Range("[1, inf)")]
    frame_step: Annotated[int, Range("[1, inf)")]
    min_view_change: Annotated[float, Range("[0, 1]")]
    max_candidates: Annotated[int, Range("[1, inf)")]
    max_views: Annotated[int, Range("[1, inf)")]
    min_views: Annotated[int, Range("[1, inf)")]
    loss: CalibrationLoss
    loss_scale_px: Annotated[float, Range("(0, inf)")]
    max_nfev: Annotated[int, Range("[1, inf)")]
    omega_search: Annotated[list[float], Range("(0, inf)", length=3)]
    omega_search_views: Annotated[int, Range("[1, inf)")]
    omega_search_nfev: Annotated[int, Range("[1, inf)")]
    outlier_factor: Annotated[float, Range("[1, inf)")]
    outlier_min_rms_px: Annotated[float, Range("[0, inf)")]
    max_refits: Annotated[int, Range("[0, inf)")]
    selection_grid: Annotated[int, Range("[1, inf)")]
    coverage_grid: Annotated[int, Range("[1, inf)")]
    min_tilt_deg: Annotated[float, Range("[0, 90]")]


@dataclass(frozen=True)
class SynthCalibrationConfig:
    board: Annotated[list[int], Range("[2, inf)", length=2)]
    square_m: Annotated[float, Range("(0, inf)")]
    margin_squares: Annotated[float, Range("[0, inf)")]
    views: Annotated[int, Range("[1, inf)")]
    size: Annotated[list[int], Range("[1, inf)", length=2)]
    model: DistortionModel
    focal_rel: Annotated[float, Range("(0, inf)")]
    omega: Annotated[float, Range("(0, pi)")]
    radtan: Annotated[list[float], Range("(-inf, inf)", length=5)]
    tilt_max_deg: Annotated[float, Range("[0, 90)")]
    roll_max_deg: Annotated[float, Range("[0, 180]")]
    fill: Annotated[list[float], Range("(0, 1]", length=2)]
    border_px: Annotated[float, Range("[0, inf)")]
    edge_samples: Annotated[int, Range("[1, inf)")]
    black: Annotated[float, Range("[0, 255]")]
    white: Annotated[float, Range("[0, 255]")]
    background: Annotated[float, Range("[0, 255]")]
    blur_sigma_px: Annotated[float, Range("[0, inf)")]
    noise_sigma: Annotated[float, Range("[0, inf)")]
    seed: Annotated[int, Range("[0, inf)")]
    fps: Annotated[float, Range("(0, inf)")]


@dataclass(frozen=True)
class ViewerConfig:
    queue_size: Annotated[int, Range("[1, inf)")]
    grpc_port: Annotated[int, Range("[1, 65535]")]
    web_port: Annotated[int, Range("[1, 65535]")]
    serve_start_timeout_s: Annotated[float, Range("(0, inf)")]
    server_memory_limit: str
    jpeg_quality: Annotated[int, Range("[0, 100]")]
    ar_image_lossless: bool
    thumbnail_level: Annotated[int, Range("[0, inf)")]
    frustum_depth: Annotated[float, Range("(0, inf)")]
    camera_frustum_depth: Annotated[float, Range("(0, inf)")]
    point_radius_ui: Annotated[float, Range("(0, inf)")]
    measurement_radius_px: Annotated[float, Range("(0, inf)")]
    failed_radius_px: Annotated[float, Range("(0, inf)")]
    grid_spacing: Annotated[float, Range("(0, inf)")]
    grid_half_cells: Annotated[int, Range("[1, inf)")]
    status_interval_s: Annotated[float, Range("[0, inf)")]


@dataclass(frozen=True)
class ArConfig:
    scene: ArScene
    queue_frames: Annotated[int, Range("[1, inf)")]
    init_buffer_frames: Annotated[int, Range("[0, inf)")]
    plane_refresh_growth: Annotated[float, Range("[1, inf)")]
    grid_half_cells: Annotated[int, Range("[1, inf)")]
    grid_spacing: Annotated[float, Range("(0, inf)")]
    grid_samples_per_cell: Annotated[int, Range("[1, inf)")]
    grid_line_px: Annotated[int, Range("[1, inf)")]
    grid_fade_frames: Annotated[list[int], Range("[0, inf)", length=2)]
    game_grid_alpha: Annotated[float, Range("[0, 1]")]
    light_direction: Annotated[list[float], Range("(-inf, inf)", length=3)]
    ambient: Annotated[float, Range("[0, 1]")]
    diffuse: Annotated[float, Range("[0, 1]")]
    specular: Annotated[float, Range("[0, 1]")]
    shininess: Annotated[float, Range("[0, inf)")]
    eye_radius: Annotated[float, Range("(0, inf)")]
    eye_pupil_deg: Annotated[float, Range("[0, 180]")]
    eye_iris_deg: Annotated[float, Range("[0, 180]")]
    eye_turn_rate: Annotated[float, Range("[0, inf)")]
    shadow_radius_rel: Annotated[float, Range("[0, inf)")]
    shadow_softness_rel: Annotated[float, Range("[0, inf)")]
    shadow_alpha: Annotated[float, Range("[0, 1]")]
    target_count: Annotated[int, Range("[0, inf)")]
    target_radius: Annotated[float, Range("(0, inf)")]
    target_speed: Annotated[float, Range("[0, inf)")]
    target_turn_rate: Annotated[float, Range("[0, inf)")]
    target_wander_deg: Annotated[float, Range("[0, 180]")]
    arena_half_size: Annotated[float, Range("(0, inf)")]
    max_step_s: Annotated[float, Range("(0, inf)")]
    dwell_frames: Annotated[int, Range("[0, inf)")]
    burst_frames: Annotated[int, Range("[0, inf)")]
    crosshair_radius: Annotated[float, Range("[0, inf)")]
    seed: Annotated[int, Range("[0, inf)")]


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

    def replace(self, **changes: str) -> Config:
        """A copy with ``section.key`` values changed, e.g. ``cfg.replace(**{"tracker.max_patches": 500})``."""
        from .loader import apply_overrides  # the loader builds Configs; sections must not import it at load

        return apply_overrides(self, [f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}" for k, v in changes.items()])
