"""How many sub-frames a motion-blurred frame needs: enough that the scene moves at most ``max_step_px`` in the
image from one to the next.

A frame's motion blur is the mean of renders at sub-frame poses spread evenly over the exposure (``Scene``); the
scene's ``subframes`` is the most it uses. A frame whose image hardly moves during the exposure is rendered with
fewer: desk_blur's slow frames smear about 3 px, and drawn with five sub-frames three quarters of a pixel apart
instead of twelve a quarter apart they change by 0.17 grey levels on average (its sensor noise is 2), at under
half the work (``tests/test_synthetic_motion_blur.py``). The smear is measured on a grid of probe pixels: the scene
points they see from the frame's pose (``Scene.raycast``), projected at every one of the ``subframes`` poses, give
each point's image path; the longest path decides. The count is odd, so that one sub-frame is the frame's own
(ground-truth) pose, as it is with an odd ``subframes``.
"""

from __future__ import annotations

import math

import numpy as np

from ..camera import CameraModel

PROBE_GRID = (17, 13)  # probe pixels across the image (columns, rows), corners included


def probe_pixels(camera: CameraModel) -> np.ndarray:
    """(N, 2) pixels of the probe grid."""
    u = np.linspace(0.0, camera.width - 1.0, PROBE_GRID[0])
    v = np.linspace(0.0, camera.height - 1.0, PROBE_GRID[1])
    uu, vv = np.meshgrid(u, v)
    return np.stack([uu.ravel(), vv.ravel()], axis=-1)


def smear_px(camera: CameraModel, X: np.ndarray, sub_T_wc: np.ndarray) -> float:
    """The longest image path (px) of world points ``X`` (N, 3) over the sub-frame poses ``sub_T_wc`` (P, 4, 4);
    inf where a point leaves the front of the camera, 0 without points."""
    if not len(X):
        return 0.0
    R = sub_T_wc[:, :3, :3]
    Xc = np.einsum("pji,pnj->pni", R, X[None] - sub_T_wc[:, None, :3, 3])  # R_wcᵀ (X − c) per sub-frame
    if np.any(Xc[..., 2] <= 0.0):
        return math.inf
    uv = camera.project(Xc)
    return float(np.max(np.sum(np.linalg.norm(np.diff(uv, axis=0), axis=-1), axis=0)))


def subframe_count(smear: float, max_step_px: float, subframes: int) -> int:
    """The fewest sub-frames, odd, that are at most ``max_step_px`` apart along a ``smear`` px path; at most
    ``subframes``, and ``subframes`` when ``max_step_px`` is 0."""
    if max_step_px == 0.0 or not math.isfinite(smear):
        return subframes
    return min(2 * math.ceil(smear / (2.0 * max_step_px)) + 1, subframes)
