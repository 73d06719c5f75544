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

import dataclasses
import logging
import threading
import time
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..camera import load_camera
from ..camera.model import CameraModel
from ..capture import open_dataset
from ..config import Config
from ..errors import InputError
from ..geometry import se3
from ..image.pyramid import Pyramid
from ..map.map import Map
from ..mapping.map_maker import MapMaker
from ..tracking.relocaliser import Relocaliser, confirms
from ..tracking.tracker import Tracker
from ..tracking.trails import TrailTracker
from ..vocabulary import InitMode, Quality, RunMode, TrackingState
from .frame_outcome import FrameOutcome
from .initialisation import Initialisation
from .keyframe_policy import KeyframePolicy
from .priority import lower_priority
from .ray_check import RayCheck
from .run_stats import RunStats
from .stereo_start import StereoStart
from .tracks import Tracks
from .warm_up import rehearsal_frames, rehearsal_log

log = logging.getLogger("ptam")

INITIALISING, LOST, RELOCALISING = TrackingState.INITIALISING, TrackingState.LOST, TrackingState.RELOCALISING


def _tracked_state(res) -> TrackingState:
    return TrackingState.GOOD if res.quality == Quality.GOOD else TrackingState.POOR


class System(Initialisation, KeyframePolicy, Tracks):
    """``map_``: start from an existing map (e.g. loaded from a file) instead of initialising; the tracker starts
    at its first keyframe with the coarse stage forced. ``localize_only``: track against the map without adding
    keyframes (the mapper never runs). ``observers``: callables ``f(outcome, system)`` run after every frame in
    the tracker's thread (the viewer); they must be cheap and must not block. ``init_mode``: ``"auto"`` or
    ``"key"`` (stereo initialisation keyframes taken by :meth:`request_keyframe`)."""

    _rehearsed: ClassVar[bool] = False  # the kernels were loaded by a rehearsal in this process (``_rehearse``)

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
        self._ray_check = RayCheck(camera, cfg)
        self.mapper = MapMaker(camera, cfg, map_)
        self._init_tracks()
        self._init = StereoStart(camera, cfg, background=self._build_in_background())
        self.state = INITIALISING
        self.observers: list = []
        if self.mapper.initialised:
            self.state = TrackingState.GOOD
            self.tracker.set_pose(self.mapper.map.kf_T_cw[0], recovered=True)
        self.trajectory: list[tuple[float, np.ndarray]] = []  # (timestamp, T_wc) per tracked frame
        self.stats = RunStats(cfg.system.latency_window_frames)
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._stepped = threading.Event()  # the mapper finished a unit of work
        self._mapper_error: BaseException | None = None
        self.last_failure: str | None = None
        self._held: list[tuple[float, np.ndarray]] = []  # tracked while the initialisation frames are posed
        self._confirming: list[tuple[float, np.ndarray]] | None = None  # poses tracked since a relocalisation
        self._good_streak = 0  # frames in a row tracked with good quality, up to this one

    def _build_in_background(self) -> bool:
        """The first map is built beside the tracker where frames keep coming (``realtime``); a file replayed in
        ``async`` mode waits for it as it waits for the mapper (else it would race ahead on trails alone)."""
        return self.mode == RunMode.REALTIME or (
            self.mode == RunMode.ASYNC and not self.cfg.system.async_waits_for_local_ba
        )

    # -- threads -------------------------------------------------------------------------------------------
    def start(self) -> System:
        """Start the mapper thread (not in ``sync``); outside ``sync`` mode, load every kernel first
        (``_rehearse``) so that no frame waits while one is compiled or loaded."""
        if self.mode != RunMode.SYNC:
            self._rehearse()
        if self.mode != RunMode.SYNC and not self.localize_only and self._thread is None:
            self._thread = threading.Thread(target=self._mapper_loop, name="ptam-mapper", daemon=True)
            self._thread.start()
        return self

    def _rehearse(self) -> None:
        """Once per process, a ``sync`` System over ``system.warm_up_frames`` synthetic frames (``warm_up``) loads
        the kernels of the tracker and the mapper, or compiles them on the first run after an install."""
        n = self.cfg.system.warm_up_frames
        if n == 0 or System._rehearsed:
            return
        try:
            with rehearsal_log(log), System(self.camera, self.cfg, mode=RunMode.SYNC) as rehearsal:
                for frame in rehearsal_frames(self.camera, n):
                    rehearsal.process(frame)
        except Exception as e:  # the rehearsal only saves time: its failure must not stop the user's run
            log.warning("the kernel rehearsal failed (%s: %s); kernels load as the frames arrive", type(e).__name__, e)
        System._rehearsed = True

    def _mapper_loop(self) -> None:
        lower_priority(self.cfg.system.background_nice)
        try:
            while not self._stop.is_set():
                if not (self.mapper.step() or self._merge_tracks() or self._step_set_aside()):
                    self._wake.wait(self.cfg.system.mapper_idle_wait_s)
                    self._wake.clear()
                self._stepped.set()
        except BaseException as e:  # re-raised in the tracker's thread
            self._mapper_error = e

    def _check_mapper(self) -> None:
        if self._mapper_error is not None:
            err, self._mapper_error = self._mapper_error, None
            raise err

    def close(self) -> None:
        if self._init.building:  # the source ended while the map was being built: adopt it and its frames
            last = self._init.history[-1]
            self._built(self._init.wait(), last.index, last.timestamp)
        self._collect_posed(wait=True)
        self._init.close()
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self._check_mapper()
        self._keep_rotation_poses()
        self._settle_tracks()

    def __enter__(self) -> System:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # -- user commands (called between frames, in the tracker's thread) ------------------------------------
    def request_keyframe(self) -> None:
        """The user's key press of stereo initialisation (PTAM §6.1): the first press takes the first keyframe
        and starts the trails, the second takes the second keyframe and builds the map. Ignored in ``auto``
        mode and while the current track has a map (after a loss, a new track starts without one: §4.4)."""
        self._key_pressed = self.init_mode == InitMode.KEY and not self.mapper.initialised

    @property
    def init_started(self) -> bool:
        """Stereo initialisation has its first keyframe and is following trails."""
        return self._init.started and not self.mapper.initialised

    @property
    def trails(self) -> TrailTracker:
        return self._init.trails

    def reset(self) -> None:
        """PTAM's reset: discard the map, the trajectory and the tracker's state, then initialise again."""
        restart = self._thread is not None
        self.close()
        self._stop.clear()
        self.mapper = MapMaker(self.camera, self.cfg)
        self.tracker.reset()
        self._init = StereoStart(self.camera, self.cfg, background=self._build_in_background())
        self.state = INITIALISING
        self.trajectory = []
        self._key_pressed = False
        self._reset_tracks()
        if restart:
            self.start()

    # -- per frame -----------------------------------------------------------------------------------------
    def process(self, frame) -> FrameOutcome:
        if frame.image.shape[:2] != (self.camera.height, self.camera.width):
            h, w = frame.image.shape[:2]
            raise InputError(
                f"frame {frame.index} is {w}x{h} but the camera is {self.camera.width}x{self.camera.height}"
            )
        self._check_mapper()
        t0 = time.perf_counter()
        self.stats.frames += 1
        self._apply_merges()
        out = self._track(frame) if self.mapper.initialised else self._without_map(frame)
        if self._init.posing:
            self._collect_posed()
        if self.mapper.reset_requested:  # PTAM code: a bundle adjustment that cannot be solved ditches the map
            log.warning("the map is corrupt (bundle adjustment failed): starting again")
            self.reset()
        out.process_ms = 1e3 * (time.perf_counter() - t0)
        out.frame = frame
        for observe in self.observers:
            observe(out, self)
        return out

    def _track(self, frame) -> FrameOutcome:
        snapshot = self.mapper.snapshot
        index, ts = int(frame.index), float(frame.timestamp)
        lost = self.state in (LOST, RELOCALISING) and self._confirming is None
        if lost and self._new_track_on_loss():  # Gauglitz §4.4
            return self._lose_track(frame, Pyramid.build(frame.image, self.cfg.image))
        relocalising = self.state in (LOST, RELOCALISING) and self.cfg.reloc.enabled
        if self.cfg.reloc.enabled:
            self.relocaliser.sync(snapshot)  # keyframe descriptors as keyframes appear, not all at the first loss
        pyramid = None
        if relocalising and self._confirming is None:
            pyramid = Pyramid.build(frame.image, self.cfg.image)
            reloc = self.relocaliser.attempt(pyramid, snapshot)
            self.stats.reloc_attempts += 1
            if reloc is None or not reloc.accepted:
                self.state = RELOCALISING
                return FrameOutcome(index, ts, RELOCALISING, None)
            self.tracker.set_pose(reloc.T_cw, recovered=True)
            self._confirming = []
        res = self.tracker.track(frame, snapshot, pyramid)
        self.stats.track_ms.append(res.timings.total)
        if relocalising:
            return self._confirm(res)
        if self._ray_check.translated(res, snapshot):  # Gauglitz §4.2: rays alone cannot follow it
            log.info("frame %d: a translation with only rays in view; the track is lost", res.frame_index)
            res = dataclasses.replace(res, quality=Quality.BAD, lost=True)
        if res.lost and self.state != LOST:
            self.stats.lost_events += 1
        self.state = LOST if res.lost else _tracked_state(res)
        self._good_streak = self._good_streak + 1 if self.state == TrackingState.GOOD else 0
        if not self.localize_only:
            m = res.measurements
            self.mapper.report_tracking(m.point_ids[m.found & m.inlier], m.point_ids[m.found & ~m.inlier])
        T = res.T_cw if self._reported(res) else None
        if T is not None:
            self._record([(res.timestamp, se3.inv(T))])
        added = self._maybe_add_keyframe(res, snapshot)
        return FrameOutcome(res.frame_index, res.timestamp, self.state, T, res, added)

    def _reported(self, res) -> bool:
        """Whether a tracked frame's pose is reported (trajectory, AR, viewer). A poor frame (PTAM §5.6: found
        fraction between the lost and good thresholds, PTAM's "dodgy") is tracked on, but its pose is withheld
        unless ``system.report_poor_poses``: a wrong pose is worse than a lost frame, and on blurred footage half
        the poor frames were more than 20 mm or 2° off against 1 % of the good ones (desk_blur). Under rapid
        motion the pose is reported as PTAM reports it: failure detection is suspended there (Agility §8) and
        the rotation estimator carries the pose through a saccade (§9.3). And a frame poor by its patches, or bad
        by them under rapid motion, is reported when its edgelets held (``_edgelets_held``)."""
        if res.quality == Quality.GOOD or (res.tracked and (self.cfg.system.report_poor_poses or res.rapid_motion)):
            return True
        return (res.tracked or res.rapid_motion) and self._edgelets_held(res)

    def _edgelets_held(self, res) -> bool:
        """The edgelets were found as a good frame's patches are: at least ``edgelets.track_min_found`` (enough
        for the final pose to be [R|t] from points and edgelets) and a found fraction above PTAM's
        ``tracker.quality_good``. Blur that smears the patches past PTAM's quality check leaves edges (Agility §5),
        and Agility §8 tracks through it; its failure check counts points alone, which under fast motion says
        little about a pose the edgelets fix (``system.report_edgelet_held_poses``)."""
        n, found = res.n_edgelets_attempted, res.n_edgelets_found
        held = found >= self.cfg.edgelets.track_min_found and found > self.cfg.tracker.quality_good * n
        return self.cfg.system.report_edgelet_held_poses and held

    def _confirm(self, res) -> FrameOutcome:
        """A relocalisation (Agility §7) counts only once the tracker confirms it: ``reloc.confirm_frames``
        frames in a row that :func:`~ptam.tracking.relocaliser.confirms`. Until then the frames are not reported
        tracked (a wrong pose is worse than a lost frame); then they all are. A frame that does not confirm sends
        the system back to relocalising."""
        assert self._confirming is not None
        if not confirms(res, self.cfg.reloc) or self._ray_check.refutes(res, self.mapper.snapshot):
            self._confirming = None
            self.state = RELOCALISING
            return FrameOutcome(res.frame_index, res.timestamp, RELOCALISING, None, res)
        self._confirming.append((res.timestamp, se3.inv(res.T_cw)))
        if len(self._confirming) < self.cfg.reloc.confirm_frames:
            return FrameOutcome(res.frame_index, res.timestamp, RELOCALISING, None, res)
        self._record(self._confirming)
        self.stats.relocalisations += 1
        self._confirming = None
        self.state = TrackingState.GOOD
        return FrameOutcome(res.frame_index, res.timestamp, self.state, res.T_cw, res)

    def _record(self, poses: list[tuple[float, np.ndarray]]) -> None:
        """Tracked (timestamp, T_wc) in time order: the trajectory only grows at its end (the viewer and the
        streamed outputs rely on it), so while the frames seen during initialisation are still being posed the
        newer ones are held back."""
        self.stats.tracked += len(poses)
        if self._init.posing:
            self._held.extend(poses)
        else:
            self.trajectory.extend(poses)


def run_dataset(path, cfg: Config, mode: RunMode | str | None = None, **kwargs) -> System:
    """Run a whole dataset folder (TUM/EuRoC/images with its ``camera.yaml``, stamped at ``capture.default_fps``
    where the dataset has no timestamps) through a System; returns it."""
    path = Path(path)
    camera = load_camera(path / "camera.yaml")
    with open_dataset(path, cfg.capture.default_fps) as src, System(camera, cfg, mode=mode, **kwargs) as system:
        for frame in src:
            system.process(frame)
    return system
