"""When the tracker hands a frame to the mapper as a keyframe (PTAM §6.2, Gauglitz et al. §4.3), and the wait
for the mapper on a replayed file."""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..geometry import se3
from ..mapping.map_maker import KeyframeRequest, MapMaker
from ..tracking.tracker import Tracker
from ..vocabulary import PoseModel, Quality, RunMode
from .ray_check import RayCheck
from .run_stats import RunStats


class KeyframePolicy:
    """Mixed into :class:`~ptam.system.core.System`, whose state it uses (declared here for the type checker)."""

    camera: CameraModel
    cfg: Config
    mode: RunMode
    localize_only: bool
    mapper: MapMaker
    tracker: Tracker
    stats: RunStats
    _good_streak: int
    _ray_check: RayCheck
    _wake: threading.Event
    _stepped: threading.Event
    _mapper_error: BaseException | None
    _thread: threading.Thread | None

    if TYPE_CHECKING:  # defined by the Tracks mixin

        def _merge_tracks(self) -> bool: ...

    def _maybe_add_keyframe(self, res, snapshot) -> bool:
        """PTAM §6.2 (code ``Tracker::NeedNewKeyFrame`` + ``MapMaker::NeedNewKeyFrame``); frames of rapid motion
        are tracked but not used for map-building (Agility §10) unless sharp (``_rapid_but_mappable``), nor are
        frames tracked from an approximate prior (after a recovery or missed frames), nor a good frame right after
        poor ones: its prior was a doubtful pose, and the tracker can settle on a wrong pose that still finds texture
        (desk_blur: a keyframe 300 mm off, the first good frame after ten poor ones). Trust is earned as a
        relocalisation's is: ``reloc.confirm_frames`` good frames in a row. ``snapshot``: the map the frame was
        tracked against."""
        m = self.cfg.mapper
        kf = res.keyframe
        turned = self._view_turned(res)
        panorama = turned and res.pose_model == PoseModel.ROTATION
        if panorama:  # Gauglitz et al. §4.3: the keyframe's kind follows the model; [R|0] has no baseline
            due = True
        elif res.pose_model == PoseModel.ROTATION:
            due = False
        else:
            due = turned or self._baseline_grown(res)
        if (
            self.localize_only
            or (res.rapid_motion and not self._rapid_but_mappable(res))
            or res.in_doubt
            or self._ray_check.doubting
            or self._good_streak < self.cfg.reloc.confirm_frames
            or not (
                res.quality == Quality.GOOD
                and self._spaced(kf.frames_since_keyframe, turned, snapshot)
                and self.mapper.queue_size() < m.kf_max_queue
                and due
            )
        ):
            return False
        meas = res.measurements
        f = meas.found
        self.mapper.add_keyframe(
            KeyframeRequest(
                res.pyramid,
                self._about_parent(res.T_cw) if panorama else res.T_cw.copy(),
                res.timestamp,
                meas.point_ids[f],
                meas.xy[f],
                meas.level[f],
                kf.mean_scene_depth,
                kf.scene_depth_sigma,
                panorama=panorama,
            )
        )
        self.tracker.keyframe_added()
        self.stats.keyframes_requested += 1
        if self.mode == RunMode.SYNC:
            self.mapper.run_until_idle()
            while self._merge_tracks():  # Gauglitz §5.3, where async mode's mapper would do it: when idle
                self.mapper.run_until_idle()
        else:
            self._wake.set()
            if self.mode == RunMode.ASYNC and self.cfg.system.async_waits_for_local_ba:
                self._wait_for_mapper()
        return True

    def _baseline_grown(self, res) -> bool:
        """Enough parallax for an SfM keyframe. Gauglitz et al. §4.3: the median triangulation angle of the frame's
        inliers between the nearest keyframe's centre and the frame's exceeds the first stereo pair's (baseline over
        depth, PTAM's "wiggle", times ``mapper.kf_dist_wiggle_mult``); a camera moving along its view gains distance
        but little angle. PTAM §6.2 (``model_selection.keyframe_by_angle: false``): distance over mean depth."""
        kf = res.keyframe
        if not self.cfg.model_selection.keyframe_by_angle:
            return self.mapper.need_new_keyframe(kf.nearest_keyframe_distance, kf.mean_scene_depth)
        snap = self.mapper.snapshot
        meas = res.measurements
        if snap is None or kf.nearest_keyframe < 0:
            return False
        ids = meas.point_ids[meas.found & meas.inlier]
        ids = ids[~snap.ray[ids]]
        if not len(ids):
            return False
        X = snap.X[ids]
        to_frame = X - se3.inv(res.T_cw)[:3, 3]
        to_keyframe = X - snap.camera_centres[kf.nearest_keyframe]
        cos = np.einsum("ij,ij->i", to_frame, to_keyframe) / (
            np.linalg.norm(to_frame, axis=1) * np.linalg.norm(to_keyframe, axis=1)
        )
        angle = float(np.median(np.arccos(np.clip(cos, -1.0, 1.0))))
        return angle > self.cfg.mapper.kf_dist_wiggle_mult * self.mapper.wiggle_depth_normalised

    def _spaced(self, frames_since_keyframe: int, turned: bool, snapshot) -> bool:
        """Enough time since the last keyframe: PTAM §6.2's twenty frames; or, for a view turning away from every
        keyframe (Gauglitz et al. §4.3 condition 3, whose condition 2 gives no time), the image travel itself once
        the mapper has integrated the previous keyframe (the travel is measured against the snapshot's keyframes)
        and adjusted it locally (the next one is placed against a refined map, at the pace the mapper keeps). A
        turn at hand-held speed leaves the map within twenty frames (desk_corner: 15). The travel must have been
        measured against that keyframe too: in ``realtime`` the mapper can integrate it while the next frame is
        tracked against the snapshot before it, which then asked for a second keyframe a frame after the first
        (desk_pan: four such pairs in a run)."""
        if frames_since_keyframe > self._min_frames():
            return True
        ms = self.cfg.model_selection
        if not (turned and ms.turn_keyframes_unspaced and self.mapper.keyframes_settled()):
            return False
        current = self.mapper.snapshot
        return snapshot is not None and current is not None and snapshot.n_keyframes == current.n_keyframes

    def _min_frames(self) -> int:
        """PTAM §6.2's twenty frames, counted at its 30 Hz camera (``mapper.kf_min_frames_fps``, PTAM §7): the
        spacing paces the mapper in time, so a 10 fps source waits 7 frames, a 60 fps one 40. The rate is the
        one the tracker sees (the median gap between the frames it tracked)."""
        m = self.cfg.mapper
        period = self.tracker.gaps.period
        if not (m.kf_min_frames_fps > 0.0 and period):
            return m.kf_min_frames
        return round(m.kf_min_frames / (m.kf_min_frames_fps * period))

    def _rapid_but_mappable(self, res) -> bool:
        """A rapid frame that may still become a keyframe. Agility §10 keeps rapid frames out of the map for their
        motion blur; one whose image kept its corners (``res.sharp``, the tracker's ``blur_evidence``) was exposed
        too briefly to blur, and a turn filmed at 10 fps is rapid throughout: without its keyframes the map cannot
        follow it.
        It must also have been posed by more than the coarse stage's few features (``tracker.coarse_points``,
        PTAM §5.5): a pose from a dozen coarse patches is good by PTAM's fraction but does not place a keyframe
        (desk_corner at 10 fps, 6° a frame, with blur expected: one 70 mm off from 11 of 12 patches)."""
        m = res.measurements
        inliers = int(np.count_nonzero(m.found & m.inlier))
        return inliers > self.cfg.tracker.coarse_points and res.sharp

    def _about_parent(self, T_cw: np.ndarray) -> np.ndarray:
        """A panorama keyframe's pose. Its rotation was estimated about the nearest keyframe's centre: when that
        is a panorama keyframe, the new one takes its centre exactly (Gauglitz et al. §4.3, [R|t]_prev ∘ [R|0]),
        so a panorama group shares one centre instead of drifting by up to t_max per keyframe; the first of a
        group keeps the centre tracked against the 3-D map."""
        snap = self.mapper.snapshot
        assert snap is not None  # a keyframe is only requested against a map
        d = np.linalg.norm(snap.camera_centres - se3.inv(T_cw)[:3, 3], axis=1)
        nearest = int(np.argmin(d))
        if not snap.keyframes[nearest].panorama:
            return T_cw.copy()
        T = T_cw.copy()
        T[:3, 3] = -T[:3, :3] @ snap.camera_centres[nearest]
        return T

    def _view_turned(self, res) -> bool:
        """Gauglitz et al. §4.3, condition 3 for rotation-only motion: the view has travelled far enough from every
        keyframe's (``model_selection.panorama_kf_travel`` of the image width). Under [R|0] the keyframe is a
        panorama keyframe; under [R|t] (the camera has also moved beyond t_max) an SfM keyframe, whose baseline
        lets the map grow where the camera now looks."""
        ms = self.cfg.model_selection
        return ms.enabled and res.keyframe.view_travel_px > ms.panorama_kf_travel * self.camera.width

    def _wait_for_mapper(self) -> None:
        """``async`` on a recorded source: the tracker would otherwise run several times faster than real time,
        far ahead of a map that is not extended yet. It waits until the mapper has integrated the keyframe and
        adjusted it locally (PTAM §6.3), then runs on beside the global adjustment and the data-association
        refinement; ``realtime`` (live) never waits."""
        deadline = time.perf_counter() + self.cfg.system.mapper_wait_max_s
        while not self.mapper.keyframes_settled() and time.perf_counter() < deadline:
            if self._mapper_error is not None or self._thread is None:
                return
            self._stepped.wait(self.cfg.system.mapper_idle_wait_s)
            self._stepped.clear()
