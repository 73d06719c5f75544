"""Geometry drawn by the viewer, as plain arrays: the dominant-plane grid, thumbnail intrinsics and edgelet
segments."""

from __future__ import annotations

import numpy as np

from ..edgelet import Edgelets, perp, project_edgelets
from ..image.pyramid import zero_to_level

# rerun puts pixel corners at integer coordinates (a W-pixel-wide image spans [0, W]); ptam puts pixel centres there.
RERUN_PIXEL_OFFSET = 0.5


def grid_lines(spacing: float, half_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Lines of the map's z = 0 plane (PTAM §6.1: the dominant plane after initialisation), drawn as PTAM's map
    viewer does (code ``MapViewer::DrawGrid``): 2·half_cells + 1 lines each way, ``spacing`` apart.

    Returns (L, 2, 3) segment end points and an (L,) bool that marks the two lines through the origin."""
    k = np.arange(-half_cells, half_cells + 1, dtype=np.float64) * spacing
    e = half_cells * spacing
    zeros = np.zeros_like(k)
    along_y = np.stack([np.stack([k, -e + zeros, zeros], 1), np.stack([k, e + zeros, zeros], 1)], axis=1)
    along_x = np.stack([np.stack([-e + zeros, k, zeros], 1), np.stack([e + zeros, k, zeros], 1)], axis=1)
    axis = np.arange(-half_cells, half_cells + 1) == 0
    return np.concatenate([along_y, along_x]), np.concatenate([axis, axis])


def level_intrinsics(camera, level: int) -> tuple[tuple[float, float], tuple[float, float], tuple[int, int]]:
    """Focal lengths, principal point (in rerun's pixel convention) and size of pyramid level ``level``: the linear
    part of the camera, enough to draw a frustum."""
    s = 2.0**level
    c = zero_to_level(np.array([[camera.cx, camera.cy]]), level)[0] + RERUN_PIXEL_OFFSET
    return (camera.fx / s, camera.fy / s), (float(c[0]), float(c[1])), (camera.width >> level, camera.height >> level)


def edgelet_segments(snap, camera, ids: np.ndarray, length_px: float) -> np.ndarray:
    """(N, 2, 3) end points of edgelets ``ids`` of a map snapshot: each as long as it was made, ``length_px`` in its
    source keyframe (Agility §4.2: an edge of 18 pixels), i.e. ±length_px/2 over its image length per metre there
    (eq. 5, ``project_edgelets``), about its centre along its direction."""
    ed = Edgelets(snap.edgelet_centre[ids], snap.edgelet_direction[ids], snap.edgelet_normal[ids])
    centre, direction, source = ed.centre, ed.direction, snap.edgelet_source_kf[ids]
    per_metre = np.zeros(len(ids))
    for k in np.unique(source).tolist():  # one projection per source keyframe
        sel = source == k
        per_metre[sel] = np.linalg.norm(project_edgelets(camera, snap.kf_T_cw[k], ed.subset(sel)).direction, axis=1)
    half = 0.5 * length_px / np.maximum(per_metre, 1e-12)
    return np.stack([centre - half[:, None] * direction, centre + half[:, None] * direction], axis=1)


def image_segments(xy: np.ndarray, normal: np.ndarray, length_px: float) -> np.ndarray:
    """(N, 2, 2) image segments ``length_px`` long through points ``xy`` across their unit edge normals, in rerun's
    pixel convention: an edgelet where the tracker found (or predicted) it."""
    along = 0.5 * length_px * perp(np.asarray(normal, np.float64).reshape(-1, 2))
    c = np.asarray(xy, np.float64).reshape(-1, 2) + RERUN_PIXEL_OFFSET
    return np.stack([c - along, c + along], axis=1)
