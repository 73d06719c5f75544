"""Projecting edgelets into a view and their tracking Jacobian (Agility §4.2 eq. 3–5, §5.1 eq. 10–11).

The centre is transformed into the camera frame and projected, c = CamProj(E_KE (0 0 0 1)ᵀ) (eq. 3–4). The
image direction d is the derivative of that projection with respect to motion along the edgelet's z-axis
(eq. 5), i.e. the projection Jacobian applied to the camera-frame direction; its length |d| is pixels per
unit length along the edgelet, which places the BA sample points (eq. 6). The image normal is
``perp(d̂)``, the dark-to-light side by the polarity convention of ``ptam.edgelet.edgelet``.

For tracking, an edgelet gives one perpendicular distance; its 1×6 Jacobian with respect to the camera pose
(update T ← exp(μ) T, μ = (translation, rotation)) is J = n̂ᵀ ∂CamProj/∂X_c · [I | −[X_c]×] (eq. 11), and
the expected edge-normal blur length is l = |J γ_C| for the camera motion γ_C during the exposure (eq. 10).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import CameraModel
from .edgelet import Edgelets
from .edgelet_projection_kernels import edgelet_projection


@dataclass(frozen=True)
class ImageEdgelets:
    """Edgelets in one image: ``centre`` (N, 2) px, ``direction`` (N, 2) px per unit length (eq. 5),
    unit ``normal`` (N, 2) dark → light, ``valid`` (N,) in front of the camera and in the lens' range."""

    centre: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    valid: np.ndarray
    camera_centre: np.ndarray  # (N, 3) the edgelet centres in the camera frame

    @property
    def unit_direction(self) -> np.ndarray:
        n = np.linalg.norm(self.direction, axis=-1, keepdims=True)
        return self.direction / np.where(n > 0, n, 1.0)


def project_edgelets(camera: CameraModel, T_cw: np.ndarray, edgelets: Edgelets) -> ImageEdgelets:
    """Centres, image directions and dark-to-light normals of ``edgelets`` seen from pose ``T_cw`` (§4.2)."""
    return project_edgelets_with_jacobian(camera, T_cw, edgelets, jacobian=False)[0]


def project_edgelets_with_jacobian(
    camera: CameraModel, T_cw: np.ndarray, edgelets: Edgelets, jacobian: bool = True
) -> tuple[ImageEdgelets, np.ndarray]:
    """``project_edgelets`` and each edgelet's (N, 6) ∂ε/∂μ_C of eq. 11 ((0, 6) without ``jacobian``), from one
    projection (``edgelet_projection_kernels``)."""
    c, d, n, valid, Xc, J = edgelet_projection(
        camera.kernel_params(),
        np.ascontiguousarray(T_cw, dtype=np.float64),
        np.ascontiguousarray(edgelets.centre, dtype=np.float64).reshape(-1, 3),
        np.ascontiguousarray(edgelets.direction, dtype=np.float64).reshape(-1, 3),
        jacobian,
    )
    return ImageEdgelets(c, d, n, valid, Xc), J


def blur_lengths(jacobian: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """Edge-normal blur l = |J γ_C| (eq. 10) for Jacobians (N, 6) and the camera motion during exposure (6,)."""
    return np.abs(np.asarray(jacobian, dtype=np.float64) @ np.asarray(gamma, dtype=np.float64))
