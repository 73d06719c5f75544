"""The ``System`` facade: tracker and mapper as two threads (PTAM §2, DESIGN.md Concurrency).

The tracker runs in the caller's thread, one :meth:`System.process` call per frame; the mapper runs in its
own thread (``async``, the default) or, in ``sync`` mode, to idle inside ``process`` right after a keyframe is
handed over, which makes runs deterministic. The tracker reads ``mapper.snapshot`` (an immutable
``MapSnapshot`` swapped atomically by the mapper) and takes no lock. An exception in the mapper thread is
re-raised in the caller at the next frame or at :meth:`close`.

Before a map exists the system initialises (PTAM §6.1). With ``init_mode="key"`` (live cameras) the user's two
key presses (:meth:`System.request_keyframe`) take the two keyframes, as in the paper. With ``"auto"`` (recorded
sources) trails start at the first frame and the second keyframe is taken when their median disparity passes
``init.auto_min_disparity_rel_focal`` × f, or at fixed frames (``init_frames``); a failure is logged with its
reason and initialisation restarts. :meth:`System.reset` discards the map and initialises again.

Once tracking is lost (PTAM §5.6), every frame is relocalised (Agility §7) before it is tracked: the pose from
the best-matching keyframe restarts the tracker with an enlarged coarse stage, until a frame is tracked again
(not bad). A rejected attempt skips tracking; no attempt changes the map, and no keyframe is added while
relocalising (PTAM code: only the normal tracking branch adds keyframes).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .camera import load_camera
from .camera.model import CameraModel
from .capture import open_dataset
from .config import Config
from .geometry import se3
from .image.pyramid import Pyramid
from .map.map import Map
from .mapping.map_maker import KeyframeRequest, MapMaker
from .mapping.stereo_init import init_from_stereo
from .mapping.two_view import InitFailure
from .tracking.relocaliser import Relocaliser
from .tracking.tracker import Tracker
from .tracking.trails import TrailTracker
from .vocabulary import InitMode, Quality, RunMode, TrackingState

log = logging.getLogger("ptam")

INITIALISING, LOST, RELOCALISING = TrackingState.INITIALISING, TrackingState.LOST, TrackingState.RELOCALISING


@dataclass
class FrameOutcome:
    """What happened to one frame: the state, the pose if tracked (T_cw), and the tracker's result if any."""

    index: int
    timestamp: float
    state: TrackingState
    T_cw: np.ndarray | None
    result: object = None
    keyframe_added: bool = False
    process_ms: float = 0.0
    frame: object = None  # the capture Frame, for observers that show the image


@dataclass
class RunStats:
    frames: int = 0
    tracked: int = 0
    lost_events: int = 0
    relocalisations: int = 0  # lost -> tracking through a relocalisation (Agility §7)
    reloc_attempts: int = 0
    keyframes_requested: int = 0
    init_attempts: int = 0
    init_failures: list = field(default_factory=list)
    track_ms: list = field(default_factory=list)


def _tracked_state(res) -> TrackingState:
    return TrackingState.GOOD if res.quality == Quality.GOOD else TrackingState.POOR


class System:
    """``map_``: start from an existing map (e.g. loaded from a file) instead of initialising; the tracker starts
    at its first keyframe with the coarse stage forced. ``localize_only``: track against the map without adding
    keyframes (the mapper never runs). ``observers``: callables ``f(outcome, system)`` run after every frame in
    the tracker's thread (the viewer); they must be cheap and must not block. ``init_mode``: ``"auto"`` or
    ``"key"`` (stereo initialisation keyframes taken by :meth:`request_keyframe`)."""

    def __init__(
        self,
        camera: CameraModel,
        cfg: Config,
        mode: RunMode | str | None = None,
        init_frames: tuple[int, int] | None = None,
        map_: Map | None = None,
        localize_only: bool = False,
        init_mode: InitMode | str = InitMode.AUTO,
    ):
        init_mode = InitMode(init_mode)
        self.camera = camera
        self.cfg = cfg
        self.mode = RunMode(mode or cfg.system.mode)
        self.init_frames = init_frames
        self.init_mode = init_mode
        self._key_pressed = False
        self.localize_only = localize_only
        self.tracker = Tracker(camera, cfg)
        self.relocaliser = Relocaliser(camera, cfg)
        self.mapper = MapMaker(camera, cfg, map_)
        self.trails = TrailTracker(cfg.init, cfg.image)
        self.state = INITIALISING
        self.observers: list = []
        if self.mapper.initialised:
            self.state = TrackingState.GOOD
            self.tracker.set_pose(self.mapper.map.kf_T_cw[0], recovered=True)
        self.trajectory: list[tuple[float, np.ndarray]] = []  # (timestamp, T_wc) per tracked frame
        self.stats = RunStats()
        self._first: tuple[Pyramid, float, int] | None = None  # the first stereo keyframe: pyramid, time, index
        self._init_frames: list = []  # frames seen since the first keyframe, tracked once a map exists
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._mapper_error: BaseException | None = None
        self.last_failure: str | None = None

    # -- threads -------------------------------------------------------------------------------------------
    def start(self) -> System:
        if self.mode != RunMode.SYNC and not self.localize_only and self._thread is None:
            self._thread = threading.Thread(target=self._mapper_loop, name="ptam-mapper", daemon=True)
            self._thread.start()
        return self

    def _mapper_loop(self) -> None:
        try:
            while not self._stop.is_set():
                if not self.mapper.step():
                    self._wake.wait(self.cfg.system.mapper_idle_wait_s)
                    self._wake.clear()
        except BaseException as e:  # re-raised in the tracker's thread
            self._mapper_error = e

    def _check_mapper(self) -> None:
        if self._mapper_error is not None:
            err, self._mapper_error = self._mapper_error, None
            raise err

    def close(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self._check_mapper()

    def __enter__(self) -> System:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # -- user commands (called between frames, in the tracker's thread) ------------------------------------
    def request_keyframe(self) -> None:
        """The user's key press of stereo initialisation (PTAM §6.1): the first press takes the first keyframe
        and starts the trails, the second takes the second keyframe and builds the map. Ignored in ``auto``
        mode and once a map exists."""
        self._key_pressed = self.init_mode == InitMode.KEY and not self.mapper.initialised

    @property
    def init_started(self) -> bool:
        """Stereo initialisation has its first keyframe and is following trails."""
        return self._first is not None and not self.mapper.initialised

    def reset(self) -> None:
        """PTAM's reset: discard the map, the trajectory and the tracker's state, then initialise again."""
        restart = self._thread is not None
        self.close()
        self._stop.clear()
        self.mapper = MapMaker(self.camera, self.cfg)
        self.tracker.reset()
        self.trails = TrailTracker(self.cfg.init, self.cfg.image)
        self.state = INITIALISING
        self.trajectory = []
        self._first, self._init_frames, self._key_pressed = None, [], False
        if restart:
            self.start()

    # -- per frame -----------------------------------------------------------------------------------------
    def process(self, frame) -> FrameOutcome:
        self._check_mapper()
        t0 = time.perf_counter()
        self.stats.frames += 1
        out = self._track(frame) if self.mapper.initialised else self._initialise(frame)
        out.process_ms = 1e3 * (time.perf_counter() - t0)
        out.frame = frame
        for observe in self.observers:
            observe(out, self)
        return out

    def _track(self, frame, record: bool = True) -> FrameOutcome:
        snapshot = self.mapper.snapshot
        recovering = self.state in (LOST, RELOCALISING) and self.cfg.reloc.enabled
        if self.cfg.reloc.enabled:
            self.relocaliser.sync(snapshot)  # keyframe descriptors as keyframes appear, not all at the first loss
        pyramid = None
        if recovering:
            pyramid = Pyramid.build(frame.image, self.cfg.image)
            reloc = self.relocaliser.attempt(pyramid, snapshot)
            self.stats.reloc_attempts += 1
            if reloc is None or not reloc.accepted:
                self.state = RELOCALISING
                return FrameOutcome(int(frame.index), float(frame.timestamp), RELOCALISING, None)
            self.tracker.set_pose(reloc.T_cw, recovered=True)
        res = self.tracker.track(frame, snapshot, pyramid)
        self.stats.track_ms.append(res.timings.total)
        if recovering:
            self.state = RELOCALISING if res.lost else _tracked_state(res)
            if not res.lost:
                self.stats.relocalisations += 1
        else:
            if res.lost and self.state != LOST:
                self.stats.lost_events += 1
            self.state = LOST if res.lost else _tracked_state(res)
        if not recovering and not self.localize_only:
            m = res.measurements
            self.mapper.report_tracking(m.point_ids[m.found & m.inlier], m.point_ids[m.found & ~m.inlier])
        T = res.T_cw if res.tracked else None
        if T is not None and record:
            self.trajectory.append((res.timestamp, se3.inv(T)))
            self.stats.tracked += 1
        added = record and not recovering and self._maybe_add_keyframe(res)
        return FrameOutcome(res.frame_index, res.timestamp, self.state, T, res, added)

    def _maybe_add_keyframe(self, res) -> bool:
        """PTAM §6.2 (code ``Tracker::NeedNewKeyFrame`` + ``MapMaker::NeedNewKeyFrame``); frames of rapid motion
        are tracked but not used for map-building (Agility §10)."""
        m = self.cfg.mapper
        kf = res.keyframe
        if (
            self.localize_only
            or res.rapid_motion
            or not (
                res.quality == Quality.GOOD
                and kf.frames_since_keyframe > m.kf_min_frames
                and self.mapper.queue_size() < m.kf_max_queue
                and self.mapper.need_new_keyframe(kf.nearest_keyframe_distance, kf.mean_scene_depth)
            )
        ):
            return False
        meas = res.measurements
        f = meas.found
        self.mapper.add_keyframe(
            KeyframeRequest(
                res.pyramid,
                res.T_cw.copy(),
                res.timestamp,
                meas.point_ids[f],
                meas.xy[f],
                meas.level[f],
                kf.mean_scene_depth,
                kf.scene_depth_sigma,
            )
        )
        self.tracker.keyframe_added()
        self.stats.keyframes_requested += 1
        if self.mode == RunMode.SYNC:
            self.mapper.run_until_idle()
        else:
            self._wake.set()
        return True

    # -- initialisation (PTAM §6.1) ----------------------------------------------------------------------
    def _restart_init(self, pyramid, frame, reason: str | None) -> None:
        if reason:
            log.info("initialisation restarts: %s", reason)
            self.last_failure = reason
            self.stats.init_failures.append(reason)
        n = self.trails.start(pyramid)
        self._first = (pyramid, float(frame.timestamp), int(frame.index))
        self._init_frames = []
        if n < self.cfg.init.min_trails:
            self.last_failure = f"too few corners to start trails ({n} < {self.cfg.init.min_trails})"
            self._first = None

    def _initialise(self, frame) -> FrameOutcome:
        c = self.cfg.init
        pyramid = Pyramid.build(frame.image, self.cfg.image)
        idle = FrameOutcome(int(frame.index), float(frame.timestamp), INITIALISING, None)
        key, self._key_pressed = self._key_pressed, False
        fixed = self.init_frames
        restarts = self.init_mode == InitMode.AUTO and fixed is None  # else each attempt waits for its own trigger
        if self._first is None:
            start = key if self.init_mode == InitMode.KEY else (fixed is None or frame.index == fixed[0])
            if start:
                self._restart_init(pyramid, frame, None)
            return idle
        n = self.trails.advance(pyramid)
        if n < c.min_trails:
            if restarts:
                self._restart_init(pyramid, frame, f"too few trails survive ({n} < {c.min_trails})")
            else:
                self.last_failure = f"too few trails survive to frame {frame.index} ({n} < {c.min_trails})"
                self._first = None
            return idle
        self._init_frames.append(frame)
        f = 0.5 * (self.camera.fx + self.camera.fy)
        if self.init_mode == InitMode.KEY:
            if not key:
                return idle
        elif fixed is not None:
            if frame.index < fixed[1]:
                return idle
        elif self.trails.median_disparity() < c.auto_min_disparity_rel_focal * f:
            return idle
        self.stats.init_attempts += 1
        first = self._first
        try:
            T = init_from_stereo(
                self.mapper, first[:2], (pyramid, float(frame.timestamp)), self.trails.start_xy, self.trails.current_xy
            )
        except InitFailure as e:
            self.mapper = MapMaker(self.camera, self.cfg)
            if restarts:
                self._restart_init(pyramid, frame, str(e))
            else:
                self.last_failure = str(e)
                self.stats.init_failures.append(str(e))
                self._first = None
            return idle
        snap = self.mapper.snapshot
        n_points = snap.n_points if snap is not None else 0
        log.info("map initialised from frames %d and %d: %d points", first[2], frame.index, n_points)
        self._after_init(first, frame, T)
        return FrameOutcome(int(frame.index), float(frame.timestamp), TrackingState.GOOD, T, None, True)

    def _after_init(self, first, frame, T_second) -> None:
        """Record both keyframes' poses and, for frames in between, track them against the new map."""
        T0 = self.mapper.map.kf_T_cw[0].copy()
        self.trajectory.append((first[1], se3.inv(T0)))
        self.stats.tracked += 1
        if self.cfg.init.track_frames_between:
            self.tracker.set_pose(T0)
            for f in self._init_frames[:-1]:
                self._track(f)
        self.trajectory.append((float(frame.timestamp), se3.inv(T_second)))
        self.stats.tracked += 1
        self._init_frames = []
        self.tracker.reset()
        self.tracker.set_pose(T_second)
        self.state = TrackingState.GOOD
        if self.mode != RunMode.SYNC:
            self._wake.set()


def run_dataset(path, cfg: Config, mode: RunMode | str | None = None, **kwargs) -> System:
    """Run a whole dataset folder (TUM/EuRoC/images with its ``camera.yaml``, stamped at ``capture.default_fps``
    where the dataset has no timestamps) through a System; returns it."""
    path = Path(path)
    camera = load_camera(path / "camera.yaml")
    with open_dataset(path, cfg.capture.default_fps) as src, System(camera, cfg, mode=mode, **kwargs) as system:
        for frame in src:
            system.process(frame)
    return system
