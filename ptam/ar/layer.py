"""The AR overlay attached to a running ``System``, off the tracker's critical path (DESIGN.md, Concurrency).

:class:`ArLayer` is a system observer: in the tracker's thread it only hands (frame image, T_cw, map snapshot)
to its own worker thread through a bounded buffer of ``ar.queue_frames`` frames; the worker refreshes the
plane, renders, writes the video and publishes ``latest`` for a viewer. Images are shared, not copied: pyramid
and keyframe images are immutable once created.

When the buffer is full — the worker is slower than the tracker for ``ar.queue_frames`` frames in a row — a
layer that writes a video makes the tracker wait for a free slot, so the video stays drop-free (one frame per
tracked frame); a layer without a video drops its oldest frame instead and never blocks tracking.

Drawing is the worker's main cost, and it competes with the tracker for the cores and the GIL, so a frame is drawn
only when someone looks at it: every frame when a video is written, else only the frames a view (the viewer)
:meth:`ArView.wants` — those it has time and room for (a layer without views draws every frame, for ``latest``).
The scene still advances every frame (``Augmenter.advance``).

Frames seen while the system initialises are kept (the last ``ar.init_buffer_frames``): when stereo
initialisation succeeds, the system tracks the frames between the two keyframes retroactively (their poses go
to its trajectory), and the layer augments them then, before the frame that completed initialisation — so the
video has exactly one frame per trajectory pose.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from ..errors import InputError, PtamError
from ..geometry import se3
from ..vocabulary import TrackingState
from .augmenter import Augmenter
from .kernel_warm_up import warm_overlay_kernels
from .scenes import SCENES
from .video_writer import open_video_writer


def frame_image(frame) -> np.ndarray:
    """What the overlay is drawn on: the colour original when the source is colour, else the grey image."""
    return frame.colour if frame.colour is not None else frame.image


class ArView(Protocol):
    """Where augmented frames are shown (a viewer). Both calls run in the AR worker's thread and must not block."""

    def wants(self, index: int, timestamp: float) -> bool:
        """Whether to draw frame ``index`` for this view; asked, in frame order, only of frames nothing else
        needs drawn (no video is written)."""

    def show(self, index: int, timestamp: float, bgr: np.ndarray) -> None:
        """Frame ``index`` as drawn: a new uint8 image, the view's to keep: BGR (H, W, 3), or grey (H, W) when the
        frame and its overlay are grey (``OverlayRenderer.render``'s ``grey_ok``)."""


class ArLayer:
    """Observer ``f(outcome, system)``; ``close()`` (or a ``with`` block) flushes the buffer and the video.

    ``latest``: (frame index, timestamp, image) of the newest augmented frame (BGR, or grey as in
    :meth:`ArView.show`); ``listeners``: the views
    (:class:`ArView`) shown every drawn frame; ``undrawn``: frames advanced but not drawn, as no view wanted
    them; ``fire()`` and ``set_scene(name)``: key presses, called from any thread and applied by the worker
    before its next frame (the scene is only ever touched in the worker's thread).
    """

    def __init__(
        self,
        camera,
        cfg,
        scene: str | None = None,
        video_path: str | Path | None = None,
        fps: float | None = None,
        T_pw: np.ndarray | None = None,
    ):
        warm_overlay_kernels(camera, cfg)  # here, not on the first frame: that is when the map is youngest
        self.augmenter = Augmenter(camera, cfg, scene, T_pw)
        self.capacity = max(int(cfg.ar.queue_frames), 1)
        fps = cfg.capture.default_fps if fps is None else fps
        self.writer = open_video_writer(video_path, camera.size, fps) if video_path else None
        self.video_path = video_path
        self.listeners: list[ArView] = []
        self.latest: tuple[int, float, np.ndarray] | None = None
        self.frames_rendered = 0
        self.frames_written = 0
        self.dropped = 0
        self.undrawn = 0
        self.render_ms: list[float] = []
        self.cpu_s = 0.0  # the worker's CPU time on frames: scene, drawing, video and views (its cost to the cores)
        self._pending: deque = deque(maxlen=max(int(cfg.ar.init_buffer_frames), 0))
        self._items: deque = deque()
        self._cond = threading.Condition()
        self._closing = False
        self._error: BaseException | None = None
        self._fire = False
        self._next_scene: str | None = None
        self.scene_name = str(self.augmenter.scene.name)  # the scene shown, or asked for by set_scene
        self._thread = threading.Thread(target=self._run, name="ptam-ar", daemon=True)
        self._thread.start()

    @property
    def scene(self):
        return self.augmenter.scene

    def fire(self) -> None:
        """A key press for the game: fires at the next augmented frame (other scenes ignore it)."""
        with self._cond:
            self._fire = True

    def set_scene(self, name: str) -> None:
        """Show scene ``name`` (eyes | game | grid | off) from the next augmented frame on."""
        if name not in SCENES:  # fails here, in the caller's thread
            raise InputError(f"unknown AR scene '{name}' (choose from {', '.join(SCENES)})")
        with self._cond:
            self._next_scene = self.scene_name = str(name)

    # -- tracker thread ------------------------------------------------------------------------------------
    def __call__(self, outcome, system) -> None:
        frame = outcome.frame
        if frame is None:
            return
        if outcome.T_cw is None:
            if outcome.state == TrackingState.INITIALISING:
                self._pending.append(frame)
            return
        snapshot = system.mapper.snapshot
        if outcome.result is None and self._pending:  # this frame completed stereo initialisation
            poses = dict(system.trajectory[:-1])  # the first keyframe and the frames tracked since
            for f in self._pending:
                T_wc = poses.get(float(f.timestamp))
                if T_wc is not None:
                    self.submit(frame_image(f), se3.inv(T_wc), f.index, f.timestamp, snapshot)
        self._pending.clear()
        self.submit(frame_image(frame), outcome.T_cw, outcome.index, outcome.timestamp, snapshot)

    def submit(self, image: np.ndarray, T_cw: np.ndarray, index: int, timestamp: float, snapshot=None) -> None:
        item = (image, np.array(T_cw, np.float64), int(index), float(timestamp), snapshot)
        with self._cond:
            self._check()
            if self._closing:
                raise PtamError("AR layer: frame submitted after close()")
            while len(self._items) >= self.capacity:
                if self.writer is None:
                    self._items.popleft()
                    self.dropped += 1
                    break
                self._cond.wait()  # drop-free video: wait for the worker to take a frame
                self._check()
            self._items.append(item)
            self._cond.notify_all()

    def _check(self) -> None:
        if self._error is not None:
            err, self._error = self._error, None
            raise err

    # -- worker thread -------------------------------------------------------------------------------------
    def _run(self) -> None:
        try:
            while True:
                with self._cond:
                    while not self._items and not self._closing:
                        self._cond.wait()
                    if not self._items:
                        return
                    image, T_cw, index, timestamp, snapshot = self._items.popleft()
                    fire, self._fire = self._fire, False
                    next_scene, self._next_scene = self._next_scene, None
                    self._cond.notify_all()
                if fire:  # pressed before the scene switch, if both are pending
                    self.augmenter.scene.fire()
                if next_scene is not None:
                    self.augmenter.set_scene(next_scene)
                self._frame(image, T_cw, index, timestamp, snapshot)
        except BaseException as e:  # re-raised in the tracker's thread at the next frame or at close()
            with self._cond:
                self._error = e
                self._items.clear()
                self._cond.notify_all()

    def _frame(self, image: np.ndarray, T_cw: np.ndarray, index: int, timestamp: float, snapshot) -> None:
        c0 = time.thread_time()
        try:
            self._draw_frame(image, T_cw, index, timestamp, snapshot)
        finally:
            self.cpu_s += time.thread_time() - c0

    def _draw_frame(self, image: np.ndarray, T_cw: np.ndarray, index: int, timestamp: float, snapshot) -> None:
        step = self.augmenter.advance(T_cw, timestamp, snapshot)
        views = self.listeners
        # Every view is asked (a list, not a short-circuiting generator): each one paces itself.
        if self.writer is None and views and not any([view.wants(index, timestamp) for view in views]):
            self.undrawn += 1
            return
        t0 = time.perf_counter()
        bgr = self.augmenter.draw(image, step, grey_ok=True)
        self.render_ms.append(1e3 * (time.perf_counter() - t0))
        self.frames_rendered += 1
        if self.writer is not None:
            self.writer.write(bgr if bgr.ndim == 3 else cv2.cvtColor(bgr, cv2.COLOR_GRAY2BGR))
            self.frames_written += 1
        self.latest = (index, timestamp, bgr)
        for view in views:
            view.show(index, timestamp, bgr)

    # -- shutdown ------------------------------------------------------------------------------------------
    def close(self) -> None:
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self._thread.join()
        if self.writer is not None:
            self.writer.release()
            self.writer = None
        with self._cond:
            self._check()

    def __enter__(self) -> ArLayer:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def attach(system, scene: str | None = None, video_path: str | Path | None = None, fps: float | None = None) -> ArLayer:
    """An :class:`ArLayer` for ``system`` (its camera and config), registered as one of its observers.

    ``scene``: eyes | game | grid | off (default ``ar.scene``); ``video_path``: .avi or .mp4 to write the
    augmented frames to, one per tracked frame; ``fps``: the video's frame rate (the source's). Call
    ``close()`` when the stream ends.
    """
    layer = ArLayer(system.camera, system.cfg, scene, video_path, fps)
    system.observers.append(layer)
    return layer
