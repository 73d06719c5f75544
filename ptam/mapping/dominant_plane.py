"""The dominant plane of the map, found by RANSAC and refined by PCA (PTAM §6.1, code ``CalcPlaneAligner``).

Many triples of points hypothesise planes, scored by the sum of point distances truncated at the inlier
distance (PTAM code: MSAC with a 0.05 cap in map units, where the stereo baseline is 0.1); the consensus
set's mean and the smallest eigenvector of its covariance give the refined plane. The aligner is the rigid
transform that puts the plane at z = 0 with +z towards a reference point (the camera), so AR content stands
on the plane, facing the user.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import se3


@dataclass(frozen=True)
class Plane:
    normal: np.ndarray  # (3,) unit
    point: np.ndarray  # (3,) a point on the plane (the consensus set's mean)
    inliers: np.ndarray  # (N,) bool


def fit_dominant_plane(X: np.ndarray, inlier_distance: float, iterations: int, seed: int) -> Plane | None:
    """MSAC over point triples (all hypotheses scored at once), then PCA of the consensus set."""
    X = np.asarray(X, np.float64)
    if len(X) < 3:
        return None
    rng = np.random.default_rng(seed)
    tri = rng.integers(0, len(X), size=(iterations, 3))
    a, b, c = X[tri[:, 0]], X[tri[:, 1]], X[tri[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-12  # also drops triples that repeat a point
    if not ok.any():
        return None
    n = n[ok] / norm[ok, None]
    d = np.abs(n @ X.T - (n * a[ok]).sum(axis=1, keepdims=True))  # (hypotheses, points)
    best = int(np.argmin(np.minimum(d, inlier_distance).sum(axis=1)))
    inliers = d[best] < inlier_distance
    P = X[inliers]
    mean = P.mean(axis=0)
    _, vecs = np.linalg.eigh((P - mean).T @ (P - mean))
    normal = vecs[:, 0]
    return Plane(normal, mean, inliers)


def plane_aligner(plane: Plane, towards: np.ndarray) -> np.ndarray:
    """T_new_old (4, 4): the plane becomes z = 0 with its normal as +z pointing to ``towards``."""
    z = plane.normal if np.dot(towards - plane.point, plane.normal) >= 0 else -plane.normal
    # Any in-plane x axis will do; take the one closest to the old x axis for a stable, readable frame.
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - z * np.dot(ref, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R_new_old = np.stack([x, y, z])
    return se3.from_Rt(R_new_old, -R_new_old @ plane.point)
