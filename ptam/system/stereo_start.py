"""Stereo initialisation without stalling the tracker (PTAM §6.1; DESIGN: nothing slow on the tracker's thread).

PTAM builds its first map in the tracker's thread, which at 30 Hz drops the ~20 frames the two-view geometry
and the first bundle adjustments take, and resumes from a pose that is that many frames stale. Here the map is
built by a worker (inline in ``sync`` mode, so runs stay deterministic) while the tracker keeps following the
trails. A frame is remembered only by its trails — which trail, where (a few kB, never the image) — in a
bounded history; once the map exists, each remembered frame is posed by PnP against the points its trails
became, and tracking resumes from the newest one.
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera.model import CameraModel
from ..config import Config
from ..geometry import so3
from ..image.pyramid import Pyramid
from ..mapping.map_maker import MapMaker
from ..mapping.stereo_init import StereoMap, init_from_stereo
from ..mapping.two_view import AmbiguousPair, InitFailure
from ..tracking.trails import TrailTracker
from .priority import lower_priority
from .rotation_start import RotationStart


@dataclass(frozen=True)
class TrailFrame:
    """A frame seen while initialising, by its trails: their ids (``TrailTracker.ids``) and pixels."""

    index: int
    timestamp: float
    ids: np.ndarray
    xy: np.ndarray


@dataclass(frozen=True)
class Built:
    """A finished attempt: the mapper holding the new map, or the reason it failed; the trail ids of the points
    made from trails (row for row with ``stereo.point_ids``)."""

    mapper: MapMaker | None
    failure: str | None
    stereo: StereoMap | None
    trail_ids: np.ndarray
    first: tuple[int, float]  # (index, timestamp) of each keyframe
    second: tuple[int, float]
    ambiguous: bool = False  # the pair fitted two poses equally: keep the trails, a later second keyframe may not


class StereoStart:
    """The trails from the first keyframe, the bounded history of frames since, and the map being built."""

    def __init__(self, camera: CameraModel, cfg: Config, background: bool):
        self.camera = camera
        self.cfg = cfg
        self.trails = TrailTracker(cfg.init, cfg.image)
        self.first: tuple[Pyramid, float, int] | None = None
        self.waiting = False  # a pair from these trails was ambiguous: later ones are tried, frame by frame
        self.history: deque[TrailFrame] = deque(maxlen=cfg.init.max_history_frames)
        self._pool = (
            ThreadPoolExecutor(1, "ptam-init", lower_priority, (cfg.system.background_nice,)) if background else None
        )
        self._job: Future | None = None
        self._posing: Future | None = None
        ms = cfg.model_selection
        # Gauglitz §4.3, §6: tracked from the first frame, in a panorama, until this map exists.
        self.rotation = RotationStart(camera, cfg, background) if ms.enabled and ms.initialisation_free else None

    @property
    def started(self) -> bool:
        return self.first is not None

    @property
    def building(self) -> bool:
        return self._job is not None

    def start(self, pyramid: Pyramid, index: int, timestamp: float) -> int:
        """Trails from a new first keyframe; returns how many started."""
        n = self.trails.start(pyramid)
        self.first = (pyramid, timestamp, index)
        self.waiting = False
        self.history.clear()
        self._remember(index, timestamp)
        return n

    def stop(self) -> None:
        self.first = None
        self.history.clear()

    def advance(self, pyramid: Pyramid, index: int, timestamp: float) -> int:
        """Follow the trails into frame ``index``: around where the rotation the panorama tracked from the previous
        trail frame moves them (``init.trail_rotation_prior``), or where they were."""
        R = None
        if self.rotation is not None and self.cfg.init.trail_rotation_prior and self.history:
            R = self.rotation.turned(self.history[-1].index, index)
        n = self.trails.advance(pyramid, None if R is None else self.trails.rotated(self.camera, R))
        self._remember(index, timestamp)
        return n

    def _remember(self, index: int, timestamp: float) -> None:
        t = self.trails
        self.history.append(TrailFrame(index, timestamp, t.ids.copy(), t.current_xy.copy()))

    def build(self, pyramid: Pyramid, index: int, timestamp: float) -> None:
        """Build the map from the first keyframe and this frame (the second keyframe), in the worker."""
        assert self.first is not None
        t = self.trails
        kf0, kf1 = self.first[:2], (pyramid, timestamp)
        args = (kf0, kf1, (self.first[2], self.first[1]), (index, timestamp), t.start_xy, t.current_xy, t.ids)
        if self._pool is None:
            self._job = _done(self._build(*args))
        else:
            self._job = self._pool.submit(self._build, *args)

    def _build(self, kf0, kf1, first, second, xy0, xy1, ids) -> Built:
        mapper = MapMaker(self.camera, self.cfg)
        try:
            stereo = init_from_stereo(mapper, kf0, kf1, xy0, xy1)
        except InitFailure as e:
            return Built(None, str(e), None, np.zeros(0, np.int64), first, second, isinstance(e, AmbiguousPair))
        return Built(mapper, None, stereo, ids[stereo.trail_rows], first, second)

    def finished(self) -> Built | None:
        """The finished attempt, once (None while it is still being built)."""
        if self._job is None or not self._job.done():
            return None
        job, self._job = self._job, None
        return job.result()

    def wait(self) -> Built:
        """The attempt being built, waiting for it."""
        assert self._job is not None
        job, self._job = self._job, None
        return job.result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        if self.rotation is not None:
            self.rotation.close()

    def abandon(self) -> None:
        """Drop this initialisation, a map being built included, without waiting for the worker."""
        self.stop()
        self._job = self._posing = None
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        if self.rotation is not None:
            self.rotation.close()

    # -- posing the remembered frames ---------------------------------------------------------------------
    def adopt(self, built: Built) -> tuple[TrailFrame, np.ndarray | None]:
        """The newest remembered frame and its pose (None if PnP fails), computed now so tracking resumes from it;
        the other remembered frames are posed in the worker (:meth:`posed` hands them over)."""
        frames = list(self.history)
        self.history.clear()
        newest = frames.pop()
        T = self.pose_frames(built, [newest])
        if self._pool is None:
            self._posing = _done(self.pose_frames(built, frames))
        else:
            self._posing = self._pool.submit(self.pose_frames, built, frames)
        return newest, (T[0][1] if T else None)

    @property
    def posing(self) -> bool:
        return self._posing is not None

    def posed(self, wait: bool = False) -> list[tuple[TrailFrame, np.ndarray]]:
        """Poses of the other remembered frames, once they are ready (or waiting for them)."""
        if self._posing is None or not (wait or self._posing.done()):
            return []
        job, self._posing = self._posing, None
        return job.result()

    def pose_frames(self, built: Built, frames: list[TrailFrame]) -> list[tuple[TrailFrame, np.ndarray]]:
        """(frame, T_cw): the two keyframes from the map, the others by PnP on the points their trails became
        (frames too few of whose trails survive are left out)."""
        assert built.mapper is not None and built.stereo is not None
        m = built.mapper.map
        point_of = np.full(self.cfg.init.max_trails, -1, np.int64)  # trail id -> point id
        point_of[built.trail_ids] = built.stereo.point_ids
        keyframes = {built.first[0]: m.kf_T_cw[0], built.second[0]: m.kf_T_cw[1]}
        posed = []
        for fr in frames:  # one PnP per remembered frame, once per initialisation
            T = keyframes.get(fr.index)
            if T is None:
                T = self._pnp(fr, point_of, m.X, m.bad)
            if T is not None:
                posed.append((fr, T.copy()))
        return posed

    def _pnp(self, fr: TrailFrame, point_of: np.ndarray, X: np.ndarray, bad: np.ndarray) -> np.ndarray | None:
        c = self.cfg.init
        p = point_of[fr.ids]
        ok = p >= 0
        ok[ok] = ~bad[p[ok]]
        if ok.sum() < c.min_inliers:
            return None
        obj, img = X[p[ok]], self.camera.unproject(fr.xy[ok].astype(np.float64))
        f = 0.5 * (self.camera.fx + self.camera.fy)
        found, rvec, tvec, inliers = cv2.solvePnPRansac(
            obj, img, np.eye(3), None, reprojectionError=c.history_pnp_max_error_px / f,
            confidence=c.ransac_confidence, flags=cv2.SOLVEPNP_EPNP,
        )  # fmt: skip
        if not found or inliers is None or len(inliers) < c.min_inliers:
            return None
        i = inliers[:, 0]
        rvec, tvec = cv2.solvePnPRefineLM(obj[i], img[i], np.eye(3), None, rvec, tvec)
        T = np.eye(4)
        T[:3, :3] = so3.exp(rvec.ravel())
        T[:3, 3] = tvec.ravel()
        return T


def _done(result) -> Future:
    """A finished future: sync mode runs the worker's jobs inline, through the same hand-over."""
    f: Future = Future()
    f.set_result(result)
    return f
