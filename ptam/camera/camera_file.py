"""camera.yaml read/write with validation.

Accepted layout (pixel units, pixel centres at integer coordinates)::

    model: fov            # fov | pinhole | radtan
    width: 640
    height: 480
    fx: 384.0
    fy: 384.0
    cx: 319.5
    cy: 239.5
    omega: 0.9            # fov only
    k1: 0.0               # radtan only: k1 k2 p1 p2 k3 (OpenCV order)

PTAM's own normalised 5-vector is accepted too (``ptam: [fx/W, fy/H, cx/W, cy/H, omega]``, with
cx_px = W·p − 0.5), so calibrations made with PTAM's CameraCalibrator can be reused. So is the EuRoC dataset's
``cam0/sensor.yaml`` (Kalibr's fields: ``resolution: [W, H]``, ``intrinsics: [fu, fv, cu, cv]``, a pinhole
``camera_model``, ``distortion_model: radial-tangential`` with ``distortion_coefficients: [k1, k2, p1, p2]``),
whose pixel convention is ptam's.
"""

from __future__ import annotations

import math
import os

import yaml

from ..errors import InputError
from ..vocabulary import LensModel
from .fov import FovCamera
from .model import CameraModel
from .pinhole import PinholeCamera
from .radtan import RadTanCamera

_MODELS = {"fov": FovCamera, "pinhole": PinholeCamera, "radtan": RadTanCamera}
_DISTORTION_KEYS = {"fov": ("omega",), "pinhole": (), "radtan": ("k1", "k2", "p1", "p2", "k3")}
_KALIBR_LENSES = {"radial-tangential": "radtan", "radtan": "radtan", "none": "pinhole"}


def _number(d: dict, key: str, where: str) -> float:
    if key not in d:
        raise InputError(f"{where}: missing '{key}'")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"{where}: '{key}' must be a finite number, got {v!r}")
    return float(v)


def _numbers(d: dict, key: str, where: str, n: tuple[int, ...]) -> list[float]:
    v = d.get(key)
    if not isinstance(v, (list, tuple)) or len(v) not in n:
        raise InputError(f"{where}: '{key}' must be a list of {' or '.join(map(str, n))} numbers")
    return [_number({key: x}, key, where) for x in v]


def _kalibr_layout(d: dict, where: str) -> dict:
    """A EuRoC ``sensor.yaml`` (Kalibr's camera fields) as a camera.yaml mapping."""
    if d.get("camera_model") != "pinhole":
        raise InputError(f"{where}: camera_model '{d.get('camera_model')}' is not supported (pinhole only)")
    lens = d.get("distortion_model", "none")
    if lens not in _KALIBR_LENSES:
        raise InputError(f"{where}: distortion_model '{lens}' is not supported ({', '.join(_KALIBR_LENSES)})")
    width, height = _numbers(d, "resolution", where, (2,))
    fx, fy, cx, cy = _numbers(d, "intrinsics", where, (4,))
    out = {"model": _KALIBR_LENSES[lens], "width": width, "height": height, "fx": fx, "fy": fy, "cx": cx, "cy": cy}
    if out["model"] == "radtan":
        key = "distortion_coefficients" if "distortion_coefficients" in d else "distortion_coeffs"
        out.update(zip(_DISTORTION_KEYS["radtan"], _numbers(d, key, where, (4, 5))))
    return out


def camera_from_dict(d: dict, where: str = "camera") -> CameraModel:
    """Build and validate a camera model from a camera.yaml mapping (or a EuRoC sensor.yaml's)."""
    if not isinstance(d, dict):
        raise InputError(f"{where}: expected a mapping of camera parameters")
    if "intrinsics" in d:
        d = _kalibr_layout(d, where)
    model = d.get("model", "fov" if "ptam" in d or "omega" in d else "pinhole")
    if model not in _MODELS:
        raise InputError(f"{where}: unknown camera model '{model}' (expected one of {', '.join(_MODELS)})")
    width = _number(d, "width", where)
    height = _number(d, "height", where)
    if width <= 0 or height <= 0 or width != int(width) or height != int(height):
        raise InputError(f"{where}: width and height must be positive integers")
    width, height = int(width), int(height)
    if "ptam" in d:
        vec = d["ptam"]
        if not isinstance(vec, (list, tuple)) or len(vec) != 5:
            raise InputError(f"{where}: 'ptam' must be the 5-vector [fx/W, fy/H, cx/W, cy/H, omega]")
        if model != "fov":
            raise InputError(f"{where}: the 'ptam' 5-vector describes a fov camera, not '{model}'")
        pv = [_number({"v": v}, "v", where) for v in vec]
        fx, fy = pv[0] * width, pv[1] * height
        cx, cy = pv[2] * width - 0.5, pv[3] * height - 0.5
        dist = {"omega": pv[4]}
    else:
        fx, fy, cx, cy = (_number(d, k, where) for k in ("fx", "fy", "cx", "cy"))
        dist = {k: (_number(d, k, where) if (k in d or k == "omega") else 0.0) for k in _DISTORTION_KEYS[model]}
    if fx <= 0 or fy <= 0:
        raise InputError(f"{where}: focal lengths must be positive (fx={fx:g}, fy={fy:g})")
    if not (0 <= cx <= width - 1 and 0 <= cy <= height - 1):
        raise InputError(f"{where}: principal point ({cx:g}, {cy:g}) lies outside the {width}x{height} image")
    if model == LensModel.FOV and not (0 < dist["omega"] < math.pi):
        raise InputError(f"{where}: omega must be in (0, pi), got {dist['omega']:g}")
    return _MODELS[model](width, height, fx, fy, cx, cy, **dist)


def load_camera(path: str | os.PathLike) -> CameraModel:
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"calibration file not found: {path}")
    try:
        with open(path) as f:
            d = yaml.safe_load(f)
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read calibration {path}: {str(e).splitlines()[0]}") from None
    return camera_from_dict(d, where=path)


def save_camera(camera: CameraModel, path: str | os.PathLike) -> None:
    d = camera.to_dict()
    with open(path, "w") as f:
        yaml.safe_dump(d, f, sort_keys=False)
