"""Ideal pinhole camera: no distortion."""

from __future__ import annotations

import numpy as np

from ..vocabulary import LensModel
from .model import CameraModel


class PinholeCamera(CameraModel):
    model = LensModel.PINHOLE

    def distort(self, xy):
        return np.asarray(xy, dtype=np.float64).copy()

    def undistort(self, xy_d):
        return np.asarray(xy_d, dtype=np.float64).copy()

    def distort_jacobian(self, xy):
        return np.broadcast_to(np.eye(2), (len(xy), 2, 2)).copy()

    def distortion_params(self):
        return []

    def distortion_dict(self) -> dict:
        return {}
