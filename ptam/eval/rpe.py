"""Relative pose error (Sturm et al., IROS 2012; TUM's evaluate_rpe.py): for pose pairs (i, j) a fixed
delta apart, E = (Q_i⁻¹Q_j)⁻¹(P_i⁻¹P_j) with Q ground truth and P the estimate; the drift per delta is
the translation and rotation angle of E."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import PtamError
from ..geometry import se3, so3


@dataclass(frozen=True)
class RpeResult:
    trans_rmse: float  # metres per delta
    rot_rmse_deg: float  # degrees per delta
    pairs: int
    trans_errors: np.ndarray  # (pairs,)
    rot_errors_deg: np.ndarray  # (pairs,)


def pairs_by_frames(n: int, delta: int) -> tuple[np.ndarray, np.ndarray]:
    if delta < 1:
        raise PtamError(f"RPE delta must be at least one frame, got {delta}")
    i = np.arange(max(n - delta, 0))
    return i, i + delta


def pairs_by_time(timestamps: np.ndarray, delta_s: float) -> tuple[np.ndarray, np.ndarray]:
    """For each pose i, the later pose j whose time is closest to t_i + delta_s (poses sorted by time)."""
    if not delta_s > 0:
        raise PtamError(f"RPE delta must be positive, got {delta_s} s")
    t = np.asarray(timestamps, dtype=np.float64)
    target = t + delta_s
    j = np.clip(np.searchsorted(t, target), 1, len(t) - 1)
    earlier = np.abs(t[j - 1] - target) <= np.abs(t[j] - target)
    j = np.where(earlier, j - 1, j)
    i = np.arange(len(t))
    # A pose within delta_s of the end has no partner a full delta later.
    ok = (j > i) & (target <= t[-1])
    return i[ok], j[ok]


def rpe(T_wc_gt: np.ndarray, T_wc_est: np.ndarray, i: np.ndarray, j: np.ndarray, scale: float = 1.0) -> RpeResult:
    """RPE over the pairs (i, j) of associated poses (N, 4, 4). ``scale`` multiplies the estimate's
    translations first (the Sim(3) scale from ATE, for monocular estimates)."""
    if len(i) == 0:
        raise PtamError("RPE: no pose pairs a full delta apart")
    P = np.array(T_wc_est, dtype=np.float64)
    P[:, :3, 3] *= scale
    Q = np.asarray(T_wc_gt, dtype=np.float64)
    E = se3.inv(se3.inv(Q[i]) @ Q[j]) @ (se3.inv(P[i]) @ P[j])
    trans = np.linalg.norm(E[:, :3, 3], axis=1)
    rot = np.degrees(np.linalg.norm(so3.log(E[:, :3, :3]), axis=1))
    return RpeResult(float(np.sqrt(np.mean(trans**2))), float(np.sqrt(np.mean(rot**2))), len(i), trans, rot)
