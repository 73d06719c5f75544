"""Camera trajectories from key poses: cubic Hermite in position, slerp-built Bézier in rotation, jitter.

Key poses sit at (possibly fractional) frame numbers. Between keys the position follows a cubic Hermite
segment and the rotation the matching cubic Bézier on SO(3), evaluated by De Casteljau's construction
with slerps, so velocity and angular velocity are continuous across keys. Tangents are monotone
(Fritsch–Carlson, as in PCHIP): the path never overshoots a key, a pause (``hold``) is a true stop, and the
camera starts and ends at rest.

Hand-held jitter is a sum of sinusoids with random frequencies and phases per axis (deterministic from a
seed and defined at any time, so motion-blur sub-frames see it too), scaled to a given standard deviation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import so3


@dataclass(frozen=True)
class KeyPose:
    frame: float
    position: np.ndarray  # (3,) camera centre in the world
    R_wc: np.ndarray  # (3, 3) camera-to-world rotation
    hold: float = 0.0  # frames spent at rest on this pose


@dataclass(frozen=True)
class Jitter:
    seed: int
    position_m: float  # standard deviation per world axis
    rotation_rad: float  # standard deviation per camera axis
    freq_lo_hz: float
    freq_hi_hz: float
    components: int  # sinusoids per axis


def look_at(position, target, up, roll_rad: float = 0.0) -> np.ndarray:
    """R_wc of a camera at ``position`` looking at ``target`` (x right, y down, z forward), ``up`` kept upward."""
    position, target, up = (np.asarray(v, dtype=np.float64) for v in (position, target, up))
    f = target - position
    f = f / np.linalg.norm(f)
    right = np.cross(f, up)
    right = right / np.linalg.norm(right)
    down = np.cross(f, right)
    R = np.stack([right, down, f], axis=1)
    c, s = np.cos(roll_rad), np.sin(roll_rad)
    return R @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _pchip_tangents(slopes: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """Tangents (n, 3) at n keys from the n−1 segment slopes (n−1, 3) and durations (n−1, 1)."""
    m = np.zeros((len(slopes) + 1, slopes.shape[1]))
    d0, d1 = slopes[:-1], slopes[1:]
    h0, h1 = dt[:-1], dt[1:]
    w0, w1 = 2.0 * h1 + h0, h1 + 2.0 * h0
    same = d0 * d1 > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        m[1:-1] = np.where(same, (w0 + w1) / (w0 / np.where(same, d0, 1.0) + w1 / np.where(same, d1, 1.0)), 0.0)
    return m


def _slerp(A, B, s):
    """Geodesic from A (s = 0) to B (s = 1), batched: exp(s·log(B·Aᵀ))·A."""
    w = so3.log(B @ np.swapaxes(A, -1, -2))
    return so3.exp(s[..., None] * w) @ A


class Trajectory:
    """Poses T_wc at any frame time from key poses (PTAM §7.3's camera path is built from these)."""

    def __init__(self, keys: list[KeyPose], jitter: Jitter | None = None, fps: float = 30.0):
        f, p, R = [], [], []
        for k in keys:
            for frame in (k.frame, k.frame + k.hold) if k.hold > 0 else (k.frame,):
                f.append(frame)
                p.append(k.position)
                R.append(k.R_wc)
        self.frames = np.asarray(f, dtype=np.float64)
        self.positions = np.asarray(p, dtype=np.float64)
        self.rotations = np.asarray(R, dtype=np.float64)
        self.jitter = jitter
        self.fps = float(fps)
        # Monotone (Fritsch-Carlson / PCHIP) tangents per component: the weighted harmonic mean of the slopes
        # of the two neighbouring segments, zero where they disagree in sign or one is flat (pauses), so the
        # path never overshoots a key. Zero at both ends: the camera starts and stops at rest.
        dt = np.diff(self.frames)[:, None]
        self.v = _pchip_tangents(np.diff(self.positions, axis=0) / dt, dt)
        self.w = _pchip_tangents(  # world-frame angular velocity per frame
            so3.log(self.rotations[1:] @ np.swapaxes(self.rotations[:-1], -1, -2)) / dt, dt
        )
        if jitter is not None:
            rng = np.random.default_rng(jitter.seed)
            shape = (6, jitter.components)
            self._jf = rng.uniform(jitter.freq_lo_hz, jitter.freq_hi_hz, shape) / self.fps  # cycles per frame
            self._jphase = rng.uniform(0.0, 2.0 * np.pi, shape)
            # A unit sinusoid has variance 1/2, so K of them scaled by sqrt(2/K) have unit variance.
            self._jamp = (
                np.sqrt(2.0 / jitter.components) * np.repeat([jitter.position_m, jitter.rotation_rad], 3)[:, None]
            )

    @property
    def last_frame(self) -> float:
        return float(self.frames[-1])

    def smooth_poses(self, t: np.ndarray) -> np.ndarray:
        """T_wc (N, 4, 4) of the key-pose spline at frame times t (N,), without jitter."""
        t = np.clip(np.asarray(t, dtype=np.float64), self.frames[0], self.frames[-1])
        k = np.clip(np.searchsorted(self.frames, t, side="right") - 1, 0, len(self.frames) - 2)
        f0, f1 = self.frames[k], self.frames[k + 1]
        dt = f1 - f0
        s = (t - f0) / dt
        # Cubic Bézier control points of the Hermite segment: p0, p0 + v0·dt/3, p1 − v1·dt/3, p1.
        P0, P3 = self.positions[k], self.positions[k + 1]
        P1 = P0 + self.v[k] * (dt / 3.0)[:, None]
        P2 = P3 - self.v[k + 1] * (dt / 3.0)[:, None]
        R0, R3 = self.rotations[k], self.rotations[k + 1]
        R1 = so3.exp(self.w[k] * (dt / 3.0)[:, None]) @ R0
        R2 = so3.exp(-self.w[k + 1] * (dt / 3.0)[:, None]) @ R3
        # De Casteljau: three rounds of (s)lerps.
        sp = s[:, None]
        a, b, c = P0 + sp * (P1 - P0), P1 + sp * (P2 - P1), P2 + sp * (P3 - P2)
        a, b = a + sp * (b - a), b + sp * (c - b)
        pos = a + sp * (b - a)
        A, B, C = _slerp(R0, R1, s), _slerp(R1, R2, s), _slerp(R2, R3, s)
        A, B = _slerp(A, B, s), _slerp(B, C, s)
        R = _slerp(A, B, s)
        T = np.zeros((len(t), 4, 4))
        T[:, :3, :3] = R
        T[:, :3, 3] = pos
        T[:, 3, 3] = 1.0
        return T

    def jitter_offsets(self, t: np.ndarray) -> np.ndarray:
        """(N, 6): world position offset (m) and camera-frame rotation vector (rad) at frame times t."""
        t = np.asarray(t, dtype=np.float64)
        if self.jitter is None:
            return np.zeros((len(t), 6))
        phase = 2.0 * np.pi * self._jf[None] * t[:, None, None] + self._jphase[None]
        return np.sum(self._jamp[None] * np.sin(phase), axis=-1)

    def poses(self, t: np.ndarray) -> np.ndarray:
        """T_wc (N, 4, 4) at frame times t (N,): the spline with hand-held jitter applied."""
        T = self.smooth_poses(t)
        if self.jitter is not None:
            j = self.jitter_offsets(t)
            T[:, :3, 3] += j[:, :3]
            T[:, :3, :3] = T[:, :3, :3] @ so3.exp(j[:, 3:])
        return T


def path_length(T_wc: np.ndarray) -> float:
    """Length of the polyline through the camera centres (m)."""
    return float(np.sum(np.linalg.norm(np.diff(T_wc[:, :3, 3], axis=0), axis=1)))
