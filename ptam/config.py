"""Typed configuration: one dataclass per section, values from ``configs/default.yaml``.

The dataclasses carry types only; every default value lives in the YAML file, commented with its source.
``load_config`` overlays ``--config`` files and ``--set section.key=value`` overrides, rejecting unknown
keys (with a "did you mean" suggestion) and values of the wrong type with a :class:`ConfigError`.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import os
import typing
from dataclasses import dataclass, fields

import yaml

from .errors import ConfigError
from .resources import resource_path


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
    search_level_rule: str


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
    essential_method: str
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
    mode: str
    mapper_idle_wait_s: float


@dataclass(frozen=True)
class CalibrateConfig:
    detector: str
    fast_check: bool
    subpix_window_frac: float
    subpix_window_max_px: int
    frame_step: int
    min_view_change: float
    max_candidates: int
    max_views: int
    min_views: int
    loss: str
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
    model: str
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
    scene: str
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
        return apply_overrides(self, [f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}"
                                      for k, v in changes.items()])


_CHOICES = {("ar", "scene"): ("eyes", "game", "grid", "off"),
            ("calibrate", "detector"): ("sb", "classic"),
            ("calibrate", "loss"): ("linear", "huber", "soft_l1", "cauchy"),
            ("synth_calibration", "model"): ("fov", "radtan"),
            ("system", "mode"): ("async", "sync", "realtime"),
            ("patch", "search_level_rule"): ("closest", "ptam_code"),
            ("init", "essential_method"): ("default", "magsac", "accurate", "prosac", "ransac")}


@functools.cache
def _section_types() -> dict[str, type]:
    hints = typing.get_type_hints(Config)
    return {f.name: hints[f.name] for f in fields(Config)}


@functools.cache
def _field_types(section_cls) -> dict[str, type]:
    return typing.get_type_hints(section_cls)


def _suggest(name: str, options) -> str:
    close = difflib.get_close_matches(name, list(options), n=1, cutoff=0.5)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _coerce(where: str, value, typ):
    """Check ``value`` against a field type; ints are accepted where floats are expected."""
    origin = typing.get_origin(typ)
    if origin is list:
        (inner,) = typing.get_args(typ)
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"config: {where} must be a list of {inner.__name__}, got {value!r}")
        return [_coerce(f"{where}[{i}]", v, inner) for i, v in enumerate(value)]
    if typ is bool:
        if isinstance(value, bool):
            return value
    elif typ is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif typ is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif typ is str:
        if isinstance(value, str):
            return value
    raise ConfigError(f"config: {where} must be {typ.__name__}, got {value!r}")


def _merge(base: dict, overlay, source: str) -> None:
    if not isinstance(overlay, dict):
        raise ConfigError(f"{source}: expected a mapping of sections")
    sections = _section_types()
    for sec, values in overlay.items():
        if sec not in sections:
            raise ConfigError(f"{source}: unknown config section '{sec}'{_suggest(str(sec), sections)}")
        if not isinstance(values, dict):
            raise ConfigError(f"{source}: section '{sec}' must be a mapping")
        for key, v in values.items():
            _set(base, sec, key, v, source)


def _set(base: dict, sec: str, key: str, value, source: str) -> None:
    sections = _section_types()
    if sec not in sections:
        raise ConfigError(f"{source}: unknown config section '{sec}'{_suggest(sec, sections)}")
    hints = _field_types(sections[sec])
    if key not in hints:
        options = [f"{sec}.{k}" for k in hints] + [f"{s}.{k}" for s in sections
                                                    for k in _field_types(sections[s])]
        raise ConfigError(f"{source}: unknown config key '{sec}.{key}'{_suggest(f'{sec}.{key}', options)}")
    value = _coerce(f"{sec}.{key}", value, hints[key])
    choices = _CHOICES.get((sec, key))
    if choices and value not in choices:
        raise ConfigError(f"config: {sec}.{key} must be one of {', '.join(choices)}, got {value!r}")
    base.setdefault(sec, {})[key] = value


def _build(raw: dict) -> Config:
    sections = _section_types()
    built = {}
    for sec, cls in sections.items():
        values = raw.get(sec, {})
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise ConfigError(f"config: section '{sec}' is missing {', '.join(missing)}")
        built[sec] = cls(**values)
    return Config(**built)


def _read_yaml(path: str):
    if not os.path.isfile(path):
        raise ConfigError(f"config file not found: {path}")
    try:
        with open(path) as f:
            return yaml.safe_load(f) or {}
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError(f"cannot read config {path}: {str(e).splitlines()[0]}") from None


def parse_override(text: str) -> tuple[str, str, object]:
    """``section.key=value`` -> (section, key, value), the value parsed as YAML (so 3, 0.5, [1, 2], true)."""
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise ConfigError(f"--set expects section.key=value, got '{text}'")
    lhs, rhs = text.split("=", 1)
    sec, key = lhs.strip().split(".", 1)
    try:
        value = yaml.safe_load(rhs) if rhs.strip() else ""
    except yaml.YAMLError:
        value = rhs
    return sec, key, value


def _to_raw(cfg: Config) -> dict:
    return {f.name: dataclasses.asdict(getattr(cfg, f.name)) for f in fields(Config)}


def apply_overrides(cfg: Config, overrides: list[str]) -> Config:
    raw = _to_raw(cfg)
    for text in overrides:
        sec, key, value = parse_override(text)
        _set(raw, sec, key, value, "--set")
    return _build(raw)


def load_config(config_files: list[str] | None = None, overrides: list[str] | None = None) -> Config:
    """Defaults from configs/default.yaml, then each ``--config`` file, then each ``--set`` override."""
    raw: dict = {}
    default = str(resource_path("configs/default.yaml"))
    _merge(raw, _read_yaml(default), default)
    for path in config_files or []:
        _merge(raw, _read_yaml(path), path)
    cfg = _build(raw)
    return apply_overrides(cfg, overrides or [])


def default_config() -> Config:
    return load_config()
