"""What a scene asks the renderer to draw in one frame, in plane coordinates (the dominant plane is z = 0).

Spheres and decals use the record layouts of ``ptam.ar.raster_kernels`` with positions and rotations in the plane
frame; the renderer moves them to the camera frame. The grid, the cross-hair and the text are drawn by the
renderer itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .raster_kernels import (
    D_ALPHA,
    D_COLOUR,
    D_RIN,
    D_ROUT,
    D_SOFT,
    DECAL_LEN,
    S_COLOURS,
    S_P0,
    S_P1,
    S_PATTERN,
    S_RADIUS,
    S_ROT,
    S_SPEC,
    SPHERE_LEN,
)


@dataclass
class DrawList:
    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, SPHERE_LEN)))
    decals: np.ndarray = field(default_factory=lambda: np.zeros((0, DECAL_LEN)))
    grid_alpha: float = 0.0
    crosshair: bool = False
    crosshair_locked: bool = False
    dwell: float = 0.0  # fraction of the dwell time spent on the aimed target, 0..1
    text: list[str] = field(default_factory=list)


def sphere_records(
    centres, radii, rotations, colours, pattern: int, p0: float = 0.0, p1: float = 0.0, specular: float = 1.0
) -> np.ndarray:
    """(N, SPHERE_LEN) records: centres (N, 3), radii (N,), object→plane rotations (N, 3, 3), colours (N, 3, 3)
    (A, B, C, BGR)."""
    centres = np.asarray(centres, np.float64).reshape(-1, 3)
    n = len(centres)
    rec = np.zeros((n, SPHERE_LEN))
    rec[:, 0:3] = centres
    rec[:, S_RADIUS] = radii
    rec[:, S_ROT : S_ROT + 9] = np.asarray(rotations, np.float64).reshape(n, 9)
    rec[:, S_COLOURS : S_COLOURS + 9] = np.asarray(colours, np.float64).reshape(n, 9)
    rec[:, S_PATTERN] = pattern
    rec[:, S_P0] = p0
    rec[:, S_P1] = p1
    rec[:, S_SPEC] = specular
    return rec


def decal_records(centres_uv, r_in, r_out, softness, colours, alpha) -> np.ndarray:
    """(M, DECAL_LEN) records of discs (r_in = 0) or rings on the plane; scalars broadcast."""
    centres_uv = np.asarray(centres_uv, np.float64).reshape(-1, 2)
    m = len(centres_uv)
    rec = np.zeros((m, DECAL_LEN))
    rec[:, 0:2] = centres_uv
    rec[:, D_RIN] = r_in
    rec[:, D_ROUT] = r_out
    rec[:, D_SOFT] = softness
    rec[:, D_COLOUR : D_COLOUR + 3] = np.broadcast_to(np.asarray(colours, np.float64), (m, 3))
    rec[:, D_ALPHA] = alpha
    return rec
