"""The immutable view of the map that the tracker reads (DESIGN.md, Concurrency).

The mapper publishes a new ``MapSnapshot`` after every change and swaps one reference; the tracker reads
whichever snapshot is current, without locks. Every array is read-only. Keyframe, point and measurement arrays
are copies; the per-level keyframe image stacks are views of the map's append-only stacks.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .keyframe import KeyFrame


@dataclass(frozen=True, eq=False)
class MapSnapshot:
    """Keyframe i is ``keyframes[i]`` with pose ``kf_T_cw[i]`` and level-L image ``kf_images[L][i]``.

    Points (all, including bad ones, so indices stay stable): ``X`` world position, ``normal`` unit patch
    normal in the world frame, ``source_kf``/``source_level``/``source_xy`` the patch source (pixel at the
    source level), ``bad``, ``ray`` (a panorama feature, Gauglitz et al. §3.2: a ray from its source keyframe's
    centre). Measurements: keyframe ``meas_kf`` observed point ``meas_pt`` at level-0 pixel
    ``meas_xy`` on pyramid level ``meas_level``, made by ``meas_source`` (``map.SRC_*``).

    Edgelets (Agility §4, ``map.edgelet_store``; empty unless the mapper makes them): ``edgelet_centre``,
    ``edgelet_direction``, ``edgelet_normal`` (M, 3), ``edgelet_source_kf``, ``edgelet_bad``; their keyframe
    measurements ``edgelet_meas_kf``/``edgelet_meas_edgelet`` with image lines ``edgelet_meas_a``/``_b``
    (level-0 px); ``edgelet_tables`` keyframe -> (ids, visible, r_search, t_min, max_blur) of §5.2's
    visibility table.
    """

    version: int
    keyframes: tuple[KeyFrame, ...]
    kf_T_cw: np.ndarray
    kf_images: tuple[np.ndarray, ...]
    X: np.ndarray
    normal: np.ndarray
    source_kf: np.ndarray
    source_level: np.ndarray
    source_xy: np.ndarray
    bad: np.ndarray
    ray: np.ndarray
    meas_kf: np.ndarray
    meas_pt: np.ndarray
    meas_xy: np.ndarray
    meas_level: np.ndarray
    meas_source: np.ndarray
    good_point_indices: np.ndarray
    edgelet_centre: np.ndarray = field(default_factory=lambda: _empty((0, 3), np.float64))
    edgelet_direction: np.ndarray = field(default_factory=lambda: _empty((0, 3), np.float64))
    edgelet_normal: np.ndarray = field(default_factory=lambda: _empty((0, 3), np.float64))
    edgelet_source_kf: np.ndarray = field(default_factory=lambda: _empty((0,), np.int32))
    edgelet_bad: np.ndarray = field(default_factory=lambda: _empty((0,), np.bool_))
    edgelet_meas_kf: np.ndarray = field(default_factory=lambda: _empty((0,), np.int32))
    edgelet_meas_edgelet: np.ndarray = field(default_factory=lambda: _empty((0,), np.int32))
    edgelet_meas_a: np.ndarray = field(default_factory=lambda: _empty((0, 2), np.float64))
    edgelet_meas_b: np.ndarray = field(default_factory=lambda: _empty((0, 2), np.float64))
    edgelet_tables: dict = field(default_factory=dict)

    @property
    def n_keyframes(self) -> int:
        return len(self.keyframes)

    @property
    def n_points(self) -> int:
        """Number of good (not bad) points."""
        return len(self.good_point_indices)

    @property
    def camera_centres(self) -> np.ndarray:
        """(N, 3) keyframe camera centres in the world frame."""
        return camera_centres(self.kf_T_cw)

    @property
    def good_edgelet_indices(self) -> np.ndarray:
        return np.flatnonzero(~self.edgelet_bad)

    def features(self, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Homogeneous features (X, w) of points ``ids``: map points at w = 1; panorama rays (Gauglitz et al.
        §3.2) as directions from their source keyframe's centre at w = 0."""
        X = self.X[ids]
        ray = self.ray[ids]
        if ray.any():
            X = X.copy()
            X[ray] -= self.camera_centres[self.source_kf[ids[ray]]]
        return X, (~ray).astype(np.float64)

    def nearest_keyframe(self, T_cw: np.ndarray, among: np.ndarray | None = None) -> tuple[int, float]:
        """Index and camera-centre distance of the keyframe nearest to pose ``T_cw``, of all or of the keyframe
        indices ``among`` (-1, inf without any)."""
        kfs = np.arange(self.n_keyframes) if among is None else np.asarray(among, dtype=np.int64)
        if not len(kfs):
            return -1, float("inf")
        d = np.linalg.norm(self.camera_centres[kfs] - camera_centres(T_cw[None])[0], axis=1)
        i = int(np.argmin(d))
        return int(kfs[i]), float(d[i])

    def view_travel(self, T_cw: np.ndarray) -> float:
        """Smallest rotation angle (radians) between the camera and any keyframe: the image travel of the view,
        per unit focal length, since the nearest keyframe view (Gauglitz et al. §4.3); inf without keyframes."""
        if not self.n_keyframes:
            return float("inf")
        cos = (np.einsum("nij,ij->n", self.kf_T_cw[:, :3, :3], T_cw[:3, :3]) - 1.0) / 2.0
        return float(np.arccos(np.clip(cos.max(), -1.0, 1.0)))


def _empty(shape: tuple, dtype) -> np.ndarray:
    a = np.zeros(shape, dtype)
    a.setflags(write=False)
    return a


def camera_centres(T_cw: np.ndarray) -> np.ndarray:
    """Camera centres −Rᵀt of world-to-camera poses (N, 4, 4) -> (N, 3)."""
    return -np.einsum("nji,nj->ni", T_cw[:, :3, :3], T_cw[:, :3, 3])
