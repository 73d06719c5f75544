"""Per-frame correctness of an estimated trajectory: rotation error, correct fraction and glitch frames.

ATE (``ate.py``) is an RMSE over the frames a system reports; it hides how many frames were right and punishes
a few wild frames as much as a steady drift. These metrics count frames instead:

- **rotation error**: the angle of ``R_gtᵀ·R·R_est`` per frame, where R is the rotation of a Sim(3)
  alignment (orientations are compared in the ground-truth frame). ``rot_rmse_deg`` reports its RMSE under
  the ATE's own alignment, so ATE and rotation RMSE describe the same aligned trajectory.
- **correct**: a ground-truth frame whose associated estimate, after Sim(3) alignment with the map scale
  fitted, lies within ``max_error_m`` of the true position and ``max_error_deg`` of the true orientation. The
  correct fraction divides by every ground-truth frame, so untracked (and, in realtime mode, dropped)
  frames count against it.
- **glitch**: a frame the system reported as tracked whose aligned error exceeds either threshold (a wrong
  pose presented as right, the failure an AR overlay shows). correct + glitches = matched frames.

Robust alignment (``fit_sim3``): a few gross outliers (a tracker that jumped for a handful of frames) drag a
least-squares Umeyama fit and would make good frames look wrong; a map that broke part-way (tracked on, but
wrong) drags it so far that no frame passes any threshold. So the alignment is a small maximum-consensus
search. Candidates are Umeyama fits of the positions: on all matched frames, and on each part of the
trajectory cut into 2, 3, …, ``segments`` contiguous parts (by frame order). Each candidate is re-fitted once on
its support (the frames it puts within ``gate_factor`` times both thresholds, position and orientation), and the
candidate that then puts the most frames within the thresholds themselves wins (ties: the earlier one, so the
fit on all comes first): a loose gate finds the inliers, the judged thresholds pick the fit.
Without outliers the fit on all wins and its re-fit changes nothing; with a few outliers the re-fit leaves them
out; with a broken map the largest set of frames one similarity makes right is what is judged correct (if a
map breaks into two self-consistent parts, the larger part counts as right and the other as glitches). Parts
with fewer than ``MIN_POSES`` frames give no candidate, nor a position fit where the positions are one point, and
the re-fit is skipped when the support is such a set (the winning candidate then stands).

Positions alone leave the alignment's rotation undetermined when they lie on a line or at one point, which is
what a camera that mostly rotates in place gives (a panorama, Gauglitz et al. TVCG 2013). So every part also
gives an orientation-anchored candidate: the rotation is the chordal mean of R_gt·R_estᵀ over its frames, and
scale and translation are then the least-squares fit of the positions. Both kinds compete on the same terms.

A trajectory whose positions are all one point (a run that only tracked rotation-only poses, before any map)
has no scale to fit, but it still claims that the camera stayed where it was: the orientation-anchored fit puts
that point at the true positions' mean, so each frame is judged by how far the camera really was from there and
by its orientation. Where the camera did stay put, the frames are correct; where it moved, or where the
rotation-only tracker turned the wrong way, they are glitches.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import EvalConfig
from ..geometry import so3
from ..geometry.sim3 import umeyama
from .ate import MIN_POSES

_MM_PER_M = 1e3


@dataclass(frozen=True)
class Criteria:
    """When a frame is correct; from the ``eval`` config section (``correct_mm``, ``correct_deg``,
    ``align_gate_factor``, ``align_segments``), converted to metres by the caller."""

    max_error_m: float
    max_error_deg: float
    gate_factor: float  # a candidate alignment's support: frames within gate_factor × both thresholds
    segments: int  # candidate fits also on the trajectory cut into 2..segments parts; 1: the fit on all only

    @classmethod
    def from_config(cls, eval_cfg: EvalConfig) -> Criteria:
        e = eval_cfg
        return cls(e.correct_mm / _MM_PER_M, e.correct_deg, e.align_gate_factor, e.align_segments)


@dataclass(frozen=True)
class Sim3Fit:
    """gt ≈ scale·R·est + t; ``used``: the frames (matched,) the final fit was made on."""

    scale: float
    R: np.ndarray
    t: np.ndarray
    used: np.ndarray

    def apply(self, est_xyz: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(est_xyz, dtype=np.float64) @ self.R.T + self.t


@dataclass(frozen=True)
class Correctness:
    n_groundtruth: int
    matched: int
    correct: int
    glitches: int
    fit: Sim3Fit | None  # None when fewer than MIN_POSES frames matched (then correct = glitches = 0)
    position_errors_m: np.ndarray  # (matched,) after the robust fit; NaN without a fit
    rotation_errors_deg: np.ndarray  # (matched,) after the robust fit; NaN without a fit

    @property
    def correct_fraction(self) -> float:
        return self.correct / max(self.n_groundtruth, 1)


def _one_point(est_xyz: np.ndarray) -> bool:
    return not np.any(est_xyz != est_xyz[0])


def _parts(n: int, segments: int) -> list[tuple[int, int]]:
    """[a, b) frame ranges of the trajectory cut into 2, 3, …, ``segments`` contiguous parts."""
    out = []
    for k in range(2, segments + 1):
        bounds = np.linspace(0, n, k + 1).astype(int)
        out += list(zip(bounds[:-1], bounds[1:], strict=True))
    return out


def fit_sim3(T_gt: np.ndarray, T_est: np.ndarray, criteria: Criteria) -> Sim3Fit:
    """Sim(3) alignment of associated camera-to-world poses (N, 4, 4) in frame order, N ≥ MIN_POSES: the candidate
    fit supported by the most frames, re-fitted once on those (module docstring)."""
    T_gt = np.asarray(T_gt, dtype=np.float64)
    T_est = np.asarray(T_est, dtype=np.float64)
    gt_xyz, est_xyz = T_gt[:, :3, 3], T_est[:, :3, 3]
    n = len(gt_xyz)
    gate_m, gate_deg = criteria.gate_factor * criteria.max_error_m, criteria.gate_factor * criteria.max_error_deg

    def within(fit, m: float, deg: float) -> np.ndarray:
        s, R, t = fit
        near = np.linalg.norm(gt_xyz - (s * est_xyz @ R.T + t), axis=1) <= m
        return near & (rotation_errors_deg(T_gt[:, :3, :3], T_est[:, :3, :3], R) <= deg)

    best: Sim3Fit | None = None
    best_correct = -1
    candidates = [np.ones(n, dtype=bool)]
    for a, b in _parts(n, criteria.segments):
        part = np.zeros(n, dtype=bool)
        part[a:b] = True
        candidates.append(part)

    def positions(sel):
        return umeyama(est_xyz[sel], gt_xyz[sel], with_scale=True)

    def orientations(sel):
        return orientation_fit(T_gt[sel], T_est[sel])

    for part in candidates:
        if part.sum() < MIN_POSES:
            continue
        for method in (orientations,) if _one_point(est_xyz[part]) else (positions, orientations):
            fit = method(part)
            support = within(fit, gate_m, gate_deg)
            used = part
            if support.sum() >= MIN_POSES and not (method is positions and _one_point(est_xyz[support])):
                fit, used = method(support), support  # re-fitted once on the frames it supports
            # Candidates are judged by what is judged in the end: frames within the thresholds after the re-fit.
            correct = int(within(fit, criteria.max_error_m, criteria.max_error_deg).sum())
            if correct > best_correct:
                best, best_correct = Sim3Fit(float(fit[0]), fit[1], fit[2], used), correct
    assert best is not None  # the fit on all frames is always a candidate here
    return best


def orientation_fit(T_gt: np.ndarray, T_est: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(s, R, t) with R the chordal L2 mean of R_gt·R_estᵀ (camera-to-world poses (N, 4, 4)), then s and t the
    least-squares fit of gt ≈ s·R·est + t; positions that do not spread give s = 1."""
    M = np.einsum("nij,nkj->ik", T_gt[:, :3, :3], T_est[:, :3, :3])
    U, _, Vt = np.linalg.svd(M)
    R = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
    gt, est = T_gt[:, :3, 3], T_est[:, :3, 3]
    xs = (est - est.mean(axis=0)) @ R.T
    xd = gt - gt.mean(axis=0)
    var = float((xs * xs).sum())
    s = float((xs * xd).sum() / var) if var > 0 and (xs * xd).sum() > 0 else 1.0
    return s, R, gt.mean(axis=0) - s * R @ est.mean(axis=0)


def rotation_errors_deg(R_gt: np.ndarray, R_est: np.ndarray, R_align: np.ndarray) -> np.ndarray:
    """Angle in degrees (N,) between true camera orientations R_gt (N, 3, 3) (camera-to-world) and estimated
    ones R_est mapped into the ground-truth frame by the alignment's rotation: |log(R_gtᵀ·R_align·R_est)|."""
    D = np.swapaxes(np.asarray(R_gt, dtype=np.float64), -1, -2) @ np.asarray(R_align) @ np.asarray(R_est)
    return np.degrees(np.linalg.norm(so3.log(D), axis=-1))


def rot_rmse_deg(T_gt: np.ndarray, T_est: np.ndarray, R_align: np.ndarray) -> float:
    """RMSE in degrees of the rotation errors of associated camera-to-world poses (M, 4, 4) under an alignment
    rotation (the ATE's: ``ate(...).R``); NaN for no poses."""
    T_gt = np.asarray(T_gt, dtype=np.float64).reshape(-1, 4, 4)
    if len(T_gt) == 0:
        return float("nan")
    err = rotation_errors_deg(
        T_gt[:, :3, :3], np.asarray(T_est, dtype=np.float64).reshape(-1, 4, 4)[:, :3, :3], R_align
    )
    return float(np.sqrt(np.mean(err * err)))


def correctness(T_gt: np.ndarray, T_est: np.ndarray, n_groundtruth: int, criteria: Criteria) -> Correctness:
    """Correct and glitch frames of associated camera-to-world poses T_gt, T_est (M, 4, 4) out of
    ``n_groundtruth`` ground-truth frames."""
    T_gt = np.asarray(T_gt, dtype=np.float64).reshape(-1, 4, 4)
    T_est = np.asarray(T_est, dtype=np.float64).reshape(-1, 4, 4)
    m = len(T_gt)
    if m < MIN_POSES:
        nan = np.full(m, np.nan)
        return Correctness(n_groundtruth, m, 0, 0, None, nan, nan)
    fit = fit_sim3(T_gt, T_est, criteria)
    pos = np.linalg.norm(T_gt[:, :3, 3] - fit.apply(T_est[:, :3, 3]), axis=1)
    rot = rotation_errors_deg(T_gt[:, :3, :3], T_est[:, :3, :3], fit.R)
    n_ok = int(np.count_nonzero((pos <= criteria.max_error_m) & (rot <= criteria.max_error_deg)))
    return Correctness(n_groundtruth, m, n_ok, m - n_ok, fit, pos, rot)
