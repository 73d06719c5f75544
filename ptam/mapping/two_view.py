"""Relative pose and structure from the initialisation trails (PTAM §6.1).

The five-point algorithm in a robust estimator (OpenCV ``findEssentialMat`` with USAC, as DESIGN.md
chooses), pose recovery by cheirality, then linear triangulation of the inliers. Failures carry a reason
that the system logs before it restarts initialisation: too few trails, too few inliers, or a baseline
too small against the scene (rotation-only motion) for triangulation to mean anything.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry import se3
from ..geometry.triangulation import triangulate_two_view

_USAC = {"default": cv2.USAC_DEFAULT, "magsac": cv2.USAC_MAGSAC, "accurate": cv2.USAC_ACCURATE,
         "prosac": cv2.USAC_PROSAC, "ransac": cv2.RANSAC}


class InitFailure(Exception):
    """Initialisation did not succeed; ``str(e)`` is the reason."""


@dataclass(frozen=True)
class TwoViewResult:
    T_c1c0: np.ndarray       # (4, 4) second camera from first camera, unit baseline
    X0: np.ndarray           # (K, 3) inlier points in the first camera's frame
    inliers: np.ndarray      # (N,) bool over the input matches
    median_parallax_deg: float


def estimate_two_view(camera, xy0: np.ndarray, xy1: np.ndarray, init_cfg) -> TwoViewResult:
    """Matches in level-0 pixels (N, 2) -> relative pose and triangulated inliers."""
    c = init_cfg
    n = len(xy0)
    if n < c.min_matches:
        raise InitFailure(f"too few trails ({n} < {c.min_matches})")
    r0 = camera.unproject(np.asarray(xy0, np.float64))
    r1 = camera.unproject(np.asarray(xy1, np.float64))
    f = 0.5 * (camera.fx + camera.fy)
    cv2.setRNGSeed(c.ransac_seed)  # deterministic runs (sync-mode tests compare trajectories bit for bit)
    E, mask = cv2.findEssentialMat(r0, r1, np.eye(3), method=_USAC[c.essential_method],
                                   prob=c.ransac_confidence, threshold=c.essential_threshold_px / f)
    if E is None or E.shape != (3, 3):
        raise InitFailure("no essential matrix found")
    mask = mask.ravel().astype(bool)
    n_in, R, t, mask_pose = cv2.recoverPose(E, r0, r1, np.eye(3), mask=mask.astype(np.uint8).copy())
    inl = mask_pose.ravel().astype(bool)
    if inl.sum() < c.min_inliers:
        raise InitFailure(f"too few inliers ({int(inl.sum())} < {c.min_inliers})")
    T = se3.from_Rt(R, t.ravel())
    X0 = triangulate_two_view(np.eye(4), T, r0[inl], r1[inl])
    X1 = se3.transform(T, X0)
    # Reprojection and cheirality check in pixels, as the five-point inlier test was made on rays.
    e0 = np.linalg.norm(camera.project(X0) - xy0[inl], axis=1)
    e1 = np.linalg.norm(camera.project(X1) - xy1[inl], axis=1)
    good = (X0[:, 2] > 0) & (X1[:, 2] > 0) & (e0 < c.triangulation_max_error_px) & (e1 < c.triangulation_max_error_px)
    idx = np.flatnonzero(inl)
    inl = np.zeros(n, bool)
    inl[idx[good]] = True
    X0 = X0[good]
    if len(X0) < c.min_inliers:
        raise InitFailure(f"too few triangulated inliers ({len(X0)} < {c.min_inliers})")
    # Parallax: angle between the two viewing rays of each point.
    c1 = -T[:3, :3].T @ T[:3, 3]
    a = X0 / np.linalg.norm(X0, axis=1, keepdims=True)
    b = X0 - c1
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    parallax = float(np.degrees(np.median(np.arccos(np.clip((a * b).sum(axis=1), -1.0, 1.0)))))
    if parallax < c.min_parallax_deg:
        raise InitFailure(f"baseline too small for the scene depth (median parallax {parallax:.2f} deg < "
                          f"{c.min_parallax_deg} deg): rotation-only motion?")
    return TwoViewResult(T, X0, inl, parallax)
