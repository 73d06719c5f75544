"""The tracker: PTAM §5's per-frame procedure against a map snapshot.

1. pyramid + FAST corners (keyframe preparation), prior pose from the motion model (§5.1), its rotation
   replaced by the small-blurry-image rotation estimate when enabled (Agility §6, §8); a frame that prior leaves
   in doubt (rapid, or not good by §5.6's check) is tracked again from the motion model's own prior, and the pass
   whose pose keeps more of its patches is used (``rotation.motion_model_fallback``, :mod:`.tracking_pass`);
2. project all good map points, keep the potentially visible set, compute each one's warp and search level
   (§5.2, §5.3); drop the patches the expected motion blur smears past recognition (:mod:`.patch_blur`), none
   under rapid motion when the image kept its corners (:mod:`.blur_evidence`);
3.–4. coarse stage (§5.5): up to ``coarse_points`` points at the coarsest search levels, searched over a large
   radius with sub-pixel refinement, then a pose update — skipped when the camera is nearly stationary (§6.5),
   when disabled, or when too few coarse points are visible or found (PTAM code);
5. fine stage: every remaining top-level point and a random subset of the others, up to ``max_patches``
   measurements in all, re-projected with the coarse pose, searched over a tight radius, with sub-pixel
   refinement from ``fine_subpix_min_level`` up (every level with ``fine_subpix_all_levels``, but under rapid motion);
6. final pose from the coarse and fine measurements together (§5.4; with ``smear_variance`` > 0 an integer match
   is less certain along its patch's expected smear, :func:`.patch_blur.smear_axes`), then motion model and
   quality (§5.6); failure detection is suspended while the prior rotates faster than ``reloc.rapid_rotation_deg``
   (Agility §8). With ``model_selection.enabled`` the final pose is the better of [R|t] and [R|t ≤ t_max] by GRIC
   (Gauglitz et al. §4.2, :mod:`.model_selection`); panorama features (rays) constrain the rotation only.

The tracker reads the immutable :class:`~ptam.map.snapshot.MapSnapshot` it is given and takes no lock. Per-point
work is vectorised or in numba kernels; the Python code here handles whole arrays only.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..errors import InputError
from ..geometry import se3
from ..image.pyramid import Pyramid
from ..map.snapshot import MapSnapshot
from ..patch.finder import PatchFinder
from ..patch.warp import PixelVectorCache, search_warps, template_matrices
from ..vocabulary import PoseModel
from .blur_evidence import shows_blur
from .edgelet_tracking import EdgeletFrame, EdgeletTracker
from .model_selection import select_pose_model
from .motion_model import FrameGaps, MotionModel
from .patch_blur import patch_blur, patch_smear, searchable, smear_axes, unless_blurred
from .pose_update import update_pose
from .projection import project_points
from .quality import GOOD, TrackingQuality
from .rotation_estimator import RotationEstimator
from .track_result import (
    MODEL,
    POSE,
    PREPARE,
    PROJECT,
    SEARCH,
    Batch,
    Clock,
    KeyframeCandidate,
    Measurements,
    TrackResult,
)
from .tracking_pass import Candidates, TrackingPass


class Tracker:
    def __init__(self, camera: CameraModel, cfg: Config):
        self.camera = camera
        self.cfg = cfg
        self.tcfg = cfg.tracker
        self.n_levels = cfg.image.levels
        self._cam = camera.kernel_params()
        self.motion = MotionModel(cfg.tracker)
        self.gaps = FrameGaps(cfg.tracker.motion_period_window)
        self.rotation = RotationEstimator(camera, cfg.rotation)
        self.quality = TrackingQuality(cfg.tracker)
        self.finder = PatchFinder(cfg.patch)
        self.edgelets = EdgeletTracker(camera, cfg)  # Agility §5
        self._edges = EdgeletFrame.empty()
        self._pixel_vectors = PixelVectorCache(camera)
        self.reset()

    # -- state -------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Forget pose, velocity, quality history and the keyframe counter."""
        self.T_cw = np.eye(4)
        self.motion.reset()
        self.gaps.reset()
        self.rotation.reset()
        self.quality.reset()
        self.frames_since_keyframe = 0
        self.scene_depth: tuple[float | None, float] = (None, 0.0)
        self._force_coarse = False
        self._rapid = False
        self._sharp = False
        self._model = PoseModel.GENERAL
        self._rng = np.random.default_rng(self.tcfg.shuffle_seed)

    def set_pose(self, T_cw: np.ndarray, recovered: bool = False) -> None:
        """Start from ``T_cw`` at rest. ``recovered``: the pose is approximate (a relocalisation), so the next
        frame runs the coarse stage with ``recovery_coarse_factor`` × points and radius (PTAM code)."""
        self.T_cw = np.array(T_cw, dtype=np.float64)
        self.motion.reset()
        self.rotation.reset()  # the previous small image belongs to another pose
        self._force_coarse = bool(recovered)
        if recovered:  # a recovered pose earns trust before it may make keyframes (PTAM §6.2's 20 frames)
            self.frames_since_keyframe = 0

    def rebase(self, T_cw: np.ndarray, recovered: bool, tracking: Tracker) -> None:
        """Start from ``T_cw`` in another map's frame where ``tracking`` followed the same camera up to this frame
        (a panorama before the first map, Gauglitz §4.3): as :meth:`set_pose` after :meth:`reset`, but with its
        velocity (in the camera's frame, so the same in any world frame) and its last small image."""
        self.reset()
        self.set_pose(T_cw, recovered)
        self.motion.velocity = tracking.motion.velocity.copy()
        self.rotation.previous = tracking.rotation.previous

    def keyframe_added(self) -> None:
        """The mapper accepted this frame as a keyframe: restart the frames-since-keyframe count."""
        self.frames_since_keyframe = 0

    # -- per frame ---------------------------------------------------------------------------------------
    def track(self, image_or_frame, snapshot: MapSnapshot | None, pyramid: Pyramid | None = None) -> TrackResult:
        """Track one frame (a grey uint8 image or a capture ``Frame``) against ``snapshot``; ``pyramid``: the
        frame's pyramid if already built (relocalisation needs it first)."""
        clock = Clock()
        image = getattr(image_or_frame, "image", image_or_frame)
        index = int(getattr(image_or_frame, "index", -1))
        timestamp = float(getattr(image_or_frame, "timestamp", 0.0))
        if np.shape(image)[:2] != (self.camera.height, self.camera.width):
            raise InputError(
                f"tracker: image of shape {np.shape(image)} does not match the camera's "
                f"{self.camera.width}x{self.camera.height}"
            )
        if pyramid is None:
            pyramid = Pyramid.build(image, self.cfg.image)
        rotation = self.rotation.estimate(pyramid) if self.cfg.rotation.enabled else None
        self._sharp = not shows_blur(pyramid, snapshot, self.T_cw, self.tcfg.blur_corner_fraction)
        clock.lap(PREPARE)

        T_start = self.T_cw
        gap = self.gaps.frames(timestamp)
        late = gap > self.tcfg.motion_gap_frames  # frames were missed: the prior is less certain
        frames = min(gap, self.tcfg.motion_max_gap_frames)
        force, self._force_coarse = self._force_coarse or late, False
        keep = self.cfg.rotation.keep_axial_velocity
        run = self._stages(pyramid, snapshot, self.motion.predict(T_start, rotation, keep, frames), force, clock)
        if rotation is not None and self.cfg.rotation.motion_model_fallback and (run.rapid or not run.good(self.tcfg)):
            # Agility §9.3: clutter (a hand) can turn the rotation estimate; PTAM §5.2's prior is the other guess.
            alt = self._stages(pyramid, snapshot, self.motion.predict(T_start, None, keep, frames), force, clock)
            if alt.holds(self.cfg) and alt.found_fraction > run.found_fraction:
                run = alt
            else:
                self.motion.predict(T_start, rotation, keep, frames)  # the kept pass's prior again
        self._rapid, self._edges, self._model = run.rapid, run.edges, run.model
        res = self._finish(index, timestamp, pyramid, snapshot, T_start, run, clock, frames)
        return dataclasses.replace(res, in_doubt=force) if force else res

    def _stages(self, pyramid, snapshot, T, force: bool, clock) -> TrackingPass:
        """Steps 2-5 from the prior pose ``T`` (the motion model's prior set accordingly)."""
        self._rapid = self._prior_is_rapid()
        self._gamma = self.motion.exposure_motion(0.0 if self._rapid and self._sharp else self.tcfg.exposure_fraction)
        batch = Batch()
        self._edges = EdgeletFrame.empty()
        self._model = PoseModel.GENERAL
        did_coarse = False
        n_visible = 0
        if snapshot is not None and snapshot.n_points and snapshot.n_keyframes:
            ids, uv, level, M = self._potentially_visible(snapshot, T)
            n_visible = len(ids)
            ids, uv, level, M = self._unblurred(snapshot, T, ids, uv, level, M)
            order = np.lexsort((self._rng.random(len(ids)), -level))  # coarsest first, shuffled within a level
            cand = Candidates(ids[order], uv[order], level[order], M[order], np.zeros(len(ids), dtype=bool))
            clock.lap(PROJECT)
            T, did_coarse = self._coarse_stage(pyramid, snapshot, cand, T, force, batch, clock)
            T = self._fine_stage(pyramid, snapshot, cand, T, did_coarse, batch, clock)
        return TrackingPass(T, batch, did_coarse, n_visible, self._rapid, self._edges, self._model)

    def _coarse_stage(self, pyramid, snapshot, cand, T, force: bool, batch, clock) -> tuple[np.ndarray, bool]:
        """PTAM §5.5; code: only with more than coarse_min_points candidates at the two coarsest levels, and a
        pose update only when at least coarse_min_points of them were found, or (Agility §8) enough edgelets
        with a wide search range."""
        cfg = self.tcfg
        factor = cfg.recovery_coarse_factor if force else 1
        try_coarse = force or (
            cfg.coarse_enabled and cfg.coarse_points > 0 and self.motion.scaled_speed >= cfg.coarse_min_velocity
        )
        high = np.flatnonzero(cand.level >= cfg.coarse_min_level)
        if not (try_coarse and len(high) > cfg.coarse_min_points):
            return T, False
        sel = high[: cfg.coarse_points * factor]
        cand.taken[sel] = True
        ids, level = cand.ids[sel], cand.level[sel]
        radius = cfg.coarse_radius_px * factor
        m = self._search(pyramid, snapshot, ids, level, cand.M[sel], cand.uv[sel], radius, np.ones(len(sel), bool))
        batch.add(ids, level, m, coarse=True)
        edges = self.edgelets.search(pyramid.levels[0], snapshot, T, self._gamma, coarse=True)  # §8
        clock.lap(SEARCH)
        # Agility §8: edgelets measured with the coarse points count towards the update; blur that hides the
        # coarse points leaves edges (Fig. 5).
        with_edges = self.edgelets.usable(edges)
        did_coarse = bool(m.found.sum() >= cfg.coarse_min_points) or with_edges
        if did_coarse:
            X, Xw = snapshot.features(ids[m.found])
            xy, lv = m.xy[m.found], level[m.found]
            smear = self._smear_axes(T, X, Xw, lv, m.subpix[m.found])
            if with_edges:
                T, _, _ = self.edgelets.final_pose(T, X, Xw, xy, lv, smear, not self._rapid, edges, coarse=True)
            else:
                T, _ = update_pose(self._cam, cfg, T, X, xy, lv, True, not self._rapid, Xw, smear=smear)
        clock.lap(POSE)
        return T, did_coarse

    def _fine_stage(self, pyramid, snapshot, cand, T, did_coarse: bool, batch, clock) -> np.ndarray:
        """PTAM code: every remaining point of the top level, then a random subset of the others up to
        max_patches measurements in all, re-projected after a coarse stage; sub-pixel refinement only from
        fine_subpix_min_level up (§5.5: "a high-level subset"), or on every level with fine_subpix_all_levels.
        The final pose uses both stages (§5.4)."""
        cfg = self.tcfg
        rest = np.flatnonzero(~cand.taken)
        top = rest[cand.level[rest] == self.n_levels - 1]
        others = rest[cand.level[rest] < self.n_levels - 1]
        budget = max(cfg.max_patches - int(cand.taken.sum()) - len(top), 0)
        sel = np.concatenate([top, others[self._rng.permutation(len(others))[:budget]]])
        ids, level = cand.ids[sel], cand.level[sel]
        uv_sel = cand.uv[sel]
        if did_coarse and len(sel):
            w, h = self.camera.width, self.camera.height
            proj, _ = project_points(self._cam, w, h, cfg, T, snapshot.X, ids, keep_invisible=True)
            uv_sel = proj.uv
        clock.lap(PROJECT)
        radius = cfg.fine_radius_after_coarse_px if did_coarse else cfg.fine_radius_px
        ptam_subpix = level >= cfg.fine_subpix_min_level
        # Every level, unless blur is expected (Agility §8): a smeared patch does not converge and would be lost.
        extra = ~ptam_subpix & (cfg.fine_subpix_all_levels and not self._rapid)
        m = unless_blurred(
            self._search(pyramid, snapshot, ids, level, cand.M[sel], uv_sel, radius, ptam_subpix | extra), extra, cfg
        )
        batch.add(ids, level, m, coarse=False)
        self._edges = self.edgelets.search(pyramid.levels[0], snapshot, T, self._gamma)
        clock.lap(SEARCH)
        found, xy = batch.found(), batch.xy()
        with_edges = self.edgelets.usable(self._edges)
        if found.any() or with_edges:  # under heavy blur the edgelets alone may hold the pose (Agility §5)
            X, Xw = snapshot.features(batch.ids()[found])
            level = batch.level()[found]
            smear = self._smear_axes(T, X, Xw, level, batch.subpix()[found])
            if with_edges:
                T, w, self._edges = self.edgelets.final_pose(
                    T, X, Xw, xy[found], level, smear, not self._rapid, self._edges
                )
            elif self.cfg.model_selection.enabled:
                T, w = self._select_model(snapshot, T, X, Xw, xy[found], level, smear)
                clock.lap(MODEL)
            else:
                T, w = update_pose(self._cam, cfg, T, X, xy[found], level, False, not self._rapid, Xw, smear=smear)
            batch.weights[found] = w
        return T

    def _select_model(self, snapshot, T, X, Xw, xy, level, smear):
        """Gauglitz et al. §4.2, §6.2: [R|t] against [R|t ≤ t_max] about the nearest keyframe's centre, where
        t_max = α_max·depth and α_max = r_fine / f keeps the panorama's rays inside the fine search radius."""
        nearest, _ = snapshot.nearest_keyframe(T)
        depth = self.scene_depth[0] or snapshot.keyframes[nearest].scene_depth_mean
        t_max = self.tcfg.fine_radius_px / self.camera.fx * depth
        c_ref = snapshot.camera_centres[nearest]
        choice = select_pose_model(
            self.camera,
            self._cam,
            self.tcfg,
            self.cfg.model_selection,
            T,
            X,
            Xw,
            xy,
            level,
            not self._rapid,
            c_ref,
            t_max,
            smear,
        )
        self._model = choice.model
        return choice.T_cw, choice.weights

    # -- helpers -----------------------------------------------------------------------------------------
    def _potentially_visible(self, snapshot, T):
        """Step 2: visible good points with a valid warp -> ids, level-0 pixels, search level, template matrix."""
        proj = project_points(
            self._cam, self.camera.width, self.camera.height, self.tcfg, T, snapshot.X, snapshot.good_point_indices
        )
        right, down = self._pixel_vectors.vectors(snapshot)
        A, level = search_warps(self._cam, self.cfg.patch, self.n_levels, T, proj.Xc, right[proj.ids], down[proj.ids])
        ok = level >= 0
        return proj.ids[ok], proj.uv[ok], level[ok], template_matrices(A[ok], level[ok])

    def _smear_axes(self, T, X, Xw, level, refined):
        """The found matches' smear axes for the pose update (``patch_blur.smear_axes``), from the smear their
        patches are expected to suffer at pose T; none for ``refined`` (sub-pixel) matches, which align the whole
        template and so sit at the smear's centre. An integer match (PTAM's search: the best FAST corner in the
        radius, kept where the refinement is not run or, in a blurred frame, did not converge) is wherever the
        smear left a corner."""
        if self.tcfg.smear_variance == 0.0:  # PTAM's measurements: nothing to predict
            return np.zeros((len(X), 2))
        smear = patch_smear(self.camera, T, X, Xw, self._gamma)
        smear[refined] = 0.0
        return smear_axes(smear, level, self.tcfg.smear_variance)

    def _unblurred(self, snapshot, T, ids, uv, level, M):
        """The candidates whose expected blur leaves their patch searchable (``patch_blur``)."""
        X, w = snapshot.features(ids)
        blur = patch_blur(self.camera, T, X, w, self._gamma)
        ok = searchable(blur, level, self.cfg.patch.size, self.tcfg.blur_gate_patch_widths)
        return ids[ok], uv[ok], level[ok], M[ok]

    def _search(self, pyramid, snapshot, ids, level, M, uv, radius, subpix):
        return self.finder.find(
            pyramid,
            snapshot.kf_images,
            snapshot.source_kf[ids],
            snapshot.source_level[ids],
            snapshot.source_xy[ids],
            M,
            level,
            uv,
            float(radius),
            subpix,
        )

    def _finish(self, index, timestamp, pyramid, snapshot, T_start, run: TrackingPass, clock, frames):
        T, batch, did_coarse, n_visible = run.T, run.batch, run.did_coarse, run.n_visible
        meas = Measurements(
            batch.ids(), batch.xy(), batch.level(), batch.found(), batch.subpix(), batch.weights > 0, batch.coarse()
        )
        attempted, coarse = batch.attempted(), meas.coarse
        att_l = np.bincount(meas.level[attempted], minlength=self.n_levels)
        found_l = np.bincount(meas.level[meas.found], minlength=self.n_levels)
        depth_mean, depth_sigma = self._update_scene_depth(snapshot, T, meas)
        if depth_mean is not None:
            self.motion.update(T_start, T, depth_mean, frames)
        reloc = self.cfg.reloc
        rapid = reloc.suspend_when_rapid and self._rapid
        nearest, dist = snapshot.nearest_keyframe(T) if snapshot is not None else (-1, float("inf"))
        travel = (snapshot.view_travel(T) if snapshot is not None else float("inf")) * self.camera.fx
        # PTAM code (IsDistanceToNearestKeyFrameExcessive): a pose far beyond every keyframe, in units of the
        # initial stereo baseline, is not trusted however many patches matched.
        too_far = dist > self.tcfg.max_keyframe_distance_baselines * self.cfg.init.baseline_m
        # Gauglitz et al. §4.3–§4.4: quality is the fraction of the selected model's inliers (PTAM §5.6 counts
        # found patches, which a wrong pose on repetitive texture still finds), and tracking is lost when the
        # inliers fall below the count that lets a model be estimated at all.
        ms = self.cfg.model_selection
        inl = meas.found & meas.inlier
        few = bool(ms.enabled and np.count_nonzero(inl) < ms.min_sfm_points)
        far = too_far and np.isfinite(dist)
        judged = np.bincount(meas.level[inl], minlength=self.n_levels) if ms.enabled else found_l
        quality = self.quality.assess(att_l, judged, suspend=rapid, too_far=far, too_few_inliers=few)
        self.T_cw = T
        self.frames_since_keyframe += 1
        depth = float("nan") if depth_mean is None else depth_mean
        kf = KeyframeCandidate(quality == GOOD, self.frames_since_keyframe, nearest, dist, depth, depth_sigma, travel)
        clock.lap(POSE)
        return TrackResult(
            frame_index=index,
            timestamp=timestamp,
            T_cw=T.copy(),
            quality=quality,
            lost=self.quality.lost,
            did_coarse=did_coarse,
            n_visible=n_visible,
            n_coarse_attempted=int(attempted[coarse].sum()),
            n_coarse_found=int(meas.found[coarse].sum()),
            n_fine_attempted=int(attempted[~coarse].sum()),
            n_fine_found=int(meas.found[~coarse].sum()),
            attempted_per_level=att_l,
            found_per_level=found_l,
            measurements=meas,
            pyramid=pyramid,
            timings=clock.timings(),
            keyframe=kf,
            rapid_motion=bool(rapid),
            sharp=self._sharp,
            pose_model=self._model,
            n_edgelets_attempted=self._edges.n_attempted,
            n_edgelets_found=self._edges.n_found,
            edgelets=self._edges,
        )

    def _prior_is_rapid(self) -> bool:
        """The prior rotates the camera faster than ``reloc.rapid_rotation_deg`` a frame (Agility §8)."""
        return bool(
            np.degrees(np.linalg.norm(self.motion.prior_rotation_per_frame())) > self.cfg.reloc.rapid_rotation_deg
        )

    def _update_scene_depth(self, snapshot, T, meas) -> tuple[float | None, float]:
        """Mean scene depth of the found points at the final pose (PTAM code, end of TrackMap); before any frame
        had enough, the keyframes' own depth means."""
        if meas.found.sum() > self.tcfg.scene_depth_min_points:
            z = se3.transform(T, snapshot.X[meas.point_ids[meas.found]])[:, 2]
            self.scene_depth = (float(z.mean()), float(z.std()))
        elif self.scene_depth[0] is None and snapshot is not None and snapshot.n_keyframes:
            self.scene_depth = (float(np.mean([k.scene_depth_mean for k in snapshot.keyframes])), 0.0)
        return self.scene_depth
