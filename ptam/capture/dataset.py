"""``--dataset DIR``: recognise a TUM RGB-D, EuRoC or plain image-folder layout, and find its calibration and
ground truth."""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError
from ..eval import read_tum
from .euroc import find_cam0, open_euroc
from .euroc_groundtruth import body_to_camera, find_euroc_groundtruth, read_euroc_groundtruth
from .folder import open_folder
from .images import ImageSequence
from .tum import INDEX_FILE, open_tum

CALIBRATION_FILE = "camera.yaml"
GROUNDTRUTH_FILE = "groundtruth.txt"  # TUM's, and what ``ptam synth`` writes
EUROC_CALIBRATION_FILE = "sensor.yaml"  # beside cam0's data.csv


def dataset_kind(directory: str) -> str:
    """``"tum"``, ``"euroc"`` or ``"folder"``."""
    if not os.path.isdir(directory):
        raise InputError(f"dataset directory not found: {directory}")
    if os.path.isfile(os.path.join(directory, INDEX_FILE)):
        return "tum"
    if find_cam0(directory) is not None:
        return "euroc"
    return "folder"


def open_dataset(directory: str | os.PathLike, fps: float) -> ImageSequence:
    """The dataset in ``directory``; ``fps`` (``capture.default_fps`` on the command line) stamps a plain folder
    and is the fallback rate of a TUM or EuRoC sequence, which carry their own timestamps."""
    directory = os.fspath(directory)
    kind = dataset_kind(directory)
    if kind == "tum":
        return open_tum(directory, fps)
    if kind == "euroc":
        return open_euroc(directory, fps)
    return open_folder(directory, fps)


def find_calibration(directory: str) -> str | None:
    """``DIR/camera.yaml`` if the dataset ships one, else a EuRoC dataset's ``cam0/sensor.yaml``."""
    path = os.path.join(directory, CALIBRATION_FILE)
    return path if os.path.isfile(path) else _euroc_sensor(directory)


def _euroc_sensor(directory: str) -> str | None:
    """A EuRoC sequence's ``cam0/sensor.yaml``, if ``directory`` is one and it ships the file."""
    cam0 = find_cam0(directory) if os.path.isdir(directory) else None
    sensor = None if cam0 is None else os.path.join(cam0, EUROC_CALIBRATION_FILE)
    return sensor if sensor is not None and os.path.isfile(sensor) else None


def find_groundtruth(directory: str) -> tuple[str, np.ndarray, np.ndarray] | None:
    """The dataset's ground truth for its camera, if it ships one: (file, timestamps (N,) s, camera-to-world poses
    (N, 4, 4)) from ``DIR/groundtruth.txt`` (TUM layout), else from a EuRoC sequence's body poses and its cam0
    ``T_BS``."""
    tum = os.path.join(directory, GROUNDTRUTH_FILE)
    if os.path.isfile(tum):
        return (tum, *read_tum(tum))
    euroc = find_euroc_groundtruth(directory) if os.path.isdir(directory) else None
    if euroc is None:
        return None
    return (euroc, *read_euroc_groundtruth(euroc, body_to_camera(_euroc_sensor(directory))))
