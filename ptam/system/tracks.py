"""New tracks on loss and their merging (Gauglitz et al. TVCG 2013 §4.4, §5.3).

When tracking is lost, PTAM relocalises into its one map until that succeeds, and everything the camera sees
meanwhile is discarded. With ``tracks.new_on_loss`` the lost track is set aside and a new, unconnected track
(its own map, frame and scale) starts initialising at once; every frame without a map is still relocalised
into each set-aside track, and a confirmed relocalisation makes that track current again. In the mapper's idle
time (:class:`~.merge_search.MergeSearch`) the current track's keyframes are compared with the other tracks';
an overlap merges the other track's map into the current one (:func:`~ptam.mapping.track_merge.absorb`), so
the tracker never changes frame. Each track keeps the poses tracked in it; a merge moves them into the frame
they joined, and at the end of the run the largest track (most frames) is the trajectory and its map the map,
the others (``System.other_tracks``) are written beside it.

Threads: the tracker's thread sets tracks aside and switches between them; the mapper's thread (or, in
``sync`` mode, the tracker's, after a keyframe) merges. Both take ``_tracks_lock`` for these rare events only,
never per frame; pose bookkeeping of a merge is handed to the tracker's thread through a deque.
"""

from __future__ import annotations

import logging
import threading
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..geometry import se3
from ..geometry.sim3 import Similarity
from ..image.pyramid import Pyramid
from ..image.sbi import SmallBlurryImage
from ..mapping.map_maker import MapMaker
from ..mapping.track_merge import absorb
from ..tracking.relocaliser import Relocaliser, confirms
from ..tracking.tracker import Tracker
from ..vocabulary import TrackingState
from .frame_outcome import FrameOutcome
from .merge_search import MergeSearch
from .ray_check import RayCheck
from .run_stats import RunStats
from .stereo_start import StereoStart

log = logging.getLogger("ptam")


@dataclass(eq=False)
class Track:
    """A set-aside track: its mapper (and map), the (timestamp, T_wc) poses tracked in it, its relocaliser."""

    id: int
    mapper: MapMaker
    poses: list
    relocaliser: Relocaliser


@dataclass(frozen=True)
class Merged:
    """Track ``other`` (with its ``poses``) joined track ``into`` through ``sim`` (other's frame -> into's)."""

    other: int
    into: int
    sim: Similarity
    poses: list


class Tracks:
    """Mixed into :class:`~ptam.system.core.System`, whose state it uses (declared here for the type checker)."""

    camera: CameraModel
    cfg: Config
    localize_only: bool
    mapper: MapMaker
    tracker: Tracker
    relocaliser: Relocaliser
    trajectory: list[tuple[float, np.ndarray]]
    state: TrackingState
    stats: RunStats
    _init: StereoStart
    _confirming: list | None
    _good_streak: int
    _ray_check: RayCheck

    def _init_tracks(self) -> None:
        self.track_id = 0
        self._next_track_id = 1
        self._dormant: dict[int, Track] = {}
        self._tracks_lock = threading.Lock()
        self._merged: deque[Merged] = deque()
        self._forward: dict[int, tuple[int, Similarity]] = {}  # merged track -> (the track it joined, sim)
        self._merge_search = MergeSearch(self.camera, self.cfg)
        self.other_tracks: dict[int, list] = {}  # after close(): poses of the tracks not merged into the largest
        self._candidate: tuple[Track, list] | None = None  # a relocalisation into a set-aside track, confirming

    @property
    def track_mappers(self) -> dict[int, MapMaker]:
        """Every track's mapper (and map) by track id: the current one and those set aside."""
        return {**{t.id: t.mapper for t in tuple(self._dormant.values())}, self.track_id: self.mapper}

    # -- the tracker's thread ---------------------------------------------------------------------------
    def _new_track_on_loss(self) -> bool:
        return self.cfg.tracks.new_on_loss and not self.localize_only

    def _lose_track(self, frame, pyramid: Pyramid) -> FrameOutcome:
        """Gauglitz §4.4: set the lost track aside and start a new one from this frame."""
        self._collect_posed(wait=True)
        with self._tracks_lock:
            if self.mapper.initialised:
                self._dormant[self.track_id] = Track(self.track_id, self.mapper, self.trajectory, self.relocaliser)
                log.info("tracking lost: track %d set aside, track %d starts", self.track_id, self._next_track_id)
            self.track_id, self._next_track_id = self._next_track_id, self._next_track_id + 1
            self.mapper = MapMaker(self.camera, self.cfg)
        self.trajectory = []
        self.relocaliser = Relocaliser(self.camera, self.cfg)
        self._init.abandon()
        self._init = StereoStart(self.camera, self.cfg, background=self._build_in_background())
        self.state = TrackingState.INITIALISING
        self._confirming = None
        self._candidate = None
        self._good_streak = 0
        return self._without_map(frame, pyramid)

    def _without_map(self, frame, pyramid: Pyramid | None = None) -> FrameOutcome:
        """A frame while the current track has no map: relocalised into a set-aside track (the new track keeps
        initialising beside it until the relocalisation is confirmed), else initialising."""
        if pyramid is None:
            pyramid = Pyramid.build(frame.image, self.cfg.image)
        relocalising = bool(self._dormant) and self.cfg.reloc.enabled
        if relocalising:
            out = self._candidate_frame(frame, pyramid)
            if out is not None:
                return out
        out = self._initialise(frame, pyramid)
        if relocalising and out.state == TrackingState.INITIALISING:
            out.state = TrackingState.RELOCALISING  # what the user sees: the set-aside tracks are still sought
        return out

    def _candidate_frame(self, frame, pyramid: Pyramid) -> FrameOutcome | None:
        """Agility §7 into the set-aside tracks: the best accepted relocalisation becomes a candidate, tracked
        against its track's map until ``reloc.confirm_frames`` frames in a row confirm it (as
        :meth:`System._confirm`); then that track is current again. None while there is no confirmed one."""
        if self._candidate is None:
            reloc = self._relocalise_set_aside(pyramid)
            self.stats.reloc_attempts += 1
            if reloc is None:
                return None
            self.tracker.set_pose(reloc[1].T_cw, recovered=True)
            self._candidate = (reloc[0], [])
        t, poses = self._candidate
        res = self.tracker.track(frame, t.mapper.snapshot, pyramid)
        if not confirms(res, self.cfg.reloc) or self._ray_check.refutes(res, t.mapper.snapshot):
            self._candidate = None
            return None
        poses.append((res.timestamp, se3.inv(res.T_cw)))
        if len(poses) < self.cfg.reloc.confirm_frames:
            return None
        self._candidate = None
        if not self._switch_to(t):
            return None
        log.info("relocalised into track %d", t.id)
        self.trajectory.extend(poses)
        self.stats.tracked += len(poses)
        self.stats.relocalisations += 1
        self.state = TrackingState.GOOD
        return FrameOutcome(res.frame_index, res.timestamp, self.state, res.T_cw, res)

    def _relocalise_set_aside(self, pyramid: Pyramid):
        """Agility §7 over every set-aside track's keyframes at once: the frame's descriptor is made once, the
        keyframe it is nearest to in any track is aligned, as if the tracks' keyframes were one list (a frame
        costs the same however many tracks a long session has set aside). (track, accepted relocalisation)."""
        frame = SmallBlurryImage.from_pyramid(pyramid, self.cfg.reloc.blur_sigma)
        best, best_ssd = None, np.inf
        for t in tuple(self._dormant.values()):  # a copy: the mapper's thread may remove a merged track
            t.relocaliser.sync(t.mapper.snapshot)
            if t.relocaliser.n_keyframes:
                ssd = float(t.relocaliser.descriptor_ssd(frame).min())
                if ssd < best_ssd:
                    best, best_ssd = t, ssd
        if best is None:
            return None
        r = best.relocaliser.attempt(pyramid, best.mapper.snapshot, frame)
        return (best, r) if r is not None and r.accepted else None

    def _switch_to(self, t: Track) -> bool:
        """Make set-aside track ``t`` current (unless the mapper's thread merged it meanwhile); a current track
        with a map is set aside, one still initialising is dropped."""
        with self._tracks_lock:
            if self._dormant.pop(t.id, None) is None:
                return False
            if self.mapper.initialised:
                self._dormant[self.track_id] = Track(self.track_id, self.mapper, self.trajectory, self.relocaliser)
            self.track_id, self.mapper = t.id, t.mapper
        self.trajectory, self.relocaliser = t.poses, t.relocaliser
        self._init.abandon()  # the new track's initialisation, if any, is dropped with it
        self._init = StereoStart(self.camera, self.cfg, background=self._build_in_background())
        return True

    def _apply_merges(self) -> None:
        """The tracker's side of merges done in the mapper's thread: move the merged track's poses (under the lock,
        taken only when a merge happened: the mapper's thread reads a set-aside track's poses when it merges it)."""
        while self._merged:
            with self._tracks_lock:
                self._apply_merge(self._merged.popleft())

    def _apply_merge(self, mg: Merged) -> None:
        moved = _moved(mg.poses, mg.sim)
        self.stats.tracks_merged += 1
        into = mg.into
        while into != self.track_id and into not in self._dormant and into in self._forward:
            into, sim = self._forward[into]  # that track was merged on too, before this reached here
            moved = _moved(moved, sim)
        if into == self.track_id:
            self.trajectory = sorted(self.trajectory + moved, key=lambda p: p[0])
        elif into in self._dormant:
            t = self._dormant[into]
            t.poses = sorted(t.poses + moved, key=lambda p: p[0])

    def _settle_tracks(self) -> None:
        """At the end of the run: the largest track becomes current (trajectory and map); the poses of the
        others go to ``other_tracks``."""
        self._apply_merges()
        tracks = list(self._dormant.values())
        if not tracks:
            return
        largest = max(tracks, key=lambda t: len(t.poses))
        if len(largest.poses) > len(self.trajectory) or not self.mapper.initialised:
            self._switch_to(largest)
        self.other_tracks = {t.id: t.poses for t in self._dormant.values() if t.poses}

    def _reset_tracks(self) -> None:
        with self._tracks_lock:
            self._dormant = {}
        self._merged.clear()
        self._forward = {}
        self._candidate = None
        self.other_tracks = {}

    # -- the mapper's thread (the tracker's in sync mode) -----------------------------------------------
    def _step_set_aside(self) -> bool:
        """One unit of a set-aside track's mapping work (Gauglitz §5: the background thread serves every track),
        once the current track's mapper is idle and no merge is left to try (§5: after a loss merging comes
        first, so that it can be as quick as relocalisation); False when none has any."""
        return any(t.mapper.step() for t in tuple(self._dormant.values()))

    def _merge_tracks(self) -> bool:
        """One step of the search for an overlap with a set-aside track (Gauglitz §5.3), and the merge if one is
        found; False when there was nothing to try."""
        if not (self.cfg.tracks.merge and self._dormant):
            return False
        with self._tracks_lock:
            track, mapper, others = self.track_id, self.mapper, list(self._dormant.values())
        if not mapper.initialised:
            return False
        snaps = [(t.id, t.mapper.snapshot) for t in others if t.mapper.snapshot is not None]
        worked, overlap = self._merge_search.find(track, mapper.snapshot, snaps)
        if overlap is None:
            return worked
        with self._tracks_lock:
            other = self._dormant.pop(overlap.other, None)
            if other is None:
                return True
            self._forward[other.id] = (track, overlap.sim)
        absorb(mapper, dict(snaps)[other.id], overlap.sim, overlap.link)  # the snapshot the overlap was found in
        self._merged.append(Merged(other.id, track, overlap.sim, other.poses))
        log.info("track %d merged into track %d (scale %.3f)", other.id, track, overlap.sim.s)
        return True

    if TYPE_CHECKING:  # defined by the System and its other mixins

        def _collect_posed(self, wait: bool = False) -> None: ...
        def _build_in_background(self) -> bool: ...
        def _initialise(self, frame, pyramid: Pyramid | None = None) -> FrameOutcome: ...
        def _track(self, frame) -> FrameOutcome: ...


def _moved(poses: list, sim: Similarity) -> list:
    """(timestamp, T_wc) poses of a track moved into the frame it joined."""
    T = np.array([T for _, T in poses]).reshape(-1, 4, 4)
    return list(zip([ts for ts, _ in poses], sim.poses_wc(T)))
