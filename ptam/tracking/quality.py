"""Tracking quality from the fraction of successful observations, and the lost state (PTAM §5.6).

PTAM code (``AssessTrackingQuality``): good when found/attempted over all levels exceeds ``quality_good``;
otherwise bad when the fraction among the "large" features (levels ≥ ``quality_large_min_level``, if more than
``quality_large_min_attempted`` were attempted; else all) is below ``quality_lost``; otherwise poor. Poor
frames are tracked but may not become keyframes. Tracking is lost once ``lost_frames`` consecutive frames were
bad (PTAM code: recovery starts when the count of bad frames reaches 3), until a frame is not bad. During rapid
camera motion failure detection is suspended (Agility §8): a bad frame then leaves the count as it is.
"""

from __future__ import annotations

import numpy as np

from ..vocabulary import Quality

GOOD, POOR, BAD = Quality.GOOD, Quality.POOR, Quality.BAD


class TrackingQuality:
    def __init__(self, tracker_cfg):
        self.cfg = tracker_cfg
        self.bad_frames = 0

    def reset(self) -> None:
        self.bad_frames = 0

    @property
    def lost(self) -> bool:
        return self.bad_frames >= self.cfg.lost_frames

    def assess(
        self,
        attempted_per_level: np.ndarray,
        found_per_level: np.ndarray,
        suspend: bool = False,
        too_far: bool = False,
        too_few_inliers: bool = False,
    ) -> Quality:
        """``too_far``: the pose is far from every keyframe, which turns a poor frame bad (PTAM code: only a
        dodgy frame is checked with ``IsDistanceToNearestKeyFrameExcessive``; a good one stays good).
        ``too_few_inliers``: too few measurements support the pose for it to mean anything (Gauglitz §4.4)."""
        cfg = self.cfg
        attempted, found = int(attempted_per_level.sum()), int(found_per_level.sum())
        if attempted == 0 or found == 0 or too_few_inliers:
            quality = BAD
        else:
            fraction = found / attempted
            large_attempted = int(attempted_per_level[cfg.quality_large_min_level :].sum())
            large = (
                found_per_level[cfg.quality_large_min_level :].sum() / large_attempted
                if large_attempted > cfg.quality_large_min_attempted
                else fraction
            )
            quality = GOOD if fraction > cfg.quality_good else BAD if large < cfg.quality_lost else POOR
            if quality == POOR and too_far:
                quality = BAD
        if quality != BAD:
            self.bad_frames = 0
        elif not suspend:
            self.bad_frames += 1
        return quality
