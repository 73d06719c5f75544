"""The mapping thread's work (PTAM §6, Fig. 2): keyframe integration, new points, bundle adjustment and
data-association refinement, in PTAM's order of priority.

``MapMaker`` holds the map and does one unit of work per :meth:`step`; ``ptam.system`` runs it in its own
thread (async) or to idle after each keyframe (sync). Only this object mutates the ``Map``; after every
change it publishes a fresh immutable :class:`MapSnapshot` by swapping one reference, which the tracker reads
without a lock. Keyframes arrive through a deque (thread-safe appends/pops in CPython); a queued keyframe
aborts a running bundle adjustment (PTAM §6.3).
"""

from __future__ import annotations

import dataclasses
import logging
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..image.pyramid import Pyramid
from ..map.keyframe import KeyFrame
from ..map.map import SRC_EPIPOLAR, SRC_REFIND, SRC_ROOT, SRC_TRACKER, Map
from ..map.snapshot import MapSnapshot
from ..patch.finder import PatchFinder
from .bad_points import TrackerFeedback
from .bundle import Bundle, BundleResult
from .edgelet_map_ba import edgelet_ba_input, handle_edgelet_outliers, keep_edgelets
from .edgelet_measurements import rebuild_visibility_tables
from .edgelet_work import EdgeletWork
from .epipolar import epipolar_matches, unit_plane_corners
from .gauge import hold_scale
from .local_ba import local_sets
from .normals import NormalEstimator
from .panorama import add_ray_points, free_candidates, held_panorama_keyframes, new_point_levels, triangulate_rays
from .refind import refind_points
from .unfinished_outliers import UnfinishedOutliers

if TYPE_CHECKING:
    from ..camera.model import CameraModel
    from ..config import Config

log = logging.getLogger("ptam.mapper")


@dataclass(frozen=True)
class KeyframeRequest:
    """A frame the tracker hands over as a new keyframe, with its own measurements (PTAM §6.2)."""

    pyramid: Pyramid
    T_cw: np.ndarray
    timestamp: float
    point_ids: np.ndarray
    xy: np.ndarray
    level: np.ndarray
    depth_mean: float
    depth_sigma: float
    panorama: bool = False  # Gauglitz et al. §4.3: taken under rotation-only motion


class MapMaker:
    def __init__(self, camera: CameraModel, cfg: Config, map_: Map | None = None) -> None:
        self.camera = camera
        self.cfg = cfg
        self.bundle = Bundle(camera, cfg.bundle)
        self.finder = PatchFinder(cfg.patch)
        self.normals = NormalEstimator(camera, cfg)  # Gauglitz §5.4, the lowest-priority job
        self.edgelets = EdgeletWork(camera, cfg)  # Agility §4.3-§4.4
        self.map = map_ if map_ is not None else Map()
        self.queue: deque[KeyframeRequest] = deque()
        self.snapshot: MapSnapshot | None = None
        # Keyframes handed over (tracker's thread) and integrated, in the published snapshot (mapper's thread).
        self._handed_over = self._integrated = self._published_integrated = 0
        self._plane_corners: dict[tuple[int, int], np.ndarray] = {}
        self._never_retry: dict[int, np.ndarray] = {}  # keyframe -> bool per point: do not search again
        self._failure_queue: list[tuple[int, int]] = []
        self._new_points: list[tuple[np.ndarray, int]] = []  # (new point ids, next keyframe to search)
        self.feedback = TrackerFeedback(cfg.mapper)  # PTAM code HandleBadPoints
        self.unfinished_outliers = UnfinishedOutliers(cfg.mapper.unfinished_ba_outliers)
        self.recent_converged = True
        self.full_converged = True
        # Keyframe spacing (PTAM code mdWiggleScaleDepthNormalized): initial baseline / first keyframe's mean depth.
        self.wiggle_depth_normalised = 0.0
        # ba_running: "local" or "global" while a bundle adjustment runs, else None (read by the viewer).
        self.stats: dict[str, Any] = dict(local_ba=[], global_ba=[], ba_running=None, keyframes_added=0)
        self.stats["panorama_keyframes_added"] = 0
        self.ready = False  # set once a usable map exists; the mapper thread idles until then
        self.reset_requested = False  # the map is corrupt; the system starts again (PTAM code)
        if len(self.map.keyframes):
            self.ready = True
            self.wiggle_depth_normalised = cfg.init.baseline_m / self.map.keyframes[0].scene_depth_mean
            if cfg.edgelets.enabled and not self.map.edgelets.tables:  # a map from a file (Agility §5.2)
                rebuild_visibility_tables(self.map, cfg)
            self.publish()

    # -- interface for the tracker's thread -----------------------------------------------------------------
    @property
    def initialised(self) -> bool:
        return self.ready

    def queue_size(self) -> int:
        return len(self.queue)

    def need_new_keyframe(self, nearest_distance: float, depth_mean: float) -> bool:
        """PTAM code ``MapMaker::NeedNewKeyFrame``: far enough from the nearest keyframe, relative to depth."""
        if not depth_mean or not np.isfinite(nearest_distance):
            return False
        return nearest_distance / depth_mean > self.cfg.mapper.kf_dist_wiggle_mult * self.wiggle_depth_normalised

    def add_keyframe(self, request: KeyframeRequest, now: bool = False) -> None:
        """``now``: integrated at once, in the caller's thread (a panorama before any map: no mapper runs it)."""
        self._handed_over += 1
        self.queue.append(request)
        if now:
            self._integrate(self.queue.popleft())
            self.publish()

    def queue_refind(self, point_ids: np.ndarray, first_kf: int) -> None:
        """Search points in keyframes ``first_kf`` on in the background, as newly made ones are (merged tracks)."""
        self._new_points.append((np.asarray(point_ids, np.int64), first_kf))

    def keyframes_settled(self) -> bool:
        """Every keyframe handed over is in the published snapshot and locally adjusted (PTAM §6.3)."""
        return self._handed_over == self._published_integrated and self.recent_converged

    def publish(self) -> None:
        integrated = self._integrated  # read first: one integrated while the snapshot is taken stays pending
        self.snapshot = self.map.snapshot()
        self._published_integrated = integrated

    def _abort(self) -> bool:
        return len(self.queue) > 0

    # -- one unit of work -------------------------------------------------------------------------------------
    def step(self) -> bool:
        """Do the most pressing job (PTAM's MapMaker::run order); False when there was nothing to do."""
        if not self.initialised:
            return False
        if self._handle_bad_points():
            self.publish()
        if self.queue:
            self._integrate(self.queue.popleft())
        elif not self.recent_converged:
            self.bundle_adjust(recent=True)
        elif self._new_points:
            self._refind_newly_made()
        elif self.edgelets.pending:  # Agility §4.4, as new points
            self.edgelets.measure_pending(self.map, self._abort, self.stats)
        elif not self.full_converged:
            self.bundle_adjust(recent=False)
        elif self._failure_queue:
            self._refind_from_failure_queue()
        elif self.cfg.normals.enabled and self.normals.has_work(self.map):
            self.normals.run_batch(self.map)
        else:
            return False
        self.publish()
        return True

    def report_tracking(self, inlier_ids: np.ndarray, outlier_ids: np.ndarray) -> None:
        """Called from the tracker's thread with one frame's Tukey inliers and outliers (point ids)."""
        self.feedback.report(inlier_ids, outlier_ids)

    def _handle_bad_points(self) -> bool:
        """PTAM code ``HandleBadPoints``; returns whether any point was marked bad."""
        bad = self.feedback.bad_points(self.map.n_points_total, self.map.bad)
        if len(bad):
            self.map.mark_bad(bad)
        return bool(len(bad))

    def run_until_idle(self, max_steps: int = 10_000) -> None:
        for _ in range(max_steps):
            if not self.step():
                return

    # -- keyframe integration (PTAM §6.2) ---------------------------------------------------------------
    def _integrate(self, r: KeyframeRequest) -> None:
        """PTAM §6.2; a panorama keyframe (Gauglitz et al. §4.3) gains rays instead of triangulated points."""
        kf = KeyFrame(
            self.map.next_keyframe_id, r.pyramid, float(r.depth_mean), float(r.depth_sigma), float(r.timestamp)
        )
        k = self.map.add_keyframe(dataclasses.replace(kf, panorama=r.panorama), r.T_cw)
        good = ~self.map.bad[r.point_ids]
        self.map.add_measurements(k, r.point_ids[good], r.xy[good], r.level[good], SRC_TRACKER)
        self._refind_in_keyframe(k, self._unmeasured_points(k))
        if not r.panorama and self.cfg.model_selection.rays_gain_depth:  # Gauglitz §4.3: found anew like new points
            self._new_points.append((self._triangulate_rays(k), 0))
        min_dist = self.cfg.mapper.candidate_min_dist_px
        for level in new_point_levels(self.cfg.image.levels):
            if r.panorama:
                add_ray_points(self.map, self.camera, k, level, self.cfg.image, min_dist)
            else:
                self.add_some_map_points(k, level)
        if self.cfg.edgelets.enabled and not r.panorama:  # Agility §4.3
            self.edgelets.integrate(self.map, k, self.stats)
        self.recent_converged = self.full_converged = False
        self._integrated += 1
        self.stats["keyframes_added"] += 1
        self.stats["panorama_keyframes_added"] += int(r.panorama)

    def _triangulate_rays(self, k: int) -> np.ndarray:
        """The parallax PTAM's keyframe spacing gives its epipolar pairs (the first pair's baseline over depth)."""
        angle = self.cfg.mapper.kf_dist_wiggle_mult * self.wiggle_depth_normalised
        return triangulate_rays(self.map, self.camera, k, self.cfg, self._unit_plane_corners, angle)

    def _unit_plane_corners(self, k: int, level: int) -> np.ndarray:
        key = (k, level)
        if key not in self._plane_corners:
            self._plane_corners[key] = unit_plane_corners(self.camera, self.map.keyframes[k].pyramid, level)
        return self._plane_corners[key]

    def _measured_in(self, k: int) -> np.ndarray:
        measured = np.zeros(self.map.n_points_total, bool)
        measured[self.map.meas_pt[self.map.meas_kf == k]] = True
        return measured

    def _unmeasured_points(self, k: int) -> np.ndarray:
        return np.flatnonzero(~self._measured_in(k) & ~self.map.bad)

    def add_some_map_points(self, k: int, level: int) -> int:
        """PTAM code ``AddSomeMapPoints``: thinned candidates of keyframe k, epipolar search in the closest."""
        m = self.map
        kf = m.keyframes[k]
        xy = free_candidates(m, k, level, self.cfg.image, self.cfg.mapper.candidate_min_dist_px)
        if len(xy) == 0:
            return 0
        t = self.map.nearest_with_baseline(k)
        T = m.kf_T_cw
        res = epipolar_matches(
            self.camera,
            T[k],
            T[t],
            kf.pyramid,
            m.keyframes[t].pyramid,
            kf.scene_depth_mean,
            kf.scene_depth_sigma,
            level,
            xy,
            self._unit_plane_corners(t, level),
            self.cfg,
        )
        n = len(res.X)
        if n == 0:
            return 0
        # Patch normal facing the source camera, parallel to its image plane (PTAM §6.5).
        normal = np.broadcast_to(T[k][2, :3] * -1.0, (n, 3))
        ids = m.add_points(res.X, normal, k, level, res.src_level_xy)
        m.add_measurements(k, ids, res.src_xy, level, SRC_ROOT)
        m.add_measurements(t, ids, res.tgt_xy, level, SRC_EPIPOLAR)
        self._new_points.append((ids, 0))
        return n

    # -- data-association refinement (PTAM §6.4) --------------------------------------------------------
    def _never(self, k: int) -> np.ndarray:
        n = self.map.n_points_total
        a = self._never_retry.get(k)
        if a is None or len(a) < n:
            b = np.zeros(max(n, 2 * (0 if a is None else len(a))), bool)
            if a is not None:
                b[: len(a)] = a
            self._never_retry[k] = a = b
        return a

    def _refind_in_keyframe(self, k: int, pts: np.ndarray, source=SRC_REFIND) -> int:
        """Search ``pts`` in keyframe k, skipping points it measures already or must never retry (PTAM code
        ``ReFind_Common``)."""
        never = self._never(k)
        pts = np.unique(np.asarray(pts, dtype=np.int64))
        pts = pts[~never[pts] & ~self._measured_in(k)[pts]]
        if len(pts) == 0:
            return 0
        m = self.map
        r = refind_points(
            self.camera,
            self.cfg,
            self.finder,
            m.kf_T_cw,
            m.kf_images,
            m.keyframes[k].pyramid,
            m.kf_T_cw[k],
            m.X[pts],
            m.normal[pts],
            m.source_kf[pts],
            m.source_level[pts],
            m.source_xy[pts],
        )
        never[pts[~r.found]] = True
        if r.found.any():
            m.add_measurements(k, pts[r.found], r.xy[r.found], r.level[r.found], source)
        return int(r.found.sum())

    def _refind_newly_made(self) -> None:
        """PTAM code ``ReFindNewlyMade``: a queued keyframe interrupts the search, and the points not yet
        searched everywhere stay queued for later."""
        pts, start = self._new_points.pop(0)
        pts = pts[~self.map.bad[pts]]
        for k in range(start, self.map.n_keyframes):
            if self._abort():
                self._new_points.insert(0, (pts, k))
                return
            self._refind_in_keyframe(k, pts)

    def _refind_from_failure_queue(self) -> None:
        batch, self._failure_queue = self._failure_queue, []
        by_kf: dict[int, list[int]] = {}
        for k, p in batch:
            if not self.map.bad[p]:
                by_kf.setdefault(k, []).append(p)
        for k, pts in by_kf.items():
            self._refind_in_keyframe(k, np.asarray(pts, np.int64))

    # -- bundle adjustment (PTAM §6.3) ------------------------------------------------------------------
    def bundle_adjust(self, recent: bool) -> None:
        m = self.map
        n = m.n_keyframes
        fixed = np.zeros(n, bool)
        fixed[0] = True
        # Gauglitz et al. §5.2 adjusts SfM groups only: rays are not used, panorama keyframes are held unless their
        # rays gained depth and joined the group (§4.3, held_panorama_keyframes).
        fixed |= held_panorama_keyframes(m, self.cfg.model_selection)
        use = ~m.ray[m.meas_pt]
        if recent and n < self.cfg.mapper.local_ba_min_keyframes:
            # Small maps: global adjustment covers everything (PTAM code).
            self.recent_converged = True
            return
        if recent:
            sets = local_sets(
                m.kf_T_cw, m.meas_kf, m.meas_pt, m.n_points_total, n - 1, self.cfg.bundle.local_neighbours, fixed
            )
            fixed_poses, adjust_points = ~sets.adjust, sets.points
        else:
            fixed_poses, adjust_points = fixed, ~m.bad
        edgelets = edgelet_ba_input(m, self.cfg, sets.adjust if recent else None)  # Agility §4.4
        centres = m.camera_centres.copy()
        self.stats["ba_running"] = "local" if recent else "global"
        try:
            res = self.bundle.adjust(
                m.kf_T_cw,
                m.X,
                m.meas_kf[use],
                m.meas_pt[use],
                m.meas_xy[use],
                m.meas_level[use],
                fixed_poses,
                adjust_points & ~m.ray,
                abort=self._abort,
                edgelets=edgelets,
            )
        finally:
            self.stats["ba_running"] = None
        # (keyframes in the map, ms, converged) per run, for PTAM Table 2's buckets by map size.
        self.stats["local_ba" if recent else "global_ba"].append(
            (n, 1e3 * res.phase_seconds.get("total", 0.0), bool(res.converged))
        )
        self._keep_ba_result(res, recent, np.flatnonzero(use), edgelets)
        if not recent and res.accepted > 0 and not res.failed and self.cfg.bundle.hold_scale:
            hold_scale(m, centres)

    def _keep_ba_result(self, res: BundleResult, recent: bool, used: np.ndarray, edgelets) -> None:
        """Write an adjustment's result into the map and handle its outliers (PTAM code ``BundleAdjust``)."""
        m = self.map
        if res.failed:
            # PTAM code (MapMaker::BundleAdjust): "Cholesky failure in bundle adjust. The map is probably
            # corrupt: Ditching the map." The system resets.
            log.warning("bundle adjustment could not factorise the reduced system; the map is probably corrupt")
            self.recent_converged = self.full_converged = True
            self.reset_requested = True
            return
        if res.accepted > 0:
            m.set_poses(np.arange(m.n_keyframes), res.poses)
            m.set_points(np.arange(m.n_points_total), res.points)
            keep_edgelets(m, edgelets, res)
            self.full_converged = False
            if recent:
                self.recent_converged = False
        if self.unfinished_outliers.final(res, recent):
            if len(res.outliers):
                self._handle_outliers(used[res.outliers])
            handle_edgelet_outliers(m, self.cfg, res.edgelet_outliers)
        if res.converged:
            self.recent_converged = True
            if not recent:
                self.full_converged = True

    def _handle_outliers(self, outliers: np.ndarray) -> None:
        """PTAM code ``BundleAdjust``: a point is bad when its root measurement or one of its last two good
        ones is an outlier; other outliers are dropped, tracker/epipolar ones queued for a second chance."""
        m = self.map
        kf, pt, src = m.meas_kf[outliers], m.meas_pt[outliers], m.meas_source[outliers]
        count = np.bincount(m.meas_pt, minlength=m.n_points_total)
        bad = (count[pt] <= self.cfg.mapper.outlier_min_good_measurements) | (src == SRC_ROOT)
        retry = ~bad & ((src == SRC_TRACKER) | (src == SRC_EPIPOLAR))
        self._failure_queue.extend(zip(kf[retry].tolist(), pt[retry].tolist()))
        for k, p in zip(kf[~bad & ~retry].tolist(), pt[~bad & ~retry].tolist()):
            self._never(k)[p] = True
        mask = np.zeros(m.n_measurements, bool)
        mask[outliers[~bad]] = True
        m.remove_measurements(mask)
        if bad.any():
            m.mark_bad(np.unique(pt[bad]))
