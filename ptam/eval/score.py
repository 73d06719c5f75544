"""Scoring a run's trajectory against a ground-truth TUM file: ATE after Sim(3), rotation RMSE under the same
alignment, tracked fraction, path length and, given ``Criteria``, the correct fraction and glitch frames
(``correctness.py``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .associate import associate
from .ate import MIN_POSES, ate
from .correctness import Criteria, correctness, rot_rmse_deg
from .tum_io import read_tum


@dataclass(frozen=True)
class Score:
    ate_rmse_m: float
    matched: int
    n_groundtruth: int
    path_length_m: float
    rot_rmse_deg: float = float("nan")  # under the ATE's alignment; NaN where the ATE is
    correct: int | None = None  # ground-truth frames tracked within the criteria; None without criteria
    glitches: int | None = None  # tracked frames outside the criteria; None without criteria

    @property
    def tracked_fraction(self) -> float:
        return self.matched / max(self.n_groundtruth, 1)

    @property
    def correct_fraction(self) -> float:
        """Correct frames over all ground-truth frames; NaN without criteria."""
        return float("nan") if self.correct is None else self.correct / max(self.n_groundtruth, 1)


def score_trajectory(groundtruth, trajectory, max_dt: float = 0.01, criteria: Criteria | None = None) -> Score:
    """``score_poses`` against a ground-truth TUM file."""
    return score_poses(*read_tum(groundtruth), trajectory, max_dt, criteria)


def score_poses(t_gt, T_gt, trajectory, max_dt: float = 0.01, criteria: Criteria | None = None) -> Score:
    """``trajectory``: a list of (timestamp, T_wc) pairs, as ``System.trajectory``, against ground-truth
    camera-to-world poses ``T_gt`` (N, 4, 4) at ``t_gt`` (N,) s. ATE and rotation RMSE are NaN with fewer than
    MIN_POSES matched poses, or when they all sit at one position (only poses from before the map, rotation-only at
    its origin: no scale can be fitted); correct and glitch frames are counted only with ``criteria``."""
    length = float(np.linalg.norm(np.diff(T_gt[:, :3, 3], axis=0), axis=1).sum()) if len(T_gt) > 1 else 0.0
    zero = None if criteria is None else 0
    if len(trajectory) == 0:
        return Score(float("nan"), 0, len(t_gt), length, float("nan"), zero, zero)
    t = np.array([p[0] for p in trajectory])
    T = np.array([p[1] for p in trajectory])
    ig, ie = associate(t_gt, t, max_dt)
    rmse = rot = float("nan")
    if len(ig) >= MIN_POSES and np.any(T[ie, :3, 3] != T[ie[0], :3, 3]):
        res = ate(T_gt[ig, :3, 3], T[ie, :3, 3])
        rmse, rot = res.rmse, rot_rmse_deg(T_gt[ig], T[ie], res.R)
    if criteria is None:
        return Score(rmse, len(ig), len(t_gt), length, rot)
    c = correctness(T_gt[ig], T[ie], len(t_gt), criteria)
    return Score(rmse, len(ig), len(t_gt), length, rot, c.correct, c.glitches)
