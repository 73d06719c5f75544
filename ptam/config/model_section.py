"""Config section of model selection (Gauglitz et al. TVCG 2013 §4.2–§4.3, §6): rotation-only motion and panoramas."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from ..vocabulary import EssentialMethod
from .interval import Range


@dataclass(frozen=True)
class ModelSelectionConfig:
    enabled: bool
    min_sfm_points: Annotated[int, Range("[4, inf)")]
    em_iterations: Annotated[int, Range("[1, inf)")]
    min_sigma: Annotated[float, Range("(0, inf)")]
    inlier_ratio_bounds: Annotated[list[float], Range("(0, 1)", length=2)]
    panorama_kf_travel: Annotated[float, Range("(0, 1]")]
    turn_keyframes_unspaced: bool
    keyframe_by_angle: bool
    rays_gain_depth: bool
    adjust_panorama_keyframes: bool
    initialisation_free: bool
    rotation_check_method: EssentialMethod
    rotation_check_max_matches: Annotated[int, Range("[5, inf)")]
