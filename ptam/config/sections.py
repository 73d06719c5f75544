"""Typed configuration sections: one frozen dataclass per section of ``configs/default.yaml``.

The dataclasses carry types only; every default value lives in the YAML file, commented with its source.
``load_config`` overlays ``--config`` files and ``--set section.key=value`` overrides, rejecting unknown
keys (with a "did you mean" suggestion) and values of the wrong type with a :class:`ConfigError`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..vocabulary import (
    ArScene,
    CalibrationLoss,
    ChessboardDetector,
    DistortionModel,
    EssentialMethod,
    RunMode,
    SearchLevelRule,
)


@dataclass(frozen=True)
class ImageConfig:
    levels: int
    fast_thresholds: list[int]
    shi_tomasi_half_box: int
    shi_tomasi_min: float
    candidate_border_px: int


@dataclass(frozen=True)
class PatchConfig:
    size: int
    max_ssd_per_pixel: float
    det_min: float
    det_max: float
    subpix_iterations: int
    subpix_converge_px: float
    search_level_rule: SearchLevelRule


@dataclass(frozen=True)
class TrackerConfig:
    max_patches: int
    coarse_points: int
    coarse_min_points: int
    coarse_radius_px: float
    coarse_min_velocity: float
    fine_radius_px: float
    fine_radius_after_coarse_px: float
    irls_iterations: int
    relinearise_every: int
    min_tukey_sigma: float
    quality_good: float
    quality_lost: float
    lost_frames: int
    max_keyframe_distance_baselines: float
    valid_radius_factor: float
    motion_decay: float
    motion_blend: float
    coarse_enabled: bool
    coarse_min_level: int
    fine_subpix_min_level: int
    recovery_coarse_factor: int
    pose_prior: float
    tukey_override_enabled: bool
    tukey_override_after: int
    tukey_override_sigma_sq_coarse: float
    tukey_override_sigma_sq_fine: float
    image_margin_px: float
    scene_depth_min_points: int
    quality_large_min_level: int
    quality_large_min_attempted: int
    shuffle_seed: int


@dataclass(frozen=True)
class RotationConfig:
    enabled: bool
    blur_sigma: float
    iterations: int
    intensity_offset: bool
    keep_axial_velocity: bool
    sample_radius_px: float


@dataclass(frozen=True)
class RelocConfig:
    enabled: bool
    blur_sigma: float
    iterations: int
    max_score: float
    suspend_when_rapid: bool
    rapid_rotation_deg: float


@dataclass(frozen=True)
class CaptureConfig:
    default_fps: float
    camera_size: list[int]
    camera_fps: float
    video_missing_frames_tolerance: int
    dc1394_mode: str
    dc1394_iso_speed: int
    dc1394_dma_buffers: int
    dc1394_frame_timeout_s: float


@dataclass(frozen=True)
class InitConfig:
    max_trails: int
    trail_half_patch: int
    trail_search_radius_px: int
    trail_max_ssd: int
    trail_backward_tolerance_px2: int
    min_trails: int
    auto_min_disparity_rel_focal: float
    min_matches: int
    min_inliers: int
    essential_method: EssentialMethod
    essential_threshold_px: float
    ransac_confidence: float
    ransac_seed: int
    gric_lambda3: float
    inlier_sigmas: float
    triangulation_max_error_px: float
    min_parallax_deg: float
    max_ba_rounds: int
    track_frames_between: bool
    baseline_m: float
    plane_ransac_iterations: int
    plane_inlier_distance: float
    plane_seed: int


@dataclass(frozen=True)
class MapperConfig:
    kf_min_frames: int
    kf_max_queue: int
    kf_dist_wiggle_mult: float
    candidate_min_dist_px: float
    epipolar_far_depth_mult: float
    epipolar_min_z: float
    epipolar_min_line_length: float
    epipolar_along_margin: float
    epipolar_along_clip: float
    epipolar_box_samples: int
    epipolar_band_px: float
    refind_radius_px: int
    bad_point_min_outliers: int
    local_ba_min_keyframes: int
    outlier_min_good_measurements: int


@dataclass(frozen=True)
class EvalConfig:
    max_time_diff_s: float
    rpe_delta_s: float


@dataclass(frozen=True)
class GtMapConfig:
    kf_every: int
    max_points: int
    min_distance_px: float
    planarity_tol: float
    seed: int


@dataclass(frozen=True)
class BundleConfig:
    lambda_initial: float
    lambda_decrease: float
    lambda_increase_initial: float
    lambda_increase_growth: float
    lambda_max: float
    max_iterations: int
    converge_squared_update: float
    min_tukey_sigma: float
    local_neighbours: int
    dense_max_cameras: int


@dataclass(frozen=True)
class SyntheticConfig:
    cache_dir: str
    render_threads: int


@dataclass(frozen=True)
class SystemConfig:
    mode: RunMode
    mapper_idle_wait_s: float


@dataclass(frozen=True)
class CalibrateConfig:
    detector: ChessboardDetector
    fast_check: bool
    subpix_window_frac: float
    subpix_window_max_px: int
    frame_step: int
    min_view_change: float
    max_candidates: int
    max_views: int
    min_views: int
    loss: CalibrationLoss
    loss_scale_px: float
    max_nfev: int
    omega_search: list[float]
    omega_search_views: int
    omega_search_nfev: int
    outlier_factor: float
    outlier_min_rms_px: float
    max_refits: int
    selection_grid: int
    coverage_grid: int
    min_tilt_deg: float


@dataclass(frozen=True)
class SynthCalibrationConfig:
    board: list[int]
    square_m: float
    margin_squares: float
    views: int
    size: list[int]
    model: DistortionModel
    focal_rel: float
    omega: float
    radtan: list[float]
    tilt_max_deg: float
    roll_max_deg: float
    fill: list[float]
    border_px: float
    edge_samples: int
    black: float
    white: float
    background: float
    blur_sigma_px: float
    noise_sigma: float
    seed: int
    fps: float


@dataclass(frozen=True)
class ViewerConfig:
    queue_size: int
    grpc_port: int
    web_port: int
    serve_start_timeout_s: float
    server_memory_limit: str
    jpeg_quality: int
    ar_image_lossless: bool
    thumbnail_level: int
    frustum_depth: float
    camera_frustum_depth: float
    point_radius_ui: float
    measurement_radius_px: float
    failed_radius_px: float
    grid_spacing: float
    grid_half_cells: int
    status_interval_s: float


@dataclass(frozen=True)
class ArConfig:
    scene: ArScene
    queue_frames: int
    init_buffer_frames: int
    plane_refresh_growth: float
    grid_half_cells: int
    grid_spacing: float
    grid_samples_per_cell: int
    grid_line_px: int
    grid_fade_frames: list[int]
    game_grid_alpha: float
    light_direction: list[float]
    ambient: float
    diffuse: float
    specular: float
    shininess: float
    eye_radius: float
    eye_pupil_deg: float
    eye_iris_deg: float
    eye_turn_rate: float
    shadow_radius_rel: float
    shadow_softness_rel: float
    shadow_alpha: float
    target_count: int
    target_radius: float
    target_speed: float
    target_turn_rate: float
    target_wander_deg: float
    arena_half_size: float
    max_step_s: float
    dwell_frames: int
    burst_frames: int
    crosshair_radius: float
    seed: int


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
