"""Camera models (PTAM's FOV/ATAN model, pinhole, OpenCV radtan) and camera.yaml IO."""

from .camera_file import camera_from_dict, load_camera, save_camera
from .fov import FovCamera
from .model import MODEL_IDS, CameraModel
from .pinhole import PinholeCamera
from .radtan import RadTanCamera

__all__ = [
    "CameraModel",
    "MODEL_IDS",
    "FovCamera",
    "PinholeCamera",
    "RadTanCamera",
    "load_camera",
    "save_camera",
    "camera_from_dict",
]
