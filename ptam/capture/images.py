"""A sequence of image files with timestamps: the common core of image folders, TUM and EuRoC datasets.

Images are decoded lazily, one per iteration step, so a long dataset never sits in memory.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence

import cv2
import numpy as np

from ..errors import InputError
from .convert import grey_and_colour
from .frame import Frame
from .source import FrameSource


def read_image(path: str) -> np.ndarray:
    """Decode one image file as 8-bit grey or BGR (deeper images keep their top byte, alpha is dropped)."""
    img = cv2.imread(path, cv2.IMREAD_ANYCOLOR)
    if img is None:
        raise InputError(f"cannot read image {path}")
    return img


class ImageSequence(FrameSource):
    """Frames from ``paths`` stamped with ``timestamps`` (seconds). Every image must have the first one's size."""

    def __init__(self, name: str, paths: Sequence[str], timestamps: np.ndarray, fps: float):
        if len(paths) == 0:
            raise InputError(f"{name}: no images")
        missing = [p for p in paths if not os.path.isfile(p)]
        if missing:
            more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
            raise InputError(f"{name}: image file not found: {missing[0]}{more}")
        self.name = name
        self.paths = list(paths)
        self.timestamps = np.asarray(timestamps, dtype=np.float64)
        self.fps = float(fps)
        self.length = len(self.paths)
        h, w = read_image(self.paths[0]).shape[:2]
        self.size = (w, h)

    def __len__(self) -> int:
        return self.length

    def close(self) -> None:
        """Nothing to release: each image file is opened and closed as it is read."""

    def __iter__(self) -> Iterator[Frame]:
        w, h = self.size
        for i, path in enumerate(self.paths):
            img = read_image(path)
            if img.shape[:2] != (h, w):
                raise InputError(f"image {path} is {img.shape[1]}x{img.shape[0]}, expected {w}x{h} like the first")
            grey, colour = grey_and_colour(img)
            yield Frame(i, float(self.timestamps[i]), grey, colour)


def check_increasing(path: str, timestamps: np.ndarray, linenos: Sequence[int]) -> None:
    """Refuse an index file whose timestamps (read from lines ``linenos``) do not increase strictly: frames
    would be replayed out of order, or two frames would share one time."""
    back = np.flatnonzero(np.diff(np.asarray(timestamps, dtype=np.float64)) <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise InputError(
            f"{path}:{linenos[i]}: timestamp {timestamps[i]} is not after the previous image's {timestamps[i - 1]} "
            f"(timestamps must increase strictly)"
        )


def fps_from_timestamps(timestamps: np.ndarray, fallback: float) -> float:
    """The median frame rate of a timestamped sequence (robust to dropped frames)."""
    dt = np.diff(np.asarray(timestamps, dtype=np.float64))
    dt = dt[dt > 0]
    return float(1.0 / np.median(dt)) if dt.size else float(fallback)
