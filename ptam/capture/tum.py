"""The TUM RGB-D benchmark layout: ``rgb.txt`` lists ``timestamp path`` per line (``#`` starts a comment),
paths relative to the dataset directory, timestamps in seconds."""

from __future__ import annotations

import math
import os

import numpy as np

from ..errors import InputError
from .images import ImageSequence, check_increasing, fps_from_timestamps

INDEX_FILE = "rgb.txt"


def read_rgb_txt(path: str) -> tuple[np.ndarray, list[str]]:
    """Timestamps (N,), strictly increasing, and paths (made absolute against the file's directory)."""
    base = os.path.dirname(path)
    stamps, paths, linenos = [], [], []
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read {path}: {e}") from None
    for lineno, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        parts = text.split()
        try:
            if len(parts) != 2:
                raise ValueError
            t = float(parts[0])
            if not math.isfinite(t):
                raise ValueError
        except ValueError:
            raise InputError(f"{path}:{lineno}: expected 'timestamp path', got {line.strip()!r}") from None
        stamps.append(t)
        paths.append(os.path.join(base, parts[1]))
        linenos.append(lineno)
    if not paths:
        raise InputError(f"{path}: lists no images")
    check_increasing(path, np.array(stamps), linenos)
    return np.array(stamps), paths


def open_tum(directory: str, fallback_fps: float) -> ImageSequence:
    stamps, paths = read_rgb_txt(os.path.join(directory, INDEX_FILE))
    return ImageSequence(directory, paths, stamps, fps_from_timestamps(stamps, fallback_fps))
