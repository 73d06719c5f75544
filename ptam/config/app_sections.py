"""Config sections of the applications around the SLAM core: calibration, the viewer and the AR layer."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from ..vocabulary import ArScene, CalibrationLoss, ChessboardDetector, DistortionModel, RrdFooter
from .interval import Range


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
    rrd_footer: RrdFooter
    jpeg_quality: Annotated[int, Range("[0, 100]")]
    ar_image_lossless: bool
    ar_max_fps: Annotated[float, Range("[0, inf)")]
    thumbnail_level: Annotated[int, Range("[0, inf)")]
    frustum_depth: Annotated[float, Range("(0, inf)")]
    camera_frustum_depth: Annotated[float, Range("(0, inf)")]
    point_radius_ui: Annotated[float, Range("(0, inf)")]
    measurement_radius_px: Annotated[float, Range("(0, inf)")]
    failed_radius_px: Annotated[float, Range("(0, inf)")]
    edgelet_radius_ui: Annotated[float, Range("(0, inf)")]
    edgelet_radius_px: Annotated[float, Range("(0, inf)")]
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
