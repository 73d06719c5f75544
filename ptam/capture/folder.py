"""A folder of images in natural order ("img2" before "img10") at a given frame rate."""

from __future__ import annotations

import os
import re

import numpy as np

from ..errors import InputError
from .images import ImageSequence

IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm", ".tif", ".tiff")

_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> list:
    return [int(part) if part.isdigit() else part.lower() for part in _DIGITS.split(name)]


def list_images(directory: str) -> list[str]:
    names = [
        n
        for n in os.listdir(directory)
        if n.lower().endswith(IMAGE_EXTENSIONS) and os.path.isfile(os.path.join(directory, n))
    ]
    return [os.path.join(directory, n) for n in sorted(names, key=natural_key)]


def open_folder(directory: str, fps: float) -> ImageSequence:
    """Frame i is stamped i / fps seconds."""
    if not os.path.isdir(directory):
        raise InputError(f"image folder not found: {directory}")
    if not fps > 0:
        raise InputError(f"frame rate must be positive, got {fps}")
    paths = list_images(directory)
    if not paths:
        raise InputError(f"no images ({', '.join(e[1:] for e in IMAGE_EXTENSIONS)}) in {directory}")
    return ImageSequence(directory, paths, np.arange(len(paths)) / fps, fps)
