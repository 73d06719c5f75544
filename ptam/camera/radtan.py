"""OpenCV's radial-tangential (Brown–Conrady) model with k1, k2, p1, p2, k3.

The inverse has no closed form; ``undistort`` runs Gauss–Newton on the 2×2 forward Jacobian from the
distorted point, per point in a kernel (``camproj_kernels.undistort_points``; numpy reference
``tests/reference/camera.py``), until the normalised residual is below 1e-14.
"""

from __future__ import annotations

import numpy as np

from ..vocabulary import LensModel
from .camproj_kernels import RADTAN, UNDISTORT_ITERS, UNDISTORT_TOL, undistort_points
from .model import KERNEL_PARAMS_LEN, CameraModel


class RadTanCamera(CameraModel):
    model = LensModel.RADTAN

    def __init__(self, width, height, fx, fy, cx, cy, k1=0.0, k2=0.0, p1=0.0, p2=0.0, k3=0.0):
        super().__init__(width, height, fx, fy, cx, cy)
        self.k1, self.k2, self.p1, self.p2, self.k3 = map(float, (k1, k2, p1, p2, k3))

    def distort(self, xy):
        xy = np.asarray(xy, dtype=np.float64)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        rad = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        xd = x * rad + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        yd = y * rad + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return np.stack([xd, yd], axis=-1)

    def distort_jacobian(self, xy):
        xy = np.asarray(xy, dtype=np.float64)
        x, y = xy[..., 0], xy[..., 1]
        r2 = x * x + y * y
        rad = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        drad = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2)  # d rad / d r2
        J = np.empty(xy.shape[:-1] + (2, 2))
        J[..., 0, 0] = rad + x * drad * 2 * x + 2 * self.p1 * y + self.p2 * 6 * x
        J[..., 0, 1] = x * drad * 2 * y + 2 * self.p1 * x + self.p2 * 2 * y
        J[..., 1, 0] = y * drad * 2 * x + self.p1 * 2 * x + 2 * self.p2 * y
        J[..., 1, 1] = rad + y * drad * 2 * y + self.p1 * 6 * y + 2 * self.p2 * x
        return J

    def undistort(self, xy_d):
        xy_d = np.asarray(xy_d, dtype=np.float64)
        flat = np.ascontiguousarray(xy_d.reshape(-1, 2))
        # Only the model and its distortion: kernel_params() needs max_radius, which is computed by undistorting.
        cam = np.zeros(KERNEL_PARAMS_LEN)
        cam[0] = RADTAN
        cam[5:10] = self.distortion_params()
        return undistort_points(cam, flat, UNDISTORT_ITERS, UNDISTORT_TOL).reshape(xy_d.shape)

    def distortion_params(self):
        return [self.k1, self.k2, self.p1, self.p2, self.k3]

    def distortion_dict(self) -> dict:
        return {"k1": self.k1, "k2": self.k2, "p1": self.p1, "p2": self.p2, "k3": self.k3}
