"""The arguments of ``Bundle.adjust`` checked and converted to contiguous arrays of the kernels' dtypes, points
(PTAM §6.3) and edgelets (Agility §4.4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..config.edgelet_section import EdgeletConfig
from ..edgelet import EdgeletObservations, Edgelets
from ..errors import InputError


def _as_array(name: str, a, shape: tuple, dtype) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"bundle adjustment: {name} must have shape {want}, got {a.shape}")
    if dtype is bool and a.dtype != np.bool_:
        raise InputError(f"bundle adjustment: {name} must be a boolean mask, got {a.dtype}")
    out = np.ascontiguousarray(a, dtype=dtype)
    if out.dtype.kind == "f" and not np.isfinite(out).all():
        raise InputError(f"bundle adjustment: {name} contains NaN or infinite values")
    return out


@dataclass(frozen=True)
class _Inputs:
    """The arguments of ``Bundle.adjust``, checked and converted to contiguous arrays of the kernels' dtypes."""

    poses: np.ndarray
    points: np.ndarray
    meas_kf: np.ndarray
    meas_pt: np.ndarray
    meas_xy: np.ndarray
    meas_level: np.ndarray
    fixed_poses: np.ndarray
    adjust_points: np.ndarray


def _checked_inputs(
    poses: ArrayLike,
    points: ArrayLike,
    meas_kf: ArrayLike,
    meas_pt: ArrayLike,
    meas_xy: ArrayLike,
    meas_level: ArrayLike,
    fixed_poses: ArrayLike,
    adjust_points: ArrayLike | None,
) -> _Inputs:
    poses = _as_array("poses", poses, (None, 4, 4), np.float64)
    points = _as_array("points", points, (None, 3), np.float64)
    n, m = len(poses), len(points)
    meas_kf = _as_array("meas_kf", meas_kf, (None,), np.int64)
    k = len(meas_kf)
    meas_pt = _as_array("meas_pt", meas_pt, (k,), np.int64)
    meas_xy = _as_array("meas_xy", meas_xy, (k, 2), np.float64)
    meas_level = _as_array("meas_level", meas_level, (k,), np.int64)
    fixed_poses = _as_array("fixed_poses", fixed_poses, (n,), bool)
    adjust_points = np.ones(m, bool) if adjust_points is None else _as_array("adjust_points", adjust_points, (m,), bool)
    if k and (meas_kf.min() < 0 or meas_kf.max() >= n):
        raise InputError(f"bundle adjustment: keyframe index out of range [0, {n})")
    if k and (meas_pt.min() < 0 or meas_pt.max() >= m):
        raise InputError(f"bundle adjustment: point index out of range [0, {m})")
    if k and meas_level.min() < 0:
        raise InputError("bundle adjustment: negative pyramid level")
    return _Inputs(poses, points, meas_kf, meas_pt, meas_xy, meas_level, fixed_poses, adjust_points)


@dataclass(frozen=True)
class EdgeletBundleInput:
    """Edgelets for ``Bundle.adjust`` (Agility §4.4): the map's ``edgelets``, their keyframe measurements ``obs``
    (lines a + λb in level-0 px), the edgelet config (eq. 6's sample offset) and which edgelets to adjust
    (default all; measurements of the others are not used, as for points)."""

    edgelets: Edgelets
    obs: EdgeletObservations
    cfg: EdgeletConfig
    adjust: np.ndarray | None = None

    @property
    def adjust_mask(self) -> np.ndarray:
        return np.ones(len(self.edgelets), bool) if self.adjust is None else self.adjust

    def checked(self, n_keyframes: int) -> EdgeletBundleInput:
        """The same input with contiguous arrays of the kernels' dtypes; InputError on a wrong shape, a non-finite
        value or an index out of range."""
        e = self.edgelets
        n = len(e.centre)
        ed = Edgelets(
            *(_as_array(f"edgelet {k}", getattr(e, k), (n, 3), np.float64) for k in ("centre", "direction", "normal"))
        )
        kf = _as_array("edgelet meas_kf", self.obs.kf, (None,), np.int64)
        k = len(kf)
        idx = _as_array("edgelet meas_edgelet", self.obs.edgelet, (k,), np.int64)
        a = _as_array("edgelet meas_a", self.obs.a, (k, 2), np.float64)
        b = _as_array("edgelet meas_b", self.obs.b, (k, 2), np.float64)
        adjust = np.ones(n, bool) if self.adjust is None else _as_array("adjust_edgelets", self.adjust, (n,), bool)
        if k and (kf.min() < 0 or kf.max() >= n_keyframes):
            raise InputError(f"bundle adjustment: edgelet measurement keyframe index out of range [0, {n_keyframes})")
        if k and (idx.min() < 0 or idx.max() >= n):
            raise InputError(f"bundle adjustment: edgelet index out of range [0, {n})")
        return EdgeletBundleInput(ed, EdgeletObservations(kf, idx, a, b), self.cfg, adjust)
