"""What the tracker returns per frame (PTAM §5): the measurements, stage timings (Table 1), the keyframe
candidate for the mapper (§6.2), and the bookkeeping the tracker uses to build them."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..geometry import se3
from ..image.pyramid import Pyramid
from ..vocabulary import PoseModel, Quality
from .edgelet_tracking import EdgeletFrame


@dataclass(frozen=True)
class Measurements:
    """Every patch searched this frame. ``point_ids`` index the snapshot's points; ``xy`` is the level-0 match
    (valid where ``found``), ``level`` the search level, ``subpix`` whether it was refined, ``inlier`` whether it
    kept a non-zero Tukey weight in the final pose update, ``coarse`` whether it was a coarse-stage patch."""

    point_ids: np.ndarray
    xy: np.ndarray
    level: np.ndarray
    found: np.ndarray
    subpix: np.ndarray
    inlier: np.ndarray
    coarse: np.ndarray


@dataclass(frozen=True)
class StageTimings:
    """Milliseconds per stage, as in PTAM Table 1."""

    keyframe_preparation: float
    feature_projection: float
    patch_search: float
    pose_update: float
    model_selection: float  # both pose models and their GRIC (Gauglitz et al. §4.2); 0 when disabled
    total: float


@dataclass(frozen=True)
class KeyframeCandidate:
    """What the mapper needs for PTAM §6.2's keyframe decision (the decision itself is the mapper's):
    tracking quality, frames since the last keyframe, the nearest keyframe (by camera centre) and its distance,
    and the mean/σ depth of the points found this frame (PTAM code: only updated from more than
    ``scene_depth_min_points`` points, else the previous values)."""

    quality_good: bool
    frames_since_keyframe: int
    nearest_keyframe: int
    nearest_keyframe_distance: float
    mean_scene_depth: float
    scene_depth_sigma: float
    view_travel_px: float = float("inf")  # Gauglitz §4.3: image travel of the view since the nearest keyframe view

    @property
    def distance_over_depth(self) -> float:
        return self.nearest_keyframe_distance / self.mean_scene_depth


@dataclass(frozen=True)
class TrackResult:
    frame_index: int
    timestamp: float
    T_cw: np.ndarray
    quality: Quality
    lost: bool
    did_coarse: bool
    n_visible: int
    n_coarse_attempted: int
    n_coarse_found: int
    n_fine_attempted: int
    n_fine_found: int
    attempted_per_level: np.ndarray
    found_per_level: np.ndarray
    measurements: Measurements
    pyramid: Pyramid
    timings: StageTimings
    keyframe: KeyframeCandidate
    rapid_motion: bool = False  # failure detection was suspended this frame (Agility §8)
    sharp: bool = False  # the image kept its corners (``blur_evidence``): under rapid motion no blur was expected
    in_doubt: bool = False  # tracked from an approximate prior (a recovery or missed frames): no keyframe from it
    pose_model: PoseModel = PoseModel.GENERAL  # the motion model chosen (Gauglitz et al. §4.2)
    n_edgelets_attempted: int = 0  # edgelets searched this frame (Agility §5.1)
    n_edgelets_found: int = 0  # ... and found by the sawtooth search
    edgelets: EdgeletFrame | None = None  # the fine stage's edgelet searches (for the viewer)

    @property
    def T_wc(self) -> np.ndarray:
        return se3.inv(self.T_cw)

    @property
    def n_attempted(self) -> int:
        return self.n_coarse_attempted + self.n_fine_attempted

    @property
    def n_found(self) -> int:
        return self.n_coarse_found + self.n_fine_found

    @property
    def inlier_fraction(self) -> float:
        """Patches that kept a Tukey weight in the final pose, of those attempted."""
        m = self.measurements
        return float(np.count_nonzero(m.found & m.inlier)) / max(self.n_attempted, 1)

    @property
    def tracked(self) -> bool:
        """The pose is usable: quality good or poor (PTAM §5.6)."""
        return self.quality != Quality.BAD


PREPARE, PROJECT, SEARCH, POSE = "keyframe_preparation", "feature_projection", "patch_search", "pose_update"
MODEL = "model_selection"


class Clock:
    """Wall time per stage, accumulated lap by lap."""

    def __init__(self):
        self.start = self.t = time.perf_counter()
        self.ms = {PREPARE: 0.0, PROJECT: 0.0, SEARCH: 0.0, POSE: 0.0, MODEL: 0.0}

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.ms[stage] += 1e3 * (now - self.t)
        self.t = now

    def timings(self) -> StageTimings:
        return StageTimings(**self.ms, total=1e3 * (self.t - self.start))


class Batch:
    """The patches of both stages: point ids, search levels, match results and final Tukey weights."""

    def __init__(self):
        self.parts: list[tuple] = []
        self.weights = np.zeros(0)

    def add(self, ids, level, matches, coarse: bool) -> None:
        self.parts.append((ids, level, matches, np.full(len(ids), coarse)))
        self.weights = np.zeros(sum(len(p[0]) for p in self.parts))

    def _cat(self, get, dtype, shape=()):
        if not self.parts:
            return np.zeros((0, *shape), dtype)
        return np.concatenate([get(p) for p in self.parts]).astype(dtype, copy=False)

    def ids(self):
        return self._cat(lambda p: p[0], np.int64)

    def level(self):
        return self._cat(lambda p: p[1], np.int8)

    def coarse(self):
        return self._cat(lambda p: p[3], bool)

    def attempted(self):
        return self._cat(lambda p: p[2].attempted, bool)

    def found(self):
        return self._cat(lambda p: p[2].found, bool)

    def subpix(self):
        return self._cat(lambda p: p[2].subpix, bool)

    def xy(self):
        return self._cat(lambda p: p[2].xy, np.float64, (2,))
