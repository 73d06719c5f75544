"""Edgelets as 3-D coordinate frames E_WE (Agility §4.1, Fig. 1).

An edgelet is a short, locally straight piece of an intensity edge. Agility §4.1 stores it as a rigid
transform E_WE whose origin is the edgelet's centre and whose z-axis is its direction; the x-axis points from
dark to light in the keyframe where the edgelet was first observed, and y = z × x completes a right-handed
frame. Many edgelets are stored as a structure of arrays: ``centre``, ``direction`` (z) and ``normal`` (x),
each (N, 3) in world coordinates.

Polarity in other views. The paper does not use the x-axis for visibility; it infers the dark-to-light
direction "from the edgelet direction" (§4.1). Here that convention is: the 3-D direction is oriented so that
in the image the dark-to-light normal is ``perp(d) = (−d_y, d_x)`` of the projected direction d (x right,
y down: an edgelet running to the right has its light side below). New edgelets' frames are built to obey
it (``edgelet_triangulation_kernels``), and ``ptam.edgelet.edgelet_projection`` reports image normals by it.

The 4-DOF update used by bundle adjustment (§4.4, eq. 9) is right-multiplied, E_WE ← E_WE · exp(μ), with
μ = (t_x, t_y, ω_x, ω_y) embedded in the six-vector (t_x, t_y, 0, ω_x, ω_y, 0): translation along and
rotation about the edgelet's own z-axis change nothing measurable and are left out. After the update the
frame is re-orthonormalised exactly (Gram–Schmidt on z then x).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import se3
from .edgelet_ba_kernels import frames_updated

# Indices of the four edgelet degrees of freedom in the six-vector μ = (t_x, t_y, t_z, ω_x, ω_y, ω_z) (eq. 9).
EDGELET_DOF = (0, 1, 3, 4)
_PERP = np.array([-1.0, 1.0])


def perp(v: np.ndarray) -> np.ndarray:
    """The image vector (..., 2) turned by +90° in image coordinates: (x, y) → (−y, x)."""
    v = np.asarray(v, dtype=np.float64)
    return v[..., ::-1] * _PERP  # one ufunc call: perp runs a few thousand times a mapper job


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass(frozen=True)
class Edgelets:
    """N edgelets: ``centre`` (N, 3), unit ``direction`` (N, 3) = E-frame z, unit ``normal`` (N, 3) = E-frame x,
    perpendicular to the direction (Agility §4.1)."""

    centre: np.ndarray
    direction: np.ndarray
    normal: np.ndarray

    def __len__(self) -> int:
        return len(self.centre)

    @property
    def binormal(self) -> np.ndarray:
        """The E-frame y-axis, z × x (N, 3)."""
        return np.cross(self.direction, self.normal)

    def frames(self) -> np.ndarray:
        """E_WE as (N, 4, 4) rigid transforms (edgelet frame → world)."""
        R = np.stack([self.normal, self.binormal, self.direction], axis=-1)
        return se3.from_Rt(R, self.centre)

    @staticmethod
    def from_frames(E_WE: np.ndarray) -> Edgelets:
        E_WE = np.asarray(E_WE, dtype=np.float64)
        return Edgelets(E_WE[:, :3, 3].copy(), E_WE[:, :3, 2].copy(), E_WE[:, :3, 0].copy()).orthonormalised()

    def orthonormalised(self) -> Edgelets:
        """Exact Gram–Schmidt: the direction is normalised, the normal made perpendicular to it and normalised."""
        z = _unit(np.asarray(self.direction, dtype=np.float64))
        x = np.asarray(self.normal, dtype=np.float64)
        x = _unit(x - np.sum(x * z, axis=-1, keepdims=True) * z)
        return Edgelets(np.asarray(self.centre, dtype=np.float64), z, x)

    def updated(self, mu: np.ndarray) -> Edgelets:
        """E_WE ← E_WE · exp(μ) for μ (N, 4) = (t_x, t_y, ω_x, ω_y) in each edgelet's own frame (eq. 9)."""
        mu = np.ascontiguousarray(mu, dtype=np.float64).reshape(len(self), 4)
        out = np.empty((len(self), 4, 4))
        frames_updated(np.ascontiguousarray(self.frames()), mu, out)  # re-orthonormalised as ``orthonormalised``
        return Edgelets(out[:, :3, 3], out[:, :3, 2], out[:, :3, 0])

    def subset(self, index) -> Edgelets:
        return Edgelets(self.centre[index], self.direction[index], self.normal[index])

    def flipped(self, mask: np.ndarray) -> Edgelets:
        """Direction reversed where ``mask``; the normal kept, so the frame stays right-handed."""
        s = np.where(np.asarray(mask, dtype=bool), -1.0, 1.0)[:, None]
        return Edgelets(self.centre, self.direction * s, self.normal)
