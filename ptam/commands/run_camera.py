"""The camera a run tracks with: its calibration file, else the loaded map's camera, checked against the frames the
source delivers and the map's keyframes before the first frame."""

from __future__ import annotations

import logging

import numpy as np

from ..camera import CameraModel, load_camera
from ..errors import InputError
from ..image.pyramid import Pyramid

log = logging.getLogger("ptam")


def run_camera(calibration, map_camera: CameraModel | None, source, image_cfg) -> CameraModel:
    """The camera of ``calibration`` (a camera.yaml path, or None) or else ``map_camera``; an InputError when there
    is neither, or when its image size is not the source's or the map's, or too small for the pyramid."""
    if calibration:
        camera = load_camera(calibration)
    elif map_camera is not None:
        camera = map_camera
    else:
        raise InputError("no calibration: pass --calibration camera.yaml")
    if camera.size != source.size:
        where = f"calibration {calibration}" if calibration else "the map's camera"
        raise InputError(
            f"{where} is for {camera.width}x{camera.height} images but "
            f"{source.name} delivers {source.size[0]}x{source.size[1]}"
        )
    Pyramid.build(np.zeros((camera.height, camera.width), np.uint8), image_cfg)  # frames fit the pyramid
    if map_camera is None:
        return camera
    if camera.size != map_camera.size:
        # The keyframes' images, patches and relocalisation descriptors are at the map's size.
        raise InputError(
            f"the map was built from {map_camera.width}x{map_camera.height} images but {source.name} "
            f"delivers {camera.width}x{camera.height}; build a new map for this camera"
        )
    if camera.to_dict() != map_camera.to_dict():
        log.warning("the calibration differs from the camera the map was built with; tracking uses %s", calibration)
    return camera
