"""EuRoC's ground truth for its camera: ``mav0/state_groundtruth_estimate0/data.csv`` holds the body (IMU) pose in
the world at nanosecond timestamps (position, then the quaternion w, x, y, z, then velocities and biases), and
``cam0/sensor.yaml``'s ``T_BS`` takes the camera frame into the body frame, so the camera-to-world pose is
T_WB·T_BS, the pose ``ptam run`` reports for each frame."""

from __future__ import annotations

import os

import numpy as np
import yaml

from ..errors import InputError
from ..geometry import so3
from .euroc import find_cam0, seconds
from .images import check_increasing

GROUNDTRUTH_CSV = os.path.join("state_groundtruth_estimate0", "data.csv")  # beside cam0 in mav0
_POSE_FIELDS = 8  # timestamp, p_RS_R x y z, q_RS w x y z


def find_euroc_groundtruth(directory: str) -> str | None:
    """The ground-truth file of the EuRoC sequence in ``directory`` (its root, ``mav0`` or ``cam0``), if any."""
    cam0 = find_cam0(directory)
    path = None if cam0 is None else os.path.join(os.path.dirname(os.path.abspath(cam0)), GROUNDTRUTH_CSV)
    return path if path is not None and os.path.isfile(path) else None


def body_to_camera(sensor_yaml: str | None) -> np.ndarray:
    """``T_BS`` of a cam0 ``sensor.yaml`` (the camera frame in the body frame); the identity without one."""
    if sensor_yaml is None or not os.path.isfile(sensor_yaml):
        return np.eye(4)
    try:
        with open(sensor_yaml) as f:
            data = (yaml.safe_load(f) or {}).get("T_BS", {}).get("data")
        T = np.array(data, dtype=np.float64).reshape(4, 4)
    except (OSError, yaml.YAMLError, UnicodeDecodeError, AttributeError, TypeError, ValueError):
        raise InputError(f"{sensor_yaml}: T_BS must be a 4x4 'data' list") from None
    if not np.all(np.isfinite(T)) or not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-6):
        raise InputError(f"{sensor_yaml}: T_BS is not a rigid transform")
    return T


def read_euroc_groundtruth(path: str, T_BS: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Timestamps (N,) in seconds and the camera's camera-to-world poses T_WB·T_BS (N, 4, 4)."""
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read {path}: {e}") from None
    ns: list[int] = []
    rows: list[list[float]] = []
    linenos: list[int] = []
    for lineno, line in enumerate(lines, 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split(",")
        try:
            if len(parts) < _POSE_FIELDS:
                raise ValueError
            stamp, row = int(parts[0]), [float(p) for p in parts[1:_POSE_FIELDS]]
            if not np.all(np.isfinite(row)) or not np.any(row[3:]):
                raise ValueError
        except ValueError:
            raise InputError(f"{path}:{lineno}: expected 'timestamp_ns,px,py,pz,qw,qx,qy,qz,...'") from None
        ns.append(stamp)
        rows.append(row)
        linenos.append(lineno)
    if not rows:
        raise InputError(f"{path}: holds no poses")
    stamps_ns = np.array(ns, dtype=np.int64)
    check_increasing(path, stamps_ns, linenos)
    data = np.array(rows)
    T_WB = np.zeros((len(data), 4, 4))
    T_WB[:, :3, :3] = so3.from_quaternion(data[:, [4, 5, 6, 3]])  # (x, y, z, w)
    T_WB[:, :3, 3] = data[:, :3]
    T_WB[:, 3, 3] = 1.0
    return seconds(stamps_ns), T_WB @ T_BS
