"""The system's side of stereo initialisation (PTAM §6.1): when to take the two keyframes, restarts, and handing
over to tracking once the worker (:mod:`.stereo_start`) has built the map."""

from __future__ import annotations

import logging
import threading

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..geometry import se3
from ..image.pyramid import Pyramid
from ..mapping.map_maker import MapMaker
from ..tracking.tracker import Tracker
from ..vocabulary import InitMode, RunMode, TrackingState
from .frame_outcome import INITIALISING, FrameOutcome
from .rotation_start import RotationStart
from .run_stats import RunStats
from .stereo_start import StereoStart

log = logging.getLogger("ptam")


class Initialisation:
    """Mixed into :class:`~ptam.system.core.System`, whose state it uses (declared here for the type checker)."""

    camera: CameraModel
    cfg: Config
    mode: RunMode
    init_mode: InitMode
    init_frames: tuple[int, int] | None
    mapper: MapMaker
    tracker: Tracker
    stats: RunStats
    trajectory: list[tuple[float, np.ndarray]]
    state: TrackingState
    last_failure: str | None
    _init: StereoStart
    _key_pressed: bool
    _held: list[tuple[float, np.ndarray]]
    _wake: threading.Event

    def _initialise(self, frame, pyramid: Pyramid | None = None) -> FrameOutcome:
        index, ts = int(frame.index), float(frame.timestamp)
        key, self._key_pressed = self._key_pressed, False
        if pyramid is None:
            pyramid = Pyramid.build(frame.image, self.cfg.image)
        init, rot = self._init, self._init.rotation
        res = None if rot is None else rot.follow(frame, pyramid)  # Gauglitz §4.3, §6: tracked from frame 0
        if res is not None:
            self.stats.track_ms.append(res.timings.total)
        n = init.advance(pyramid, index, ts) if init.started else None
        idle = FrameOutcome(
            index, ts, INITIALISING, None, res, panorama_T_cw=None if rot is None else rot.pose_of(index)
        )
        if n is None:
            fixed = self.init_frames
            if key if self.init_mode == InitMode.KEY else (fixed is None or index == fixed[0]):
                self._start_trails(pyramid, index, ts, None)
            return idle
        if init.building:
            built = init.finished()
            return idle if built is None else self._built(built, index, ts)
        if n < self.cfg.init.min_trails:
            self._init_failed(pyramid, index, ts, f"too few trails survive ({n} < {self.cfg.init.min_trails})")
        elif self._second_keyframe_now(key, index):
            self.stats.init_attempts += 1
            init.build(pyramid, index, ts)
            built = init.finished()  # at once in sync mode; else on a later frame
            if built is not None:
                return self._built(built, index, ts)
        return idle

    def _second_keyframe_now(self, key: bool, index: int) -> bool:
        if self.init_mode == InitMode.KEY:
            return key
        if self.init_frames is not None:
            return index >= self.init_frames[1]
        f = 0.5 * (self.camera.fx + self.camera.fy)
        return self._init.trails.median_disparity() >= self.cfg.init.auto_min_disparity_rel_focal * f

    def _start_trails(self, pyramid, index: int, ts: float, reason: str | None) -> None:
        if reason:
            log.info("initialisation restarts: %s", reason)
            self.last_failure = reason
            self.stats.init_failures.append(reason)
        rot = self._init.rotation
        if rot is not None and self.init_mode == InitMode.AUTO and self.init_frames is None and rot.awaits(index):
            self._init.stop()  # a later frame, whose rotation is known, starts them (see RotationStart.awaits)
            return
        n = self._init.start(pyramid, index, ts)
        if rot is not None:
            rot.anchor(pyramid, index, ts)
        if n < self.cfg.init.min_trails:
            self.last_failure = f"too few corners to start trails ({n} < {self.cfg.init.min_trails})"
            self._init.stop()

    def _init_failed(self, pyramid, index: int, ts: float, reason: str) -> None:
        """Auto mode starts over from this frame; fixed frames and key presses wait for their own trigger."""
        if self.init_mode == InitMode.AUTO and self.init_frames is None:
            self._start_trails(pyramid, index, ts, reason)
        else:
            self.last_failure = f"{reason} (frame {index})"
            self.stats.init_failures.append(reason)
            self._init.stop()

    def _built(self, built, index: int, ts: float) -> FrameOutcome:
        """The map exists (or the attempt failed): pose the frames seen since the first keyframe from their
        trails and resume tracking from the newest."""
        if built.mapper is None:
            if built.ambiguous:  # the trails go on: the next frame's pair has more baseline
                if not self._init.waiting:
                    log.info("initialisation waits: %s", built.failure)
                    self.stats.init_failures.append(built.failure)
                self._init.waiting = True
                self.last_failure = built.failure
            else:
                self._init_failed(self._init.trails.previous, index, ts, built.failure)
            return FrameOutcome(index, ts, INITIALISING, None)
        rot, self._init.rotation = self._init.rotation, None
        if rot is not None:
            rot.close()
        self.mapper = built.mapper
        self.stats.tracks_created += 1
        log.info("map initialised from frames %d and %d: %d points", built.first[0], built.second[0],
                 self.mapper.map.n_points_total)  # fmt: skip
        newest, T_newest = self._init.adopt(built)
        if newest.index == built.second[0]:
            T_newest = self.mapper.map.kf_T_cw[1]
        if T_newest is not None:
            self._held = [(newest.timestamp, se3.inv(T_newest))]
            self.stats.tracked += 1
        T0 = self.mapper.map.kf_T_cw[0]
        if rot is not None and rot.agrees(built.first[0], T0, self.mapper.snapshot):
            earlier = rot.before(built.first[0], T0)  # the panorama's poses before the first keyframe, in its frame
            self.trajectory.extend(earlier)
            self.stats.tracked += len(earlier)
        self._collect_posed(wait=self.mode == RunMode.SYNC)
        self._init.stop()
        T = self._resume(rot, built, newest.index, T_newest)
        self.state = TrackingState.GOOD
        if self.mode != RunMode.SYNC:
            self._wake.set()
        tracked = T_newest is not None and newest.index == index
        return FrameOutcome(index, ts, TrackingState.GOOD, T if tracked else None, None, index == built.second[0])

    def _resume(self, rot: RotationStart | None, built, newest: int, T_newest: np.ndarray | None) -> np.ndarray:
        """Tracking resumes at the newest frame: from its PnP pose; without one (its trails lost in a turn), from
        the second keyframe's carried by the rotation the panorama tracked since (Gauglitz §4.3); else from the
        second keyframe's. A pose from the trails alone is approximate: the next frame runs the enlarged coarse
        stage. Where the tracker followed this very frame in a panorama that saw no translation, its velocity and
        last small image carry on (a velocity measured while the camera translated is a mimicking rotation's)."""
        T_kf1 = self.mapper.map.kf_T_cw[1]
        T = T_newest
        if T is None and rot is not None:
            T = rot.carried(built.second[0], newest, T_kf1)
        T = T_kf1 if T is None else T
        recovered = newest != built.second[0]
        if rot is not None and rot.tracked_at(newest) and not rot.translated:
            self.tracker.rebase(T, recovered, rot.tracker)
        else:
            self.tracker.reset()
            self.tracker.set_pose(T, recovered)
        return T

    def _collect_posed(self, wait: bool = False) -> None:
        """Poses of the frames seen while the map was built, as the worker finishes them (in timestamp order
        among the trajectory; PTAM §6.1's frames between the keyframes, optional)."""
        if not self._init.posing:
            return
        posed = self._init.posed(wait)
        if not posed and self._init.posing:
            return
        if self.cfg.init.track_frames_between:
            self.trajectory.extend((fr.timestamp, se3.inv(T)) for fr, T in posed)
            self.stats.tracked += len(posed)
        held, self._held = self._held, []
        self.trajectory.extend(held)

    def _keep_rotation_poses(self) -> None:
        """At the end of a run that never built a map: the poses tracked in the panorama are the trajectory."""
        rot = self._init.rotation
        if rot is not None and rot.poses and not self.mapper.initialised and not self.trajectory:
            self.trajectory = [(ts, se3.inv(T_cw)) for _, ts, T_cw in rot.poses]
            self.stats.tracked += len(self.trajectory)
