"""PTAM's camera: pinhole with the FOV radial distortion of Devernay & Faugeras (PTAM §5.2, eq. 3–5).

    r  = sqrt(x² + y²)/z                      (4)
    r' = arctan(2 r tan(ω/2)) / ω             (5)
    (u, v) = (u0, v0) + diag(fu, fv) · (r'/r) · (x/z, y/z)   (3)

The inverse is exact: r = tan(r' ω) / (2 tan(ω/2)).
"""

from __future__ import annotations

import numpy as np

from ..vocabulary import LensModel
from .model import CameraModel

_SMALL_R = 1e-6


class FovCamera(CameraModel):
    model = LensModel.FOV

    def __init__(self, width, height, fx, fy, cx, cy, omega):
        super().__init__(width, height, fx, fy, cx, cy)
        self.omega = float(omega)
        self._t2 = 2.0 * np.tan(self.omega / 2.0)

    def _ratio(self, r):
        """r'/r, with its limit 2·tan(ω/2)/ω at r = 0."""
        rs = np.where(r < _SMALL_R, 1.0, r)
        return np.where(r < _SMALL_R, self._t2 / self.omega, np.arctan(rs * self._t2) / (self.omega * rs))

    def distort(self, xy):
        xy = np.asarray(xy, dtype=np.float64)
        r = np.linalg.norm(xy, axis=-1)
        return xy * self._ratio(r)[..., None]

    def undistort(self, xy_d):
        xy_d = np.asarray(xy_d, dtype=np.float64)
        rd = np.linalg.norm(xy_d, axis=-1)
        rds = np.where(rd < _SMALL_R, 1.0, rd)
        # Beyond r'ω = π/2 no ray exists; clamp so the result is a huge but finite radius.
        ang = np.minimum(rds * self.omega, np.pi / 2 - 1e-9)
        inv = np.where(rd < _SMALL_R, self.omega / self._t2, np.tan(ang) / (self._t2 * rds))
        return xy_d * inv[..., None]

    def distort_jacobian(self, xy):
        xy = np.asarray(xy, dtype=np.float64)
        r = np.linalg.norm(xy, axis=-1)
        g = self._ratio(r)
        # g'(r)/r, with the series limit −(2T)³/(3ω) as r → 0 (T2 = 2·tan(ω/2)).
        rs = np.where(r < 1e-4, 1.0, r)
        dr = (self._t2 / self.omega) / (1.0 + (rs * self._t2) ** 2)  # d r'/d r
        gp_over_r = np.where(
            r < 1e-4, -(self._t2**3) / (3.0 * self.omega), (dr * rs - np.arctan(rs * self._t2) / self.omega) / (rs**3)
        )
        J = np.empty(xy.shape[:-1] + (2, 2))
        J[..., 0, 0] = g + gp_over_r * xy[..., 0] * xy[..., 0]
        J[..., 0, 1] = gp_over_r * xy[..., 0] * xy[..., 1]
        J[..., 1, 0] = J[..., 0, 1]
        J[..., 1, 1] = g + gp_over_r * xy[..., 1] * xy[..., 1]
        return J

    def distortion_params(self):
        return [self.omega]

    def kernel_params(self) -> np.ndarray:
        """ω with 2·tan(ω/2) and 1/ω beside it, which the kernels would otherwise compute for every point."""
        p = super().kernel_params()
        p[6], p[7] = self._t2, 1.0 / self.omega
        return p

    def distortion_dict(self) -> dict:
        return {"omega": self.omega}

    def ptam_vector(self) -> list[float]:
        """PTAM's normalised parameters [fx/W, fy/H, (cx+0.5)/W, (cy+0.5)/H, ω] for its own code."""
        return [
            self.fx / self.width,
            self.fy / self.height,
            (self.cx + 0.5) / self.width,
            (self.cy + 0.5) / self.height,
            self.omega,
        ]
