"""Builders shared by tests: cameras, synthetic problems. Not part of the ptam package."""

from __future__ import annotations

import functools
from pathlib import Path

from ptam.config import CaptureConfig, Config, load_config
from ptam.synthetic import ensure_sequence

# A six-frame 80x60 scene: renders in well under a second.
TINY = """\
camera: {model: fov, width: 80, height: 60, fx: 48.0, fy: 48.0, cx: 39.5, cy: 29.5, omega: 0.9}
frames: 6
fps: 10
rectangles:
  - {name: wall, center: [0, 0, 3], axes: [[1, 0, 0], [0, 1, 0]], size: [12, 9],
     texture: {type: dead_leaves, seed: 3, texel: 0.02, sizes: [0.05, 1.0], detail: 2}}
trajectory:
  up: [0, -1, 0]
  keys:
    - {frame: 0, position: [0, 0, 0], look_at: [0, 0, 3]}
    - {frame: 5, position: [0.5, 0, 0], look_at: [0.5, 0, 3]}
render:
  noise: {sigma: 1.0, seed: 2}
"""


@functools.cache
def config() -> Config:
    """The default configuration, loaded once per test session (not at import)."""
    return load_config()


def capture() -> CaptureConfig:
    return config().capture


def sequence(name: str, video: bool = False) -> Path:
    """A bundled synthetic sequence, rendered into the session's cache (``conftest.py`` points it at a temporary
    directory)."""
    return ensure_sequence(name, config().synthetic, video=video)


def read_video(path) -> list:
    """Every frame of a video file, as OpenCV decodes it (BGR)."""
    import cv2

    cap = cv2.VideoCapture(str(path))
    assert cap.isOpened(), path
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    cap.release()
    return frames
