"""The viewer's side of the AR view (``camera/augmented``): the AR layer's :class:`ptam.ar.layer.ArView`.

Everything here runs in the AR worker's thread, never in the tracker's or the viewer's logging thread. The
worker draws a frame only if the view :meth:`wants` it: drawing costs the tracker, as it competes for the cores
(and the GIL; ``ptam bench ar``), so the view asks for no more than ``viewer.ar_max_fps`` frames a second and none
while the logging thread's queue is full (they would not be logged). A drawn frame is encoded here, in the worker,
by OpenCV, which releases the GIL: the logging thread, already busy with the rest of the frame, only logs it.
"""

from __future__ import annotations

import queue
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
import rerun as rr

# Source timestamps jitter: a frame up to this fraction of a period before its due time still counts as due
# (display pacing only, not a tunable).
_DUE_SLACK = 0.25


@dataclass(frozen=True)
class ArFrame:
    """One augmented frame for the logging thread, ready to log on the camera's timelines."""

    index: int
    timestamp: float
    image: rr.EncodedImage | rr.Image


class FramePacer:
    """At most ``max_fps`` frames a second on the frame timeline (the source's timestamps, so a file replayed
    faster than real time shows the same frames; 0: every frame). Due times advance by whole periods, so a
    30 Hz source at 15 shows every other frame, and a due frame not taken leaves its slot to the next one; after
    a gap, or when time runs backwards, pacing restarts."""

    def __init__(self, max_fps: float):
        self.period = 1.0 / max_fps if max_fps > 0 else 0.0
        self._next: float | None = None
        self._last = -np.inf

    def _restart(self, t: float) -> bool:
        return self._next is None or not self._last <= t < self._next + self.period

    def due(self, timestamp: float) -> bool:
        """Whether the frame at ``timestamp`` may be shown."""
        t = float(timestamp)
        return self.period == 0.0 or self._restart(t) or t >= self._next - _DUE_SLACK * self.period

    def take(self, timestamp: float) -> None:
        """The frame at ``timestamp`` (due) is shown: the next one is due a period later."""
        t = float(timestamp)
        self._next = t + self.period if self._restart(t) else self._next + self.period
        self._last = t


class AugmentedView:
    """The AR layer's view for a viewer: ``viewer_cfg`` its config, ``out`` its logging queue, ``alive`` whether
    its logging thread still runs. ``dropped``: frames not logged for lack of room (or after the viewer closed)."""

    def __init__(self, viewer_cfg, out: queue.Queue, alive: Callable[[], bool]):
        self.cfg = viewer_cfg
        self.out = out
        self.alive = alive
        self.pacer = FramePacer(viewer_cfg.ar_max_fps)
        self.dropped = 0

    def wants(self, index: int, timestamp: float) -> bool:
        """Frame ``index`` is due (``viewer.ar_max_fps``) and the logging queue has room; a due frame without
        room is dropped, and leaves its slot to the next frame."""
        if not self.pacer.due(timestamp):
            return False
        if not self._room():
            self.dropped += 1
            return False
        self.pacer.take(timestamp)
        return True

    def show(self, index: int, timestamp: float, bgr: np.ndarray) -> None:
        """Queue frame ``index`` (BGR uint8, or grey: ``ArView.show``) for logging as ``camera/augmented``; never
        waits."""
        image = self._encode(bgr) if self._room() else None
        if image is None:
            self.dropped += 1
            return
        try:
            self.out.put_nowait(ArFrame(int(index), float(timestamp), image))
        except queue.Full:  # the tracker's frame took the last place meanwhile
            self.dropped += 1

    def _room(self) -> bool:
        return self.alive() and not self.out.full()

    def _encode(self, bgr: np.ndarray) -> rr.EncodedImage | rr.Image | None:
        """JPEG like the camera image (a grey frame as a one-channel JPEG), or the exact BGR pixels
        (``viewer.ar_image_lossless``); None if OpenCV cannot encode it (a display problem never stops the AR
        worker)."""
        if self.cfg.ar_image_lossless:
            return rr.Image(bgr if bgr.ndim == 3 else cv2.cvtColor(bgr, cv2.COLOR_GRAY2BGR), color_model="BGR")
        ok, jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, self.cfg.jpeg_quality])
        return rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg") if ok else None
