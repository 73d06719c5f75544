"""Edgelet terms for bundle adjustment (Agility §4.4): two perpendicular distances per keyframe measurement.

``sample_along`` places the two virtual sample points of eq. 6 at ∓``ba_sample_offset_px``/|d| on each
edgelet's z-axis (|d| the image length of a unit step along the edgelet in that keyframe, eq. 5); the caller
computes them once per adjustment (the paper "initialises" them) so that they stay fixed in the edgelet frame
while the parameters move. ``edgelet_terms`` evaluates residuals and the exact Jacobians with respect to the
keyframe pose (6, left-multiplied update, μ = (translation, rotation)) and the edgelet (4 DOF,
right-multiplied, ``Edgelets.updated``); the loop is ``edgelet_ba_kernels.edgelet_ba_terms``. Per §8 each
distance has unit (one-pixel) variance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import CameraModel
from ..config.edgelet_section import EdgeletConfig
from ..errors import InputError
from ..geometry import se3
from .edgelet import Edgelets, perp
from .edgelet_ba_kernels import edgelet_ba_terms
from .edgelet_refine_kernels import refine_frames


@dataclass(frozen=True)
class EdgeletObservations:
    """Keyframe measurements of edgelets: keyframe index ``kf`` (M,), edgelet index ``edgelet`` (M,), and the
    measured image line through ``a`` (M, 2) with unit direction ``b`` (M, 2) (``LineMeasurements``)."""

    kf: np.ndarray
    edgelet: np.ndarray
    a: np.ndarray
    b: np.ndarray

    def __post_init__(self) -> None:
        m = len(self.kf)
        if len(self.edgelet) != m or np.shape(self.a) != (m, 2) or np.shape(self.b) != (m, 2):
            raise InputError("edgelet observations: kf, edgelet (M,), a and b (M, 2) must agree in length")


@dataclass(frozen=True)
class EdgeletTerms:
    """Residuals ``err`` (M, 2) px, ``J_pose`` (M, 2, 6), ``J_edgelet`` (M, 2, 4), ``valid`` (M,)."""

    err: np.ndarray
    J_pose: np.ndarray
    J_edgelet: np.ndarray
    valid: np.ndarray


def sample_along(
    camera: CameraModel, poses: np.ndarray, edgelets: Edgelets, obs: EdgeletObservations, cfg: EdgeletConfig
) -> np.ndarray:
    """(M, 2) E-frame z of the two sample points of each measurement, ∓offset/|d| (eq. 6)."""
    T = np.asarray(poses, dtype=np.float64)[obs.kf]
    c = edgelets.centre[obs.edgelet]
    Xc = np.einsum("mij,mj->mi", T[:, :3, :3], c) + T[:, :3, 3]
    Dc = np.einsum("mij,mj->mi", T[:, :3, :3], edgelets.direction[obs.edgelet])
    d = np.einsum("mij,mj->mi", camera.project_jacobian(Xc), Dc)
    length = np.maximum(np.linalg.norm(d, axis=-1), 1e-12)
    z = cfg.ba_sample_offset_px / length
    return np.stack([-z, z], axis=-1)


def edgelet_terms(
    camera: CameraModel, poses: np.ndarray, edgelets: Edgelets, obs: EdgeletObservations, along: np.ndarray
) -> EdgeletTerms:
    """Residuals ε_n = m̂·(s_n − a) and their Jacobians for every observation (Agility §4.4, eq. 7–9)."""
    m_hat = _line_normals(obs)
    err, Jp, Je, valid = edgelet_ba_terms(
        camera.kernel_params(),
        np.ascontiguousarray(poses, dtype=np.float64),
        np.ascontiguousarray(edgelets.frames()),
        np.ascontiguousarray(obs.kf, dtype=np.int64),
        np.ascontiguousarray(obs.edgelet, dtype=np.int64),
        np.ascontiguousarray(obs.a, dtype=np.float64),
        np.ascontiguousarray(m_hat),
        np.ascontiguousarray(along, dtype=np.float64),
    )
    return EdgeletTerms(err, Jp, Je, valid)


def _line_normals(obs: EdgeletObservations) -> np.ndarray:
    """m̂ (M, 2): the unit normals of the measured lines."""
    b = np.asarray(obs.b, dtype=np.float64)
    return perp(b / np.linalg.norm(b, axis=-1, keepdims=True))


def update_poses(poses: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """T ← exp(μ) T for keyframe poses (K, 4, 4) and updates (K, 6): the parametrisation of ``J_pose``."""
    return se3.exp_left(mu, poses)


def refine_edgelets(
    camera: CameraModel,
    poses: np.ndarray,
    edgelets: Edgelets,
    obs: EdgeletObservations,
    cfg: EdgeletConfig,
    iterations: int,
) -> Edgelets:
    """Structure-only Gauss–Newton on the 4-DOF edgelet parameters with the keyframe poses fixed (the edgelet
    blocks of §4.4's bundle adjustment), e.g. over a new edgelet's source, target and check measurements.
    Edgelets with fewer than two valid measurements are left where they are."""
    along = sample_along(camera, poses, edgelets, obs, cfg)
    frames = np.ascontiguousarray(edgelets.frames())
    refine_frames(
        camera.kernel_params(),
        np.ascontiguousarray(poses, dtype=np.float64),
        frames,
        np.ascontiguousarray(obs.kf, dtype=np.int64),
        np.ascontiguousarray(obs.edgelet, dtype=np.int64),
        np.ascontiguousarray(obs.a, dtype=np.float64),
        np.ascontiguousarray(_line_normals(obs)),
        np.ascontiguousarray(along, dtype=np.float64),
        int(iterations),
    )
    return Edgelets(frames[:, :3, 3], frames[:, :3, 2], frames[:, :3, 0])
