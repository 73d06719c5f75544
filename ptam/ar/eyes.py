"""PTAM's eyeballs (PTAM code ``EyeGame``): four eyes on the plane that turn to follow the camera.

Eyes of radius r sit at (±r, ±r, r) in the plane frame, touching each other and the plane. Each eye's +z
axis is its gaze (black pupil, blue iris, white). Every frame each eye turns towards the camera centre by the
smallest rotation (no roll about the gaze), limited to ``ar.eye_turn_rate`` radians, so the eyes visibly
swing round when the camera moves quickly. A soft shadow disc lies under each eye (``MakeShadowTex``).
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import so3
from . import materials
from .drawlist import decal_records, sphere_records
from .raster_kernels import EYE


class Eyes:
    def __init__(self, ar_cfg):
        self.cfg = ar_cfg
        r = ar_cfg.eye_radius
        self.radius = r
        self.positions = np.array([[-r, -r, r], [r, -r, r], [-r, r, r], [r, r, r]])
        self.R = np.tile(np.eye(3), (4, 1, 1))  # eye→plane; initially all gazing along the plane normal

    @property
    def gaze(self) -> np.ndarray:
        """(4, 3) unit gaze directions in the plane frame."""
        return self.R[:, :, 2].copy()

    def look_at(self, target: np.ndarray) -> None:
        """PTAM code ``EyeGame::LookAt``: rotate each gaze towards ``target`` (plane frame) by at most the limit."""
        d = np.einsum("kji,kj->ki", self.R, np.asarray(target, np.float64) - self.positions)  # in eye frames
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        axis = np.stack([-d[:, 1], d[:, 0], np.zeros(len(d))], axis=1)  # z × d
        s = np.linalg.norm(axis, axis=1)
        angle = np.arctan2(s, d[:, 2])
        step = np.minimum(angle, self.cfg.eye_turn_rate)
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(s[:, None] > 1e-12, axis / s[:, None], 0.0) * step[:, None]
        self.R = self.R @ so3.exp(w)

    def spheres(self) -> np.ndarray:
        colours = np.array([materials.EYE_WHITE, materials.EYE_IRIS, materials.EYE_PUPIL])
        return sphere_records(
            self.positions,
            self.radius,
            self.R,
            np.broadcast_to(colours, (4, 3, 3)),
            EYE,
            math.cos(math.radians(self.cfg.eye_pupil_deg)),
            math.cos(math.radians(self.cfg.eye_iris_deg)),
        )

    def shadows(self) -> np.ndarray:
        c = self.cfg
        r = self.radius
        return decal_records(
            self.positions[:, :2],
            0.0,
            c.shadow_radius_rel * r,
            c.shadow_softness_rel * r,
            materials.SHADOW,
            c.shadow_alpha,
        )
