"""Inter-frame camera rotation from small blurry images ("image-based motion initialisation", Agility §6).

Each frame's small blurry image (σ = ``rotation.blur_sigma``) is aligned to the previous frame's by ESM over
SE(2) (``rotation.iterations``); the image motion is converted to the best-fit 3-D camera rotation through a
few virtual sample points about the image centre, unprojected through the camera model before and after the
image motion (a procedure like the unscented transform, §6). The rotation replaces the motion model's
(§8; :meth:`ptam.tracking.motion_model.MotionModel.predict`). With ``rotation.robust`` the alignment is
Tukey-weighted, so that something moving before the camera on its own (§9.3 names a hand) does not turn the
estimate after it.
"""

from __future__ import annotations

import numpy as np

from ..geometry import so3
from ..image.pyramid import Pyramid, level_to_zero
from ..image.sbi import Alignment, SmallBlurryImage, small_level


def sample_offsets(radius: float) -> np.ndarray:
    """Virtual sample points about the image centre (4, 2), in small-image pixels (PTAM code: ±5 px in x;
    the y pair pins roll and tilt symmetrically)."""
    r = float(radius)
    return np.array([[r, 0.0], [-r, 0.0], [0.0, r], [0.0, -r]])


def rotation_from_se2(
    camera, params: np.ndarray, shape: tuple[int, int], level: int, offsets: np.ndarray
) -> np.ndarray:
    """The camera rotation R (3, 3) taking template-camera bearings to aligned-camera bearings that best explains
    the SE(2) alignment ``params`` of small images of ``shape`` (H, W) at pyramid ``level`` (Agility §6;
    PTAM code ``SE3fromSE2``): sample points x and their images c + R(θ)(x − c) + t, unprojected to unit rays
    a and b, and R = argmin Σ |R a − b|² (Kabsch)."""
    h, w = shape
    c = np.array([0.5 * (w - 1), 0.5 * (h - 1)])
    t, theta = params[:2], params[2]
    cs, sn = np.cos(theta), np.sin(theta)
    turned = offsets @ np.array([[cs, sn], [-sn, cs]]) + c + t
    a = camera.unproject_rays(level_to_zero(offsets + c, level))
    b = camera.unproject_rays(level_to_zero(turned, level))
    U, _, Vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


class RotationEstimator:
    """Agility §6. :meth:`estimate` takes each new frame's pyramid and returns the rotation vector (3,) of the
    camera from the previous frame to this one (the rotation part of the SE(3) motion in μ = (t, ω)), or None
    for the first frame after :meth:`reset`."""

    def __init__(self, camera, rotation_cfg):
        self.camera = camera
        self.cfg = rotation_cfg
        self.offsets = sample_offsets(rotation_cfg.sample_radius_px)
        self.previous: SmallBlurryImage | None = None
        self.last: Alignment | None = None

    def reset(self) -> None:
        self.previous = None
        self.last = None

    def estimate(self, pyramid: Pyramid) -> np.ndarray | None:
        c = self.cfg
        current = SmallBlurryImage.from_pyramid(pyramid, c.blur_sigma)
        previous, self.previous = self.previous, current
        if previous is None:
            self.last = None
            return None
        self.last = current.align_to(previous, c.iterations, c.intensity_offset, robust=c.robust)
        R = rotation_from_se2(self.camera, self.last.params, current.image.shape, small_level(pyramid), self.offsets)
        return so3.log(R)
