"""A live camera through Video4Linux2 (``v4l2``, ``v4l2:1`` or ``v4l2:/dev/video1``) at a requested size
and frame rate (PTAM §7: 640x480 at 30 Hz). Timestamps are the driver's buffer times when it provides
them, else the host's monotonic clock at the moment the frame arrives."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import cv2

from ..errors import InputError
from .convert import grey_and_colour
from .dc1394 import iidc_camera_present
from .frame import Frame
from .opencv_log import quiet_opencv
from .source import FrameSource

SCHEME = "v4l2"


def parse_camera(spec: str) -> int | str:
    """``v4l2`` -> 0, ``v4l2:N`` -> N, ``v4l2:/dev/videoN`` -> the path."""
    scheme, _, device = spec.partition(":")
    if scheme != SCHEME:
        raise InputError(f"unknown camera '{spec}' (expected v4l2, v4l2:N or v4l2:/dev/videoN)")
    if not device:
        return 0
    if device.isdigit():
        return int(device)
    if device.startswith("/"):
        return device
    raise InputError(f"unknown camera device '{device}' in '{spec}' (expected a number or a /dev path)")


def _iidc_hint() -> str:
    """FireWire IIDC cameras are not V4L2 devices (PTAM §7 captured them through libdc1394): when libdc1394
    sees one, say so. One bus enumeration, never an error of its own."""
    if iidc_camera_present():
        return ": no V4L2 device, but an IIDC (FireWire) camera is on the bus: use --camera dc1394"
    return ""


class CameraSource(FrameSource):
    length = None

    def __init__(self, spec: str, size: tuple[int, int], fps: float):
        device = parse_camera(spec)
        self.name = spec
        quiet_opencv()
        self._cap = cv2.VideoCapture(device, cv2.CAP_V4L2)
        if not self._cap.isOpened():
            self._cap.release()
            raise InputError(f"cannot open camera {spec}{_iidc_hint()}")
        self._cap.set(cv2.CAP_PROP_FRAME_WIDTH, size[0])
        self._cap.set(cv2.CAP_PROP_FRAME_HEIGHT, size[1])
        self._cap.set(cv2.CAP_PROP_FPS, fps)
        # The driver may grant a different mode; report what it actually delivers.
        self.size = (int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        granted = self._cap.get(cv2.CAP_PROP_FPS)
        self.fps = float(granted) if math.isfinite(granted) and granted > 0 else float(fps)

    def __iter__(self) -> Iterator[Frame]:
        driver_times = None
        index = 0
        while True:
            ok, img = self._cap.read()
            if not ok or img is None:
                raise InputError(f"camera {self.name} stopped delivering frames")
            arrival = time.monotonic()
            ms = self._cap.get(cv2.CAP_PROP_POS_MSEC)
            if driver_times is None:
                driver_times = math.isfinite(ms) and ms > 0
            grey, colour = grey_and_colour(img)
            yield Frame(index, ms / 1000.0 if driver_times else arrival, grey, colour)
            index += 1

    def close(self) -> None:
        self._cap.release()
