"""The EuRoC MAV layout: ``mav0/cam0/data.csv`` with ``timestamp_ns,filename`` rows (``#`` header) and the
images in ``mav0/cam0/data/``. The dataset root, ``mav0`` or ``cam0`` itself may be given."""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError
from .images import ImageSequence, check_increasing, fps_from_timestamps

_NS_PER_S = 1_000_000_000


def find_cam0(directory: str) -> str | None:
    """The ``cam0`` directory of a EuRoC dataset given its root, ``mav0`` or ``cam0``; None if not EuRoC."""
    for cam0 in (os.path.join(directory, "mav0", "cam0"), os.path.join(directory, "cam0"), directory):
        if os.path.isfile(os.path.join(cam0, "data.csv")) and os.path.isdir(os.path.join(cam0, "data")):
            return cam0
    return None


def read_data_csv(path: str) -> tuple[np.ndarray, list[str]]:
    """Timestamps in seconds (N,), strictly increasing, and image paths in the sibling ``data/`` folder."""
    data_dir = os.path.join(os.path.dirname(path), "data")
    ns, paths, linenos = [], [], []
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read {path}: {e}") from None
    for lineno, line in enumerate(lines, 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = [p.strip() for p in text.split(",")]
        try:
            if len(parts) != 2 or not parts[1]:
                raise ValueError
            stamp = int(parts[0])
            if not -(2**63) <= stamp < 2**63:
                raise ValueError
        except ValueError:
            raise InputError(f"{path}:{lineno}: expected 'timestamp_ns,filename', got {text!r}") from None
        ns.append(stamp)
        paths.append(os.path.join(data_dir, parts[1]))
        linenos.append(lineno)
    if not paths:
        raise InputError(f"{path}: lists no images")
    ns = np.array(ns, dtype=np.int64)
    check_increasing(path, ns, linenos)  # in integer nanoseconds: exact, before any float conversion
    return seconds(ns), paths


def seconds(ns: np.ndarray) -> np.ndarray:
    """EuRoC's integer nanosecond stamps in seconds: whole seconds split from the remainder, so that the float
    conversion keeps every nanosecond it can."""
    return (ns // _NS_PER_S).astype(np.float64) + (ns % _NS_PER_S) / _NS_PER_S


def open_euroc(directory: str, fallback_fps: float) -> ImageSequence:
    cam0 = find_cam0(directory)
    if cam0 is None:
        raise InputError(f"not a EuRoC dataset (no mav0/cam0/data.csv): {directory}")
    stamps, paths = read_data_csv(os.path.join(cam0, "data.csv"))
    return ImageSequence(directory, paths, stamps, fps_from_timestamps(stamps, fallback_fps))
