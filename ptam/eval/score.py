"""Scoring a run's trajectory against a ground-truth TUM file: ATE after Sim(3), tracked fraction, path length."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .associate import associate
from .ate import MIN_POSES, ate
from .tum_io import read_tum


@dataclass(frozen=True)
class Score:
    ate_rmse_m: float
    matched: int
    n_groundtruth: int
    path_length_m: float

    @property
    def tracked_fraction(self) -> float:
        return self.matched / max(self.n_groundtruth, 1)


def score_trajectory(groundtruth, trajectory, max_dt: float = 0.01) -> Score:
    """``trajectory``: a list of (timestamp, T_wc) pairs, as ``System.trajectory``. ATE is NaN with fewer than
    MIN_POSES matched poses."""
    t_gt, T_gt = read_tum(groundtruth)
    length = float(np.linalg.norm(np.diff(T_gt[:, :3, 3], axis=0), axis=1).sum()) if len(T_gt) > 1 else 0.0
    if len(trajectory) == 0:
        return Score(float("nan"), 0, len(t_gt), length)
    t = np.array([p[0] for p in trajectory])
    T = np.array([p[1] for p in trajectory])
    ig, ie = associate(t_gt, t, max_dt)
    rmse = ate(T_gt[ig, :3, 3], T[ie, :3, 3]).rmse if len(ig) >= MIN_POSES else float("nan")
    return Score(rmse, len(ig), len(t_gt), length)
