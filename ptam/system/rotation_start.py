"""Tracking from the first frame, before any map exists (Gauglitz et al. TVCG 2013 §4.3, §6: no separate
initialisation step).

The first frame becomes a panorama keyframe: its corners are rays without depth (Gauglitz §3.2,
:mod:`ptam.mapping.panorama`), and the tracker follows them with the rotation-only model from the next frame on
(§4.2; with no 3-D point in view [R|t] cannot be estimated, and [R|0] is the only model). The view turning away
from every keyframe adds panorama keyframes (§4.3). Meanwhile PTAM's trails run from the frame where stereo
initialisation starts (the *anchor*), and the first SfM group is triangulated from them once their two-view GRIC
selects a translating relation with enough parallax (:mod:`.stereo_start`, :mod:`ptam.mapping.two_view`).

A rotation-only pose cannot represent a translation, so every frame is also checked model-free (§4.1–§4.2,
:func:`.ray_check.rays_translate`). Once a translation shows, the poses are
withheld (a wrong pose is worse than none) until the SfM group exists; the frames between its two keyframes are
then posed against it (:meth:`.stereo_start.StereoStart.adopt`), and the poses reported before its first
keyframe are moved into its frame, about that keyframe's centre, which the panorama shares. The tracker carries
on from the panorama (:meth:`~ptam.tracking.tracker.Tracker.rebase`): its velocity is the camera's.
"""

from __future__ import annotations

import logging
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..geometry import se3, so3
from ..geometry.sim3 import Similarity
from ..image.pyramid import Pyramid
from ..mapping.map_maker import KeyframeRequest, MapMaker
from ..tracking.track_result import TrackResult
from ..tracking.tracker import Tracker
from ..vocabulary import Quality
from .priority import lower_priority
from .ray_check import rays_translate

log = logging.getLogger("ptam")


class RotationStart:
    """The panorama the camera is tracked in before the first map, and the poses reported in it."""

    def __init__(self, camera: CameraModel, cfg: Config, background: bool):
        self.camera = camera
        self.cfg = cfg
        # Keyframes and the model-free check run beside the tracker where frames keep coming (inline in sync).
        self._pool = (
            ThreadPoolExecutor(1, "ptam-panorama", lower_priority, (cfg.system.background_nice,))
            if background
            else None
        )
        self._job: Future | None = None  # a keyframe being integrated
        self._check: tuple[int, Future] | None = None  # (frame, its model-free check) being run
        self.mapper: MapMaker | None = None  # keyframes of rays only
        # Its own tracker: after a loss the system's confirms relocalisations into set-aside tracks meanwhile.
        self.tracker = Tracker(camera, cfg)
        self.poses: list[tuple[int, float, np.ndarray]] = []  # (index, timestamp, T_cw) reported
        self.translated = False  # a translation showed since the panorama began
        self._seen = 0  # frames in a row that showed one
        self._poor = False  # the newest frame was tracked with poor quality
        self._anchor: tuple[int, np.ndarray] | None = None  # (index, T_cw) where the trails start
        self._tracked: deque[tuple[int, np.ndarray]] = deque(maxlen=cfg.init.max_history_frames)  # reported or not
        # The ray depth: where the stereo pair's assumed baseline gives the disparity that takes it (PTAM §6.1),
        # so the panorama is drawn at about the scale the first map will have; the tracker uses directions only.
        self._depth = cfg.init.baseline_m / cfg.init.auto_min_disparity_rel_focal

    def begin(self, pyramid: Pyramid, index: int, timestamp: float) -> np.ndarray | None:
        """Frame ``index`` is the first panorama keyframe, at the identity, and tracking starts from it; unless it
        has fewer corners than ``init.min_trails`` (as trails, a later frame tries again): then None."""
        self.mapper = MapMaker(self.camera, self.cfg)
        self.poses, self._anchor, self.translated, self._seen, self._check = [], None, False, 0, None
        T = np.eye(4)
        self._add_keyframe(pyramid, timestamp, T)
        if self.mapper.map.n_points_total < self.cfg.init.min_trails:
            self.mapper = None
            return None
        self.tracker.reset()
        self.tracker.set_pose(T)
        self.poses.append((index, timestamp, T))
        self._tracked.clear()  # poses tracked before are in another panorama's frame
        self._tracked.append((index, T))
        return T

    def follow(self, frame, pyramid: Pyramid) -> TrackResult | None:
        """One frame: the first begins the panorama; the others are tracked in it (the tracker's result) and
        reported (:meth:`pose_of`) if tracked with good quality and, by the model-free check, still a rotation
        about the panorama's centre. A reported frame whose view has turned ``model_selection.panorama_kf_travel``
        of the image width from every keyframe's becomes one (§4.3)."""
        if self.mapper is None:
            self.begin(pyramid, int(frame.index), float(frame.timestamp))
            return None
        res = self.tracker.track(frame, self.mapper.snapshot, pyramid)
        self._poor = res.quality == Quality.POOR
        if res.quality == Quality.GOOD:
            self._report(res)
        return res

    def _report(self, res: TrackResult) -> None:
        self._tracked.append((res.frame_index, res.T_cw))
        if not self.translated:
            self._check_translation(res)
        if self.translated:
            return
        T = _about_centre(res.T_cw)
        self.poses.append((res.frame_index, res.timestamp, T))
        travel = self.cfg.model_selection.panorama_kf_travel * self.camera.width
        idle = self._job is None or self._job.done()
        if idle and res.keyframe.view_travel_px > travel and not (res.rapid_motion or res.in_doubt):
            self._add_keyframe(res.pyramid, res.timestamp, T, later=True)

    def _check_translation(self, res: TrackResult) -> None:
        """The model-free check of this frame, in the background where frames keep coming (one at a time: a frame
        whose check would wait is not checked; its result counts when it is ready, a frame or two later), else
        at once. As any other evidence about a pose (a relocalisation, a keyframe), a translation counts once
        seen in ``reloc.confirm_frames`` checked frames in a row: one frame's homography can take a hand's jitter
        at the end of a pan for one."""
        assert self.mapper is not None and self.mapper.snapshot is not None
        if self._pool is None:
            self._count(res.frame_index, rays_translate(self.camera, self.cfg, res, self.mapper.snapshot))
            return
        if self._check is not None and self._check[1].done():
            index, check = self._check
            self._check = None
            self._count(index, check.result())
        if self._check is None:
            self._check = (
                res.frame_index,
                self._pool.submit(rays_translate, self.camera, self.cfg, res, self.mapper.snapshot),
            )

    def _count(self, index: int, seen: bool) -> None:
        self._seen = self._seen + 1 if seen else 0
        self.translated = self._seen >= self.cfg.reloc.confirm_frames
        if self.translated:
            log.info("frame %d: a translation; poses withheld until the map exists", index)

    def awaits(self, index: int) -> bool:
        """Whether trails that would start at frame ``index`` should wait for a later frame: this one was tracked
        in the panorama with poor quality, so its pose is not reported, yet the panorama is not lost; an anchor
        without a pose would begin a new panorama and lose every pose reported so far."""
        return self.mapper is not None and self._poor and not self.translated and self.pose_of(index) is None

    def anchor(self, pyramid: Pyramid, index: int, timestamp: float) -> None:
        """Stereo initialisation's trails start at frame ``index``: its reported pose is where the first map will
        be joined to the panorama; a frame without one (lost, or moved by a translation) begins a new panorama."""
        T = self.pose_of(index)
        if T is None:
            if self.poses:
                log.info("the rotation-only poses of %d frames cannot be joined to frame %d", len(self.poses), index)
            T = self.begin(pyramid, index, timestamp)
        self._anchor = None if T is None else (index, T)
        self.translated, self._seen, self._check = False, 0, None

    def pose_of(self, index: int) -> np.ndarray | None:
        """T_cw of frame ``index`` if it was the newest reported."""
        return self.poses[-1][2] if self.poses and self.poses[-1][0] == index else None

    def tracked_at(self, index: int) -> bool:
        """Frame ``index`` is the newest tracked with good quality (the tracker's state is this frame's)."""
        return bool(self._tracked) and self._tracked[-1][0] == index

    def turned(self, from_index: int, to_index: int) -> np.ndarray | None:
        """The rotation R (3×3) from frame ``from_index``'s camera to ``to_index``'s, if both are the newest two
        tracked with good quality, else None."""
        if len(self._tracked) < 2:
            return None
        (i, T_i), (j, T_j) = self._tracked[-2], self._tracked[-1]
        if (i, j) != (from_index, to_index):
            return None
        return T_j[:3, :3] @ T_i[:3, :3].T

    def carried(self, from_index: int, to_index: int, T_from: np.ndarray) -> np.ndarray | None:
        """Pose ``T_from`` of frame ``from_index`` carried to frame ``to_index`` by the rotation tracked between
        them (both tracked with good quality; a short interval, in which the rotation-only model holds), or None."""
        R = {i: T[:3, :3] for i, T in self._tracked}
        if from_index not in R or to_index not in R:
            return None
        D = np.eye(4)
        D[:3, :3] = R[to_index] @ R[from_index].T
        return D @ T_from

    def before(self, first_index: int, T0_cw: np.ndarray) -> list[tuple[float, np.ndarray]]:
        """(timestamp, T_wc) of the frames reported before the trails' anchor ``first_index``, moved into the
        frame of the map whose first keyframe it is, at pose ``T0_cw`` (:meth:`_into`)."""
        if self._anchor is None or self._anchor[0] != first_index:
            return []
        into = self._into(T0_cw)
        earlier = [(ts, T_cw) for i, ts, T_cw in self.poses if i < first_index]
        if not earlier:
            return []
        return list(zip([ts for ts, _ in earlier], into.poses_wc(se3.inv(np.array([T for _, T in earlier])))))

    def agrees(self, first_index: int, T0_cw: np.ndarray, snapshot) -> bool:
        """Whether the panorama shares the first map's centre, as :meth:`before` assumes: every panorama keyframe
        taken before the anchor that sees the map (tracked with good quality from its joined pose) stays within the
        fine search radius of that pose, counting its turn and its move (at the map's depth) in pixels. A camera
        that translated while a model-free check could not tell (over a plane, any motion is a homography) fails
        it, and its rotation-only poses are then withheld: lost frames, not wrong ones. Turn and move are counted
        apart, each as the image shift it alone would cause (a plane's image can look alike at two poses that differ
        by a turn and a move mimicking it: the pose is what is reported)."""
        if self._anchor is None or self._anchor[0] != first_index or self.mapper is None:
            return True
        m, into = self.mapper.map, self._into(T0_cw)
        anchor_time = next((ts for i, ts, _ in self.poses if i == first_index), np.inf)
        f, depth = 0.5 * (self.camera.fx + self.camera.fy), snapshot.keyframes[0].scene_depth_mean
        for kf, T_cw in zip(m.keyframes, m.kf_T_cw):
            if kf.timestamp >= anchor_time:
                continue
            joined = se3.inv(into.poses_wc(se3.inv(T_cw[None]))[0])
            tracker = Tracker(self.camera, self.cfg)
            tracker.set_pose(joined, recovered=True)
            res = tracker.track(kf.pyramid.levels[0], snapshot, kf.pyramid)
            if res.quality != Quality.GOOD:
                continue  # it does not see the map: nothing to compare
            turn = np.linalg.norm(so3.log(res.T_cw[:3, :3] @ joined[:3, :3].T))
            move = np.linalg.norm(se3.inv(res.T_cw)[:3, 3] - se3.inv(joined)[:3, 3]) / depth
            moved_px = f * max(turn, move)
            if moved_px > self.cfg.tracker.fine_radius_px:
                log.info("the rotation-only poses are not joined to the map: panorama keyframe at %.2f s is %.0f px "
                         "off", kf.timestamp, moved_px)  # fmt: skip
                return False
        return True

    def _into(self, T0_cw: np.ndarray) -> Similarity:
        """The panorama's frame -> that of the map whose first keyframe, at pose ``T0_cw``, is the anchor: rotated
        as the anchor was, its centre on that keyframe's (the panorama's centre). A reported pose has no
        translation, so no scale is needed."""
        assert self._anchor is not None
        return Similarity(T0_cw[:3, :3].T @ self._anchor[1][:3, :3], -T0_cw[:3, :3].T @ T0_cw[:3, 3], 1.0)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)

    def _add_keyframe(self, pyramid: Pyramid, timestamp: float, T_cw: np.ndarray, later: bool = False) -> None:
        """A panorama keyframe (rays from its corners; no mapper thread serves this map): integrated at once, or
        ``later`` in the background where frames keep coming (one at a time)."""
        mapper = self.mapper
        assert mapper is not None
        none = np.zeros(0, np.int64)
        request = KeyframeRequest(pyramid, T_cw, timestamp, none, np.zeros((0, 2)), none, self._depth, 0.0, True)
        if later and self._pool is not None:
            self._job = self._pool.submit(mapper.add_keyframe, request, True)
        else:
            mapper.add_keyframe(request, now=True)


def _about_centre(T_cw: np.ndarray) -> np.ndarray:
    """The rotation-only pose about the panorama's centre (the origin): Gauglitz §4.3, a panorama group shares
    one centre; the translation within t_max the tracker allows has no scale here."""
    T = T_cw.copy()
    T[:3, 3] = 0.0
    return T
