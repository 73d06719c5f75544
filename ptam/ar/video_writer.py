"""The AR video file: Motion-JPEG in .avi or MPEG-4 part 2 in .mp4, both written and read back by OpenCV's
FFmpeg backend (checked on this OpenCV 5 build; H.264 ``avc1`` is not available to it)."""

from __future__ import annotations

from pathlib import Path

import cv2

from ..errors import InputError

FOURCC = {".avi": "MJPG", ".mp4": "mp4v"}


def open_video_writer(path: str | Path, size: tuple[int, int], fps: float) -> cv2.VideoWriter:
    path = Path(path)
    codec = FOURCC.get(path.suffix.lower())
    if codec is None:
        raise InputError(f"--ar-video {path}: use a .avi (Motion-JPEG) or .mp4 (MPEG-4) file name")
    if not path.parent.is_dir():
        raise InputError(f"--ar-video {path}: directory {path.parent} does not exist")
    if not fps > 0:
        raise InputError(f"--ar-video {path}: frame rate must be positive, got {fps}")
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*codec), float(fps), tuple(size), True)
    if not writer.isOpened():
        raise InputError(f"--ar-video {path}: OpenCV cannot write {codec} video there")
    return writer
