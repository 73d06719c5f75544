"""Bundle-adjustment test problems beside the benchmark's (``ptam.bench.ba_timing``): a small AR workspace."""

from __future__ import annotations

import numpy as np

from ptam.bench.ba_edgelets import EdgeletBA, edgelet_errors, synthetic_edgelets  # noqa: F401
from ptam.bench.ba_timing import CAMERA, NOISE_PX, OUTLIER_FRACTION, WALL_DEPTH_M, SyntheticBA, _observe, look_at
from ptam.camera.fov import FovCamera


def synthetic_workspace_problem(
    n_keyframes: int,
    n_points: int,
    seed: int,
    camera: FovCamera | None = None,
    arc_deg: float = 90.0,
    scene_radius_m: float = 2.0,
    outlier_fraction: float = OUTLIER_FRACTION,
    noise_px: float = NOISE_PX,
    level_fractions=(1.0,),
) -> SyntheticBA:
    """A small AR workspace (PTAM §1): keyframes on an ``arc_deg`` arc 3 m from the centre of a ball of points
    (radius ``scene_radius_m``), all looking at it, so nearly every keyframe sees every point."""
    rng = np.random.default_rng(seed)
    cam = camera or FovCamera(**CAMERA)
    a = np.radians(np.linspace(-0.5 * arc_deg, 0.5 * arc_deg, int(n_keyframes)))
    centre = np.array([0.0, 0.0, WALL_DEPTH_M])
    C = centre + WALL_DEPTH_M * np.stack([np.sin(a), 0.1 * rng.normal(size=len(a)), -np.cos(a)], 1)
    T = look_at(C, centre + 0.2 * rng.normal(size=(len(a), 3)))
    d = rng.normal(size=(n_points, 3))
    X = centre + scene_radius_m * d / np.linalg.norm(d, axis=1, keepdims=True) * rng.random((n_points, 1)) ** (1 / 3)
    return _observe(cam, T, X, np.zeros(n_points, np.int64), rng, outlier_fraction, noise_px, level_fractions)
