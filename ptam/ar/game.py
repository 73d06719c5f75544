"""A mini game in the spirit of PTAM §7.5's "Ewok Rampage": the hand-held camera is the weapon.

"The projection of the camera's optical axis onto the playing surface forms the player's cross-hairs." As the
ewoks assault Darth Vader, targets (rolling beach balls) roll in on the eyes in the middle of the plane from the
edge of a square arena around them, wandering up to ``ar.target_wander_deg`` off the direct course. A target
is hit when the optical axis passes through it, or close enough that it touches the cross-hair ring
(``ar.crosshair_radius``), and either the player fires (a key press: :meth:`TargetGame.fire`) or the aim has
dwelt on it for ``ar.dwell_frames`` consecutive frames (recorded videos have no key presses). A hit scores and
leaves an expanding ring on the plane; a target that reaches the eyes bites. Either way it starts again from
the arena's edge. Everything is deterministic for a given seed and frame sequence.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry import so3
from . import materials
from .drawlist import decal_records, sphere_records
from .raster_kernels import BALL, D_ALPHA


def ray_sphere_hits(origin: np.ndarray, direction: np.ndarray, centres: np.ndarray, radius: float) -> np.ndarray:
    """Distance along the unit ray to each sphere (N,), inf where the ray misses it or it lies behind."""
    oc = centres - origin
    along = oc @ direction
    d2 = (oc * oc).sum(axis=1) - along**2
    half = np.sqrt(np.maximum(radius**2 - d2, 0.0))
    t = along - half
    return np.where((d2 <= radius**2) & (along + half > 0), np.maximum(t, 0.0), np.inf)


class TargetGame:
    """``keep_out``: the radius of the eyes' footprint around the plane origin (a target reaching it bites)."""

    def __init__(self, ar_cfg, keep_out: float):
        self.cfg = ar_cfg
        self.rng = np.random.default_rng(ar_cfg.seed)
        self.radius = ar_cfg.target_radius
        self.keep_out = keep_out + self.radius  # centre distance from the origin at which a target bites
        n = ar_cfg.target_count
        # Spread the first wave over the arena so it does not arrive all at once.
        half = ar_cfg.arena_half_size - self.radius
        self.pos = np.array([self._edge_point() * self.rng.uniform(self.keep_out / half, 1.0) for _ in range(n)])
        self.wander = np.zeros(n)  # heading offset from the direct course (rad)
        self.R = np.tile(np.eye(3), (n, 1, 1))  # ball→plane, rolled as the ball moves
        self.dwell = np.zeros(n, np.int64)
        self.hits = 0
        self.bites = 0
        self.aim: np.ndarray | None = None  # where the optical axis meets the plane (u, v)
        self.aimed = -1  # index of the target the optical axis passes through
        self.bursts = np.zeros((0, 3))  # (u, v, age in frames)
        self._fire = False

    @property
    def centres(self) -> np.ndarray:
        return np.concatenate([self.pos, np.full((len(self.pos), 1), self.radius)], axis=1)

    def fire(self) -> None:
        """A key press: hits the aimed target at the next frame."""
        self._fire = True

    def _edge_point(self) -> np.ndarray:
        """A random point on the arena's edge."""
        half = self.cfg.arena_half_size - self.radius
        side = self.rng.integers(4)
        along = self.rng.uniform(-half, half)
        return np.array([[half, along], [-half, along], [along, half], [along, -half]][side])

    def _restart(self, k: int) -> None:
        self.pos[k] = self._edge_point()
        self.wander[k] = 0.0
        self.dwell[k] = 0

    def _move(self, dt: float) -> None:
        c = self.cfg
        limit = math.radians(c.target_wander_deg)
        self.wander = np.clip(
            self.wander + c.target_turn_rate * math.sqrt(dt) * self.rng.standard_normal(len(self.pos)), -limit, limit
        )
        heading = np.arctan2(-self.pos[:, 1], -self.pos[:, 0]) + self.wander
        step = c.target_speed * dt * np.stack([np.cos(heading), np.sin(heading)], axis=1)
        dist = np.linalg.norm(step, axis=1)
        axis = np.stack([-step[:, 1], step[:, 0], np.zeros(len(step))], axis=1)  # z × step: rolling axis
        with np.errstate(invalid="ignore", divide="ignore"):
            w = np.where(dist[:, None] > 0, axis / dist[:, None], 0.0) * (dist / self.radius)[:, None]
        self.R = so3.exp(w) @ self.R
        self.pos = self.pos + step
        for k in np.flatnonzero(np.linalg.norm(self.pos, axis=1) < self.keep_out):
            self.bites += 1
            self._restart(k)

    def step(self, T_pc: np.ndarray, dt: float) -> None:
        """Advance by ``dt`` seconds and resolve the aim of the camera with pose T_pc (camera→plane)."""
        origin, axis = T_pc[:3, 3], T_pc[:3, 2]
        self.aim = origin[:2] - origin[2] / axis[2] * axis[:2] if axis[2] < 0 and origin[2] > 0 else None
        self._move(min(max(dt, 0.0), self.cfg.max_step_s))
        self.bursts[:, 2] += 1
        self.bursts = self.bursts[self.bursts[:, 2] < self.cfg.burst_frames]
        t = ray_sphere_hits(origin, axis, self.centres, self.radius + self.cfg.crosshair_radius)
        self.aimed = int(np.argmin(t)) if np.isfinite(t).any() else -1
        fired, self._fire = self._fire, False
        self.dwell = np.where(np.arange(len(self.pos)) == self.aimed, self.dwell + 1, 0)
        k = self.aimed
        if k >= 0 and (fired or (self.cfg.dwell_frames > 0 and self.dwell[k] >= self.cfg.dwell_frames)):
            self.hits += 1
            self.bursts = np.concatenate([self.bursts, [[*self.pos[k], 0.0]]])
            self._restart(k)
            self.aimed = -1

    @property
    def dwell_fraction(self) -> float:
        if self.aimed < 0 or self.cfg.dwell_frames <= 0:
            return 0.0
        return float(self.dwell[self.aimed]) / self.cfg.dwell_frames

    def spheres(self) -> np.ndarray:
        n = len(self.pos)
        stripes = np.array([materials.TARGETS[i % len(materials.TARGETS)] for i in range(n)])
        colours = np.stack(
            [stripes, np.broadcast_to(materials.TARGET_STRIPE, (n, 3)), np.broadcast_to(materials.TARGET_CAP, (n, 3))],
            axis=1,
        )
        return sphere_records(
            self.centres,
            self.radius,
            self.R,
            colours,
            BALL,
            materials.BALL_SECTORS,
            math.cos(math.radians(materials.BALL_CAP_DEG)),
            materials.TARGET_SPECULAR,
        )

    def decals(self) -> np.ndarray:
        c = self.cfg
        r = self.radius
        parts = [
            decal_records(
                self.pos, 0.0, c.shadow_radius_rel * r, c.shadow_softness_rel * r, materials.SHADOW, c.shadow_alpha
            )
        ]
        if len(self.bursts):
            f = (self.bursts[:, 2] + 1.0) / c.burst_frames
            ro = r * (1.0 + (materials.BURST_GROWTH - 1.0) * f)
            b = decal_records(self.bursts[:, :2], ro - materials.BURST_WIDTH * r, ro, 0.0, materials.BURST, 1.0)
            b[:, D_ALPHA] = 1.0 - f
            parts.append(b)
        if self.aim is not None:
            colour = materials.AIM_RING_LOCKED if self.aimed >= 0 else materials.AIM_RING
            parts.append(
                decal_records(
                    self.aim,
                    materials.AIM_RING_INNER * c.crosshair_radius,
                    c.crosshair_radius,
                    0.0,
                    colour,
                    materials.AIM_RING_ALPHA,
                )
            )
        return np.concatenate(parts)
