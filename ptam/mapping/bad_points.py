"""The tracker's verdict on map points (PTAM code ``HandleBadPoints``, ``MapPoint::nMEstimatorInlierCount`` /
``nMEstimatorOutlierCount``).

Each frame the tracker reports the points its final pose update kept as Tukey inliers and those it rejected;
the mapper drains the reports and marks a point bad once it was an outlier more than
``mapper.bad_point_min_outliers`` times and more often than an inlier. The reports wait in a bounded deque: in
``sync`` mode the mapper drains it only at keyframes, and PTAM uses the recent evidence anyway.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class TrackerFeedback:
    def __init__(self, mapper_cfg):
        self.cfg = mapper_cfg
        self.reports: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=mapper_cfg.tracker_feedback_frames)
        self._inliers = np.zeros(0, np.int64)
        self._outliers = np.zeros(0, np.int64)

    def report(self, inlier_ids: np.ndarray, outlier_ids: np.ndarray) -> None:
        """Called from the tracker's thread with one frame's Tukey inliers and outliers (point ids)."""
        self.reports.append((inlier_ids, outlier_ids))

    def bad_points(self, n_points: int, bad: np.ndarray) -> np.ndarray:
        """Drain the reports; the indices of points (of ``n_points``, ``bad`` already) that are now bad."""
        if not self.reports:
            return np.zeros(0, np.int64)
        if len(self._inliers) < n_points:
            grow = np.zeros(n_points - len(self._inliers), np.int64)
            self._inliers, self._outliers = (
                np.concatenate([self._inliers, grow]),
                np.concatenate([self._outliers, grow]),
            )
        while self.reports:
            inl, out = self.reports.popleft()
            np.add.at(self._inliers, inl[inl < n_points], 1)
            np.add.at(self._outliers, out[out < n_points], 1)
        inliers, outliers = self._inliers[:n_points], self._outliers[:n_points]
        return np.flatnonzero((outliers > self.cfg.bad_point_min_outliers) & (outliers > inliers) & ~bad[:n_points])
