"""The decaying-velocity motion model that gives each frame its prior pose (PTAM §5.1, §6.5).

PTAM code (``ApplyMotionModel``/``UpdateMotionModel``): the prior is exp(v)·E_CW of the last frame; after
tracking, with Δ = ln(E_new·E_start⁻¹), v ← decay·(blend·Δ + (1 − blend)·v), so without measurements the
camera slows and stops. The velocity's magnitude with its translation divided by the mean scene depth decides
whether the camera is nearly stationary (§6.5: the coarse stage is then skipped).

With the rotation estimator (Agility §6, §8) the prior's rotation is the image-based estimate, and its
translation is dropped ("completely replaces the SLAM system's previous motion model"); PTAM code keeps the
velocity along the optical axis (``keep_axial``), which the small-image alignment cannot see.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..geometry import se3


class MotionModel:
    def __init__(self, tracker_cfg):
        self.decay = float(tracker_cfg.motion_decay)
        self.blend = float(tracker_cfg.motion_blend)
        self.velocity = np.zeros(6)
        self.scaled_speed = 0.0
        self.prior = np.zeros(6)  # the motion of the last prediction, over its whole gap
        self.gap = 1.0  # ... of this many frame periods

    def reset(self) -> None:
        self.velocity = np.zeros(6)
        self.scaled_speed = 0.0
        self.prior = np.zeros(6)
        self.gap = 1.0

    def predict(
        self, T_cw: np.ndarray, rotation: np.ndarray | None = None, keep_axial: bool = False, frames: float = 1.0
    ) -> np.ndarray:
        """exp(k·v)·T_cw for a frame ``frames`` = k periods after the last (PTAM assumes k = 1: a camera that
        drops frames moves k frames' worth); with an estimated ``rotation`` (3,), measured over the whole gap,
        v = (0, 0, v_z if ``keep_axial`` else 0, rotation)."""
        v = self.velocity * frames
        if rotation is not None:
            v[:2] = 0.0
            if not keep_axial:
                v[2] = 0.0
            v[3:] = rotation
        self.prior = v
        self.gap = max(float(frames), 1.0)
        return se3.exp(v) @ T_cw

    def prior_rotation_per_frame(self) -> np.ndarray:
        """The prior's rotation (3,) over one frame period: the exposure lasts a fraction of one period however
        many frames were missed, and the rotation estimator measures the whole gap."""
        return self.prior[3:] / self.gap

    def exposure_motion(self, fraction: float) -> np.ndarray:
        """γ_C of Agility eq. 10, the camera motion during an exposure of ``fraction`` of a frame period: the
        prior's rotation (the rotation estimator's when it runs) and the velocity's translation (the estimator
        drops translation from the prior, but translation blurs as well), both per frame period."""
        return np.concatenate([self.velocity[:3], self.prior_rotation_per_frame()]) * fraction

    def update(self, T_start: np.ndarray, T_new: np.ndarray, mean_scene_depth: float, frames: float = 1.0) -> None:
        delta = se3.log(T_new @ se3.inv(T_start)) / frames  # per frame period
        self.velocity = self.decay * (self.blend * delta + (1.0 - self.blend) * self.velocity)
        v = self.velocity.copy()
        v[:3] /= mean_scene_depth
        self.scaled_speed = float(np.linalg.norm(v))


class FrameGaps:
    """How many frame periods passed since the previous frame, from the timestamps; the period is the median of
    the last ``window`` gaps, so a few late frames do not change it. Without timestamps (or before the first
    gap) a frame is one period."""

    def __init__(self, window: int):
        self._gaps: deque[float] = deque(maxlen=window)
        self._last: float | None = None

    def reset(self) -> None:
        self._last = None

    @property
    def period(self) -> float | None:
        """The frame period in seconds (the median of the recent gaps); None before the first gap."""
        return float(np.median(self._gaps)) if self._gaps else None

    def frames(self, timestamp: float) -> float:
        last, self._last = self._last, timestamp
        if last is None or not timestamp > last:
            return 1.0
        dt = timestamp - last
        period = self.period or dt
        self._gaps.append(dt)
        return dt / period
