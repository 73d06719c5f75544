"""Frame sources: video files, live v4l2 and FireWire IIDC (dc1394) cameras, image folders, TUM RGB-D and EuRoC
datasets."""

from .dataset import find_calibration, find_groundtruth, open_dataset
from .dc1394 import Dc1394Source
from .euroc import open_euroc
from .folder import open_folder
from .frame import Frame
from .images import ImageSequence
from .source import FrameSource
from .sources import open_source, parse_size
from .tum import open_tum
from .v4l2 import CameraSource
from .video import VideoSource

__all__ = [
    "Frame",
    "FrameSource",
    "ImageSequence",
    "VideoSource",
    "CameraSource",
    "Dc1394Source",
    "open_source",
    "open_dataset",
    "open_folder",
    "open_tum",
    "open_euroc",
    "find_calibration",
    "find_groundtruth",
    "parse_size",
]
