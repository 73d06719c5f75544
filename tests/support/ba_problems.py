"""Bundle-adjustment test problems beside the benchmark's (``ptam.bench.ba_timing``): a small AR workspace."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ptam.bench.ba_timing import CAMERA, NOISE_PX, OUTLIER_FRACTION, WALL_DEPTH_M, SyntheticBA, _observe, look_at
from ptam.camera.fov import FovCamera
from ptam.edgelet import EdgeletObservations, Edgelets, perp, project_edgelets


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


@dataclass(frozen=True)
class EdgeletBA:
    """Edgelets for a ``SyntheticBA`` problem (Agility §4.4): the truth, a perturbed start and keyframe line
    measurements (``gross``: the measurements moved far off the edge)."""

    truth: Edgelets
    init: Edgelets
    obs: EdgeletObservations
    gross: np.ndarray


def synthetic_edgelets(
    prob: SyntheticBA,
    n_edgelets: int,
    seed: int,
    offset_px: float = 0.5,
    angle_deg: float = 2.0,
    perturbation: tuple[float, float] = (0.03, 3.0),
    gross_fraction: float = 0.0,
    gross_px: float = 25.0,
) -> EdgeletBA:
    """``n_edgelets`` random edgelets in the problem's ball of points, measured in every keyframe that sees them
    as the true image line moved by N(0, ``offset_px``²) along its normal and turned by N(0, ``angle_deg``²),
    anchored anywhere within 3 px of the centre; the start is the truth moved by ``perturbation`` (m, degrees in
    random 4-DOF directions)."""
    rng = np.random.default_rng(seed)
    c = prob.points_true.mean(axis=0)
    r = np.linalg.norm(prob.points_true - c, axis=1).max()
    centre = c + 0.8 * r * rng.uniform(-1, 1, (n_edgelets, 3)) / np.sqrt(3)
    truth = Edgelets(centre, rng.normal(size=(n_edgelets, 3)), rng.normal(size=(n_edgelets, 3))).orthonormalised()
    kf, ed, a, b = [], [], [], []
    for k, T in enumerate(prob.poses_true):
        p = project_edgelets(prob.camera, T, truth)
        seen = np.flatnonzero(p.valid & prob.camera.in_image(p.centre))
        ang = np.radians(angle_deg) * rng.normal(size=len(seen))
        u = p.unit_direction[seen]
        cos, sin = np.cos(ang)[:, None], np.sin(ang)[:, None]
        b.append(cos * u + sin * perp(u))
        off = offset_px * rng.normal(size=(len(seen), 1))
        a.append(p.centre[seen] + off * p.normal[seen] + rng.uniform(-3, 3, (len(seen), 1)) * u)
        kf.append(np.full(len(seen), k))
        ed.append(seen)
    a_all = np.concatenate(a)
    gross = rng.random(len(a_all)) < gross_fraction
    b_all = np.concatenate(b)
    a_all[gross] += gross_px * perp(b_all[gross])
    obs = EdgeletObservations(np.concatenate(kf), np.concatenate(ed), a_all, b_all)
    t, deg = perturbation
    v, w = rng.normal(size=(n_edgelets, 2)), rng.normal(size=(n_edgelets, 2))
    mu = np.concatenate(
        [
            t * v / np.linalg.norm(v, axis=1, keepdims=True),
            np.radians(deg) * w / np.linalg.norm(w, axis=1, keepdims=True),
        ],
        1,
    )
    return EdgeletBA(truth, truth.updated(mu), obs, gross)


def edgelet_errors(est: Edgelets, truth: Edgelets) -> tuple[np.ndarray, np.ndarray]:
    """Each edgelet's distance from its true 3-D line (mm; the position along it is no parameter, §4.4 eq. 9)
    and the angle between the directions (degrees)."""
    off = est.centre - truth.centre
    off -= np.sum(off * truth.direction, axis=1, keepdims=True) * truth.direction
    cos = np.clip(np.abs(np.sum(est.direction * truth.direction, axis=1)), 0.0, 1.0)
    return 1e3 * np.linalg.norm(off, axis=1), np.degrees(np.arccos(cos))
