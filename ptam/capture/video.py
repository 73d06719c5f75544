"""A video file decoded by OpenCV. Timestamps come from the container (CAP_PROP_POS_MSEC); a container
without usable timestamps falls back to index / fps."""

from __future__ import annotations

import math
import os
from collections.abc import Iterator

import cv2

from ..errors import InputError
from .convert import grey_and_colour
from .frame import Frame
from .opencv_log import quiet_opencv
from .source import FrameSource


class VideoSource(FrameSource):
    def __init__(self, path: str, fallback_fps: float, missing_frames_tolerance: int):
        if not os.path.isfile(path):
            raise InputError(f"video file not found: {path}")
        self.name = path
        self._tolerance = missing_frames_tolerance
        self._cap = self._open()
        w = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH))
        h = int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if w <= 0 or h <= 0:
            self.close()
            raise InputError(f"cannot read video {path}: no decodable video stream")
        self.size = (w, h)
        fps = self._cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(fps) if math.isfinite(fps) and fps > 0 else float(fallback_fps)
        count = self._cap.get(cv2.CAP_PROP_FRAME_COUNT)
        self.length = int(count) if math.isfinite(count) and count > 0 else None
        self._used = False

    def _open(self) -> cv2.VideoCapture:
        quiet_opencv()
        cap = cv2.VideoCapture(self.name)
        if not cap.isOpened():
            raise InputError(f"cannot open video {self.name} (unreadable, truncated or corrupt)")
        return cap

    def __len__(self) -> int:
        if self.length is None:
            raise TypeError(f"video {self.name} does not state its frame count")
        return self.length

    def __iter__(self) -> Iterator[Frame]:
        if self._used:
            self._cap.release()
            self._cap = self._open()
        self._used = True
        container_times = True
        t_prev = -math.inf
        index = 0
        while True:
            ok, img = self._cap.read()
            if not ok or img is None:
                break
            ms = self._cap.get(cv2.CAP_PROP_POS_MSEC)
            t = ms / 1000.0
            # Trust the container only if frame 1 moves its clock forward; keep the stream monotonic after that.
            if index == 1 and not (math.isfinite(t) and t > t_prev):
                container_times = False
            if not container_times or not math.isfinite(t) or t < 0:
                t = index / self.fps
            elif t <= t_prev:
                t = t_prev + 1.0 / self.fps
            t_prev = t
            grey, colour = grey_and_colour(img)
            yield Frame(index, t, grey, colour)
            index += 1
        if self.length is not None and index < self.length - self._tolerance:
            raise InputError(f"video {self.name} ended after {index} of {self.length} frames (truncated or corrupt)")

    def close(self) -> None:
        self._cap.release()
