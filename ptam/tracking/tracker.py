"""The tracker: PTAM §5's per-frame procedure against a map snapshot.

1. pyramid + FAST corners (keyframe preparation), prior pose from the motion model (§5.1), its rotation
   replaced by the small-blurry-image rotation estimate when enabled (Agility §6, §8);
2. project all good map points, keep the potentially visible set, compute each one's warp and search level
   (§5.2, §5.3);
3.–4. coarse stage (§5.5): up to ``coarse_points`` points at the coarsest search levels, searched over a large
   radius with sub-pixel refinement, then a pose update — skipped when the camera is nearly stationary (§6.5),
   when disabled, or when too few coarse points are visible or found (PTAM code);
5. fine stage: every remaining top-level point and a random subset of the others, up to ``max_patches``
   measurements in all, re-projected with the coarse pose, searched over a tight radius, with sub-pixel
   refinement from ``fine_subpix_min_level`` up;
6. final pose from the coarse and fine measurements together (§5.4), then motion model and quality (§5.6);
   failure detection is suspended while the prior rotates faster than ``reloc.rapid_rotation_deg`` (Agility §8).

The tracker reads the immutable :class:`~ptam.map.snapshot.MapSnapshot` it is given and takes no lock. Per-point
work is vectorised or in numba kernels; the Python code here handles whole arrays only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geometry import se3
from ..image.pyramid import Pyramid
from ..patch.finder import PatchFinder
from ..patch.warp import patch_pixel_vectors, search_warps, template_matrices
from .motion_model import MotionModel
from .pose_update import update_pose
from .projection import project_points
from .quality import BAD, GOOD, TrackingQuality
from .rotation_estimator import RotationEstimator


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

    @property
    def distance_over_depth(self) -> float:
        return self.nearest_keyframe_distance / self.mean_scene_depth


@dataclass(frozen=True)
class TrackResult:
    frame_index: int
    timestamp: float
    T_cw: np.ndarray
    quality: str
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
    def tracked(self) -> bool:
        """The pose is usable: quality good or poor (PTAM §5.6)."""
        return self.quality != BAD


PREPARE, PROJECT, SEARCH, POSE = "keyframe_preparation", "feature_projection", "patch_search", "pose_update"


class _Clock:
    """Wall time per stage, accumulated lap by lap."""

    def __init__(self):
        self.start = self.t = time.perf_counter()
        self.ms = {PREPARE: 0.0, PROJECT: 0.0, SEARCH: 0.0, POSE: 0.0}

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.ms[stage] += 1e3 * (now - self.t)
        self.t = now

    def timings(self) -> StageTimings:
        return StageTimings(**self.ms, total=1e3 * (self.t - self.start))


class _Batch:
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


class Tracker:
    def __init__(self, camera, cfg):
        self.camera = camera
        self.cfg = cfg
        self.tcfg = cfg.tracker
        self.n_levels = cfg.image.levels
        self._cam = camera.kernel_params()
        self.motion = MotionModel(cfg.tracker)
        self.rotation = RotationEstimator(camera, cfg.rotation)
        self.quality = TrackingQuality(cfg.tracker)
        self.finder = PatchFinder(cfg.patch)
        self._pixel_vectors_of = None
        self._pixel_vectors = (np.zeros((0, 3)), np.zeros((0, 3)))
        self.reset()

    # -- state -------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget pose, velocity, quality history and the keyframe counter."""
        self.T_cw = np.eye(4)
        self.motion.reset()
        self.rotation.reset()
        self.quality.reset()
        self.frames_since_keyframe = 0
        self.scene_depth = (None, 0.0)
        self._force_coarse = False
        self._rng = np.random.default_rng(self.tcfg.shuffle_seed)

    def set_pose(self, T_cw: np.ndarray, recovered: bool = False) -> None:
        """Start from ``T_cw`` at rest. ``recovered``: the pose is approximate (a relocalisation), so the next
        frame runs the coarse stage with ``recovery_coarse_factor`` × points and radius (PTAM code)."""
        self.T_cw = np.array(T_cw, dtype=np.float64)
        self.motion.reset()
        self.rotation.reset()  # the previous small image belongs to another pose
        self._force_coarse = bool(recovered)

    def keyframe_added(self) -> None:
        """The mapper accepted this frame as a keyframe: restart the frames-since-keyframe count."""
        self.frames_since_keyframe = 0

    # -- per frame ---------------------------------------------------------------------------------------
    def track(self, image_or_frame, snapshot, pyramid: Pyramid | None = None) -> TrackResult:
        """Track one frame (a grey uint8 image or a capture ``Frame``) against ``snapshot``; ``pyramid``: the
        frame's pyramid if already built (relocalisation needs it first)."""
        clock = _Clock()
        image = getattr(image_or_frame, "image", image_or_frame)
        index = int(getattr(image_or_frame, "index", -1))
        timestamp = float(getattr(image_or_frame, "timestamp", 0.0))
        cfg = self.tcfg
        if np.shape(image)[:2] != (self.camera.height, self.camera.width):
            raise InputError(f"tracker: image of shape {np.shape(image)} does not match the camera's "
                             f"{self.camera.width}x{self.camera.height}")
        if pyramid is None:
            pyramid = Pyramid.build(image, self.cfg.image)
        rotation = self.rotation.estimate(pyramid) if self.cfg.rotation.enabled else None
        clock.lap(PREPARE)

        T_start = self.T_cw
        T = self.motion.predict(T_start, rotation, self.cfg.rotation.keep_axial_velocity)
        force, self._force_coarse = self._force_coarse, False
        batch = _Batch()
        did_coarse = False
        n_visible = 0
        if snapshot is not None and snapshot.n_points and snapshot.n_keyframes:
            ids, uv, level, M = self._potentially_visible(snapshot, T)
            n_visible = len(ids)
            order = np.lexsort((self._rng.random(len(ids)), -level))  # coarsest first, shuffled within a level
            ids, uv, level, M = ids[order], uv[order], level[order], M[order]
            taken = np.zeros(len(ids), dtype=bool)
            clock.lap(PROJECT)

            # Coarse stage (PTAM §5.5; code: only with more than coarse_min_points candidates at the two
            # coarsest levels, and a pose update only when at least coarse_min_points of them were found).
            factor = cfg.recovery_coarse_factor if force else 1
            try_coarse = force or (cfg.coarse_enabled and cfg.coarse_points > 0
                                   and self.motion.scaled_speed >= cfg.coarse_min_velocity)
            high = np.flatnonzero(level >= cfg.coarse_min_level)
            if try_coarse and len(high) > cfg.coarse_min_points:
                sel = high[: cfg.coarse_points * factor]
                taken[sel] = True
                m = self._search(pyramid, snapshot, ids[sel], level[sel], M[sel], uv[sel],
                                 cfg.coarse_radius_px * factor, np.ones(len(sel), dtype=bool))
                batch.add(ids[sel], level[sel], m, coarse=True)
                clock.lap(SEARCH)
                if m.found.sum() >= cfg.coarse_min_points:
                    did_coarse = True
                    T, _ = update_pose(self._cam, cfg, T, snapshot.X[ids[sel][m.found]], m.xy[m.found],
                                       level[sel][m.found], coarse=True)
                clock.lap(POSE)

            # Fine stage (PTAM code): every remaining point of the top level, then a random subset of the others
            # up to max_patches measurements in all, re-projected after a coarse stage; sub-pixel refinement
            # only from fine_subpix_min_level up (§5.5: "a high-level subset").
            rest = np.flatnonzero(~taken)
            top = rest[level[rest] == self.n_levels - 1]
            others = rest[level[rest] < self.n_levels - 1]
            budget = max(cfg.max_patches - int(taken.sum()) - len(top), 0)
            sel = np.concatenate([top, others[self._rng.permutation(len(others))[:budget]]])
            uv_sel = uv[sel]
            if did_coarse and len(sel):
                proj, _ = project_points(self._cam, self.camera.width, self.camera.height, cfg, T, snapshot.X,
                                         ids[sel], keep_invisible=True)
                uv_sel = proj.uv
            clock.lap(PROJECT)
            radius = cfg.fine_radius_after_coarse_px if did_coarse else cfg.fine_radius_px
            m = self._search(pyramid, snapshot, ids[sel], level[sel], M[sel], uv_sel, radius,
                             level[sel] >= cfg.fine_subpix_min_level)
            batch.add(ids[sel], level[sel], m, coarse=False)
            clock.lap(SEARCH)

            found, xy = batch.found(), batch.xy()
            if found.any():
                T, w = update_pose(self._cam, cfg, T, snapshot.X[batch.ids()[found]], xy[found],
                                   batch.level()[found], coarse=False)
                batch.weights[found] = w

        return self._finish(index, timestamp, pyramid, snapshot, T_start, T, batch, did_coarse, n_visible, clock)

    # -- helpers -----------------------------------------------------------------------------------------
    def _potentially_visible(self, snapshot, T):
        """Step 2: visible good points with a valid warp -> ids, level-0 pixels, search level, template matrix."""
        proj = project_points(self._cam, self.camera.width, self.camera.height, self.tcfg, T, snapshot.X,
                              snapshot.good_point_indices)
        right, down = self._patch_vectors(snapshot)
        A, level = search_warps(self._cam, self.cfg.patch, self.n_levels, T, proj.Xc, right[proj.ids],
                                down[proj.ids])
        ok = level >= 0
        return proj.ids[ok], proj.uv[ok], level[ok], template_matrices(A[ok], level[ok])

    def _patch_vectors(self, snapshot):
        # Snapshots are immutable, so the vectors are recomputed only when the mapper publishes a new one.
        if self._pixel_vectors_of is not snapshot:
            self._pixel_vectors = patch_pixel_vectors(self.camera, snapshot.kf_T_cw, snapshot.X, snapshot.normal,
                                                      snapshot.source_kf, snapshot.source_level, snapshot.source_xy)
            self._pixel_vectors_of = snapshot
        return self._pixel_vectors

    def _search(self, pyramid, snapshot, ids, level, M, uv, radius, subpix):
        return self.finder.find(pyramid, snapshot.kf_images, snapshot.source_kf[ids], snapshot.source_level[ids],
                                snapshot.source_xy[ids], M, level, uv, float(radius), subpix)

    def _finish(self, index, timestamp, pyramid, snapshot, T_start, T, batch, did_coarse, n_visible, clock):
        cfg = self.tcfg
        meas = Measurements(batch.ids(), batch.xy(), batch.level(), batch.found(), batch.subpix(),
                            batch.weights > 0, batch.coarse())
        attempted, coarse = batch.attempted(), meas.coarse
        att_l = np.bincount(meas.level[attempted], minlength=self.n_levels)
        found_l = np.bincount(meas.level[meas.found], minlength=self.n_levels)

        # Mean scene depth of the found points at the final pose (PTAM code, end of TrackMap); before any frame
        # had enough, the keyframes' own depth means.
        if meas.found.sum() > cfg.scene_depth_min_points:
            z = se3.transform(T, snapshot.X[meas.point_ids[meas.found]])[:, 2]
            self.scene_depth = (float(z.mean()), float(z.std()))
        elif self.scene_depth[0] is None and snapshot is not None and snapshot.n_keyframes:
            self.scene_depth = (float(np.mean([k.scene_depth_mean for k in snapshot.keyframes])), 0.0)
        depth_mean, depth_sigma = self.scene_depth

        if depth_mean is not None:
            self.motion.update(T_start, T, depth_mean)
        reloc = self.cfg.reloc
        prior_deg = np.degrees(np.linalg.norm(self.motion.prior[3:]))
        rapid = reloc.suspend_when_rapid and prior_deg > reloc.rapid_rotation_deg
        nearest, dist = -1, float("inf")
        if snapshot is not None and snapshot.n_keyframes:
            d = np.linalg.norm(snapshot.camera_centres - se3.inv(T)[:3, 3], axis=1)
            nearest = int(np.argmin(d))
            dist = float(d[nearest])
        # PTAM code (IsDistanceToNearestKeyFrameExcessive): a pose far beyond every keyframe, in units of the
        # initial stereo baseline, is not trusted however many patches matched.
        too_far = dist > cfg.max_keyframe_distance_baselines * self.cfg.init.baseline_m
        quality = self.quality.assess(att_l, found_l, suspend=rapid, force_bad=too_far and np.isfinite(dist))
        self.T_cw = T
        self.frames_since_keyframe += 1
        kf = KeyframeCandidate(quality == GOOD, self.frames_since_keyframe, nearest, dist,
                               float("nan") if depth_mean is None else depth_mean, depth_sigma)
        clock.lap(POSE)
        return TrackResult(
            frame_index=index, timestamp=timestamp, T_cw=T.copy(), quality=quality, lost=self.quality.lost,
            did_coarse=did_coarse, n_visible=n_visible,
            n_coarse_attempted=int(attempted[coarse].sum()), n_coarse_found=int(meas.found[coarse].sum()),
            n_fine_attempted=int(attempted[~coarse].sum()), n_fine_found=int(meas.found[~coarse].sum()),
            attempted_per_level=att_l, found_per_level=found_l, measurements=meas, pyramid=pyramid,
            timings=clock.timings(), keyframe=kf, rapid_motion=bool(rapid))
