"""Absolute trajectory error (Sturm et al., IROS 2012): RMSE of position differences after aligning the
estimate to ground truth by a similarity (monocular SLAM has no scale, PTAM §7.3) or a rigid motion."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..geometry.sim3 import umeyama

MIN_POSES = 3  # Umeyama's alignment is determined by three non-collinear positions


@dataclass(frozen=True)
class AteResult:
    rmse: float  # metres (ground-truth units)
    scale: float  # s in gt ≈ s·R·est + t (1 for SE(3) alignment)
    R: np.ndarray  # (3, 3)
    t: np.ndarray  # (3,)
    matched: int  # poses compared
    errors: np.ndarray  # (matched,) per-pose position error after alignment

    def aligned(self, est_xyz: np.ndarray) -> np.ndarray:
        """Estimated positions mapped into the ground-truth frame."""
        return self.scale * np.asarray(est_xyz, dtype=np.float64) @ self.R.T + self.t


def ate(gt_xyz: np.ndarray, est_xyz: np.ndarray, with_scale: bool = True) -> AteResult:
    """ATE of associated positions (N, 3); Sim(3) alignment, or SE(3) with ``with_scale=False``.

    Sim(3) needs motion on both sides: a ground truth or an estimate that never moves raises :class:`InputError`.
    """
    gt_xyz = np.asarray(gt_xyz, dtype=np.float64)
    est_xyz = np.asarray(est_xyz, dtype=np.float64)
    n = len(gt_xyz)
    if n < MIN_POSES:
        raise InputError(f"ATE needs at least {MIN_POSES} matched poses, got {n}")
    if with_scale and not np.any(gt_xyz != gt_xyz[0]):
        # Umeyama's scale would be 0 and every aligned position the one ground-truth point: "ATE 0".
        raise InputError("ground truth never moves: ATE after Sim(3) is undefined")
    if with_scale and not np.any(est_xyz != est_xyz[0]):
        raise InputError("ATE: every estimated position is the same point, so no scale can be fitted")
    s, R, t = umeyama(est_xyz, gt_xyz, with_scale=with_scale)
    errors = np.linalg.norm(gt_xyz - (s * est_xyz @ R.T + t), axis=1)
    return AteResult(float(np.sqrt(np.mean(errors**2))), float(s), R, t, n, errors)
