"""Open the frame source named on the command line (``--camera``, ``--video`` or ``--dataset``)."""

from __future__ import annotations

import re

from ..config import CaptureConfig
from ..errors import InputError
from .dataset import open_dataset
from .dc1394 import SCHEME as DC1394_SCHEME
from .dc1394 import Dc1394Source
from .source import FrameSource
from .v4l2 import CameraSource
from .video import VideoSource

_SIZE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def parse_size(size: str | tuple[int, int] | list[int]) -> tuple[int, int]:
    """``"640x480"`` or ``(640, 480)`` -> (640, 480)."""
    if isinstance(size, str):
        m = _SIZE.match(size)
        if not m:
            raise InputError(f"size must be WIDTHxHEIGHT, e.g. 640x480, got '{size}'")
        w, h = int(m.group(1)), int(m.group(2))
    else:
        w, h = (int(v) for v in size)
    if w <= 0 or h <= 0:
        raise InputError(f"size must be positive, got {w}x{h}")
    return w, h


def open_source(
    cfg: CaptureConfig,
    camera: str | None = None,
    video: str | None = None,
    dataset: str | None = None,
    fps: float | None = None,
    size: str | tuple[int, int] | None = None,
) -> FrameSource:
    """Exactly one of ``camera``, ``video``, ``dataset``. ``fps`` stamps image folders and is requested from
    cameras; ``size`` is requested from cameras. Defaults come from ``cfg``, the ``capture`` config section."""
    given = [name for name, v in (("camera", camera), ("video", video), ("dataset", dataset)) if v is not None]
    if len(given) != 1:
        raise InputError(f"give exactly one frame source (camera, video or dataset), got {len(given)}")
    if fps is not None and not fps > 0:
        raise InputError(f"frame rate must be positive, got {fps}")
    if camera is not None:
        camera_size = parse_size(size if size is not None else cfg.camera_size)
        camera_fps = fps if fps is not None else cfg.camera_fps
        if camera.partition(":")[0] == DC1394_SCHEME:
            return Dc1394Source(camera, camera_size, camera_fps, cfg)
        return CameraSource(camera, camera_size, camera_fps)
    if video is not None:
        return VideoSource(video, cfg.default_fps, cfg.video_missing_frames_tolerance)
    return open_dataset(dataset, fps if fps is not None else cfg.default_fps)
