"""The AR playing surface: the map's dominant plane (PTAM §6.1), refreshed as the map grows.

After stereo initialisation the map is aligned so that its dominant plane is z = 0 with +z towards the
camera (``ptam.mapping.dominant_plane``), so the AR frame starts as the world frame. PTAM fits the plane once; here it
is refitted by the same RANSAC (``fit_dominant_plane`` with the ``init.plane_*`` settings) whenever the map's
good points have grown by ``ar.plane_refresh_growth`` since the last fit — in the AR worker thread, never in
the tracker's. A refit keeps virtual content where it was: the new frame's origin is the old origin dropped
onto the new plane and its x axis the old x axis projected into it, so a refit only corrects the tilt and
height of the surface (and moves content onto another surface only if that surface has become dominant).
"""

from __future__ import annotations

import numpy as np

from ..geometry import se3
from ..map.snapshot import camera_centres
from ..mapping.dominant_plane import fit_dominant_plane


def reanchored_frame(T_pw: np.ndarray, normal: np.ndarray, point: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """T_pw (world→plane) of the plane (normal, point), +z facing ``towards``, anchored to the old frame."""
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    if np.dot(towards - point, n) < 0:
        n = -n
    T_wp = se3.inv(T_pw)
    origin = T_wp[:3, 3] - np.dot(T_wp[:3, 3] - point, n) * n
    x = T_wp[:3, 0] - np.dot(T_wp[:3, 0], n) * n
    if np.linalg.norm(x) < 1e-6:  # the new plane is perpendicular to the old x axis
        x = T_wp[:3, 1] - np.dot(T_wp[:3, 1], n) * n
    x /= np.linalg.norm(x)
    R_pw = np.stack([x, np.cross(n, x), n])
    return se3.from_Rt(R_pw, -R_pw @ origin)


class ArPlane:
    """``T_pw``: world→plane; the plane is z = 0 of the plane frame. ``refits`` counts refreshes. A new map (a
    different first keyframe, after a reset) starts again from the initial frame."""

    def __init__(self, init_cfg, growth: float, T_pw: np.ndarray | None = None):
        self.init_cfg = init_cfg
        self.growth = float(growth)
        self.T_pw = np.eye(4) if T_pw is None else np.asarray(T_pw, np.float64).copy()
        self._T_pw0 = self.T_pw.copy()
        self.fitted_points: int | None = None
        self.refits = 0
        self._map_key = None  # the map's first keyframe: a new one means a new map (PTAM's reset)

    def maybe_refresh(self, snapshot) -> bool:
        """Refit when the snapshot's good points reach ``growth`` × the count at the last fit."""
        if snapshot is None or snapshot.n_keyframes == 0:
            return False
        if snapshot.keyframes[0] is not self._map_key:
            self._map_key = snapshot.keyframes[0]
            self.T_pw, self.fitted_points = self._T_pw0.copy(), None
        n = snapshot.n_points
        if self.fitted_points is None:
            self.fitted_points = n  # the initial map, already aligned to z = 0 by initialisation
            return False
        if n < self.growth * max(self.fitted_points, 1):
            return False
        self.fitted_points = n
        c = self.init_cfg
        good = snapshot.good_point_indices
        X = snapshot.X[good[~snapshot.ray[good]]]  # panorama rays have no depth (Gauglitz et al. §3.2)
        plane = fit_dominant_plane(X, c.plane_inlier_distance, c.plane_ransac_iterations, c.plane_seed)
        if plane is None or plane.inliers.sum() < 3:
            return False
        towards = camera_centres(snapshot.kf_T_cw[-1:])[0]
        self.T_pw = reanchored_frame(self.T_pw, plane.normal, plane.point, towards)
        self.refits += 1
        return True
