"""The camera-model interface shared by every lens model (PTAM §5.2, eq. 2).

Pixel centres are at integer coordinates. ``project`` maps camera-frame points (N, 3) to pixels (N, 2);
``unproject`` maps pixels to rays on the z = 1 plane (N, 2) (the normalised image plane);
``project_jacobian`` gives ∂(u, v)/∂(x, y, z) (N, 2, 3). ``kernel_params`` packs the model into a float64
vector read by the numba kernels in ``ptam/kernels/camproj.py``, whose tests compare against these
numpy methods.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..vocabulary import LensModel

MODEL_IDS = {LensModel.PINHOLE: 0, LensModel.FOV: 1, LensModel.RADTAN: 2}
KERNEL_PARAMS_LEN = 12  # [model_id, fx, fy, cx, cy, d0, d1, d2, d3, d4, max_r, width*height reserved]


class CameraModel(ABC):
    model: str = ""

    def __init__(self, width: int, height: int, fx: float, fy: float, cx: float, cy: float):
        self.width = int(width)
        self.height = int(height)
        self.fx = float(fx)
        self.fy = float(fy)
        self.cx = float(cx)
        self.cy = float(cy)
        self._max_r: float | None = None

    # -- distortion on the normalised plane ------------------------------------------------------
    @abstractmethod
    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Undistorted normalised coordinates (N, 2) -> distorted normalised coordinates (N, 2)."""

    @abstractmethod
    def undistort(self, xy_d: np.ndarray) -> np.ndarray:
        """Distorted normalised coordinates (N, 2) -> undistorted (N, 2)."""

    @abstractmethod
    def distort_jacobian(self, xy: np.ndarray) -> np.ndarray:
        """∂distort/∂xy (N, 2, 2)."""

    @abstractmethod
    def distortion_params(self) -> list[float]:
        """Up to five distortion parameters in the kernel layout."""

    @abstractmethod
    def distortion_dict(self) -> dict:
        """The model's distortion parameters by their camera.yaml names."""

    def to_dict(self) -> dict:
        """The camera.yaml representation."""
        linear = {
            "width": self.width,
            "height": self.height,
            "fx": self.fx,
            "fy": self.fy,
            "cx": self.cx,
            "cy": self.cy,
        }
        return {"model": str(self.model), **linear, **self.distortion_dict()}

    # -- shared machinery --------------------------------------------------------------------------
    @property
    def K(self) -> np.ndarray:
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    def project(self, Xc: np.ndarray) -> np.ndarray:
        Xc = np.asarray(Xc, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            xy = Xc[..., :2] / Xc[..., 2:3]
        d = self.distort(xy.reshape(-1, 2)).reshape(xy.shape)
        return np.stack([self.cx + self.fx * d[..., 0], self.cy + self.fy * d[..., 1]], axis=-1)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, dtype=np.float64)
        d = np.stack([(uv[..., 0] - self.cx) / self.fx, (uv[..., 1] - self.cy) / self.fy], axis=-1)
        return self.undistort(d.reshape(-1, 2)).reshape(d.shape)

    def unproject_rays(self, uv: np.ndarray) -> np.ndarray:
        """Unit-length bearing vectors (N, 3) for pixels (N, 2)."""
        xy = self.unproject(uv)
        r = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], axis=-1)
        return r / np.linalg.norm(r, axis=-1, keepdims=True)

    def project_jacobian(self, Xc: np.ndarray) -> np.ndarray:
        Xc = np.asarray(Xc, dtype=np.float64).reshape(-1, 3)
        z = Xc[:, 2]
        xy = Xc[:, :2] / z[:, None]
        Jd = self.distort_jacobian(xy)  # (N, 2, 2)
        Jn = np.zeros((len(Xc), 2, 3))
        Jn[:, 0, 0] = 1.0 / z
        Jn[:, 1, 1] = 1.0 / z
        Jn[:, 0, 2] = -xy[:, 0] / z
        Jn[:, 1, 2] = -xy[:, 1] / z
        J = Jd @ Jn
        J[:, 0, :] *= self.fx
        J[:, 1, :] *= self.fy
        return J

    @property
    def max_radius(self) -> float:
        """Largest undistorted normalised radius of the image corners (PTAM's mdLargestRadius)."""
        if self._max_r is None:
            w, h = self.width - 1.0, self.height - 1.0
            corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
            xy = self.unproject(corners)
            self._max_r = float(np.max(np.linalg.norm(xy, axis=-1)))
        return self._max_r

    def valid(self, Xc: np.ndarray, radius_factor: float = 1.5) -> np.ndarray:
        """In front of the camera and within ``radius_factor`` × the image's largest radius (PTAM)."""
        Xc = np.asarray(Xc, dtype=np.float64)
        z = Xc[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.hypot(Xc[..., 0], Xc[..., 1]) / z
        return (z > 0) & (r <= radius_factor * self.max_radius)

    def in_image(self, uv: np.ndarray, border: float = 0.0) -> np.ndarray:
        uv = np.asarray(uv, dtype=np.float64)
        return (
            (uv[..., 0] >= border)
            & (uv[..., 1] >= border)
            & (uv[..., 0] <= self.width - 1 - border)
            & (uv[..., 1] <= self.height - 1 - border)
        )

    def kernel_params(self) -> np.ndarray:
        p = np.zeros(KERNEL_PARAMS_LEN)
        p[0] = MODEL_IDS[LensModel(self.model)]
        p[1:5] = (self.fx, self.fy, self.cx, self.cy)
        d = self.distortion_params()
        p[5 : 5 + len(d)] = d
        p[10] = self.max_radius
        return p

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.to_dict()})"
