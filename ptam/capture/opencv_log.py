"""Keep OpenCV's and FFmpeg's own warnings off stderr: a bad video or camera must give the user one line
(our :class:`~ptam.errors.InputError`), not a page of decoder chatter."""

from __future__ import annotations

import os

import cv2

_FFMPEG_QUIET = "-8"  # AV_LOG_QUIET


def quiet_opencv() -> None:
    """Call before opening a capture; OpenCV reads the FFmpeg level when it opens one."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", _FFMPEG_QUIET)
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
