"""Camera calibration from chessboard views: a joint least-squares fit of the intrinsics and every board pose.

The model is PTAM's (§5.2, eq. 3–5: pinhole + FOV distortion ω), OpenCV's radial-tangential, or a pinhole.
All three are finished by the same fit: ``scipy.optimize.least_squares`` (trust-region reflective) over
(intrinsics, 6 pose parameters per view) with an analytic Jacobian passed as a sparse matrix (each view's
residuals depend on the intrinsics and on that view's pose only) and solved by LSMR, and a robust loss so a
few bad corners cannot drag it. Views whose RMS is far above the median are dropped and the fit repeated.

Initialisation (Zhang 2000, as implemented by OpenCV's ``calibrateCamera``):
  * pinhole, radtan — ``calibrateCamera`` with the same model;
  * fov — a zero-distortion ``calibrateCamera``, then a 1-D search over ω (for each candidate ω a short fit of
    the rest on the most spread views), so the fit starts in the right basin even on wide-angle lenses,
    where the pinhole solution's focal length is far off.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from ..config import CalibrateConfig
from ..errors import InputError, PtamError
from ..geometry import se3, so3
from ..vocabulary import LensModel
from .camera_file import camera_from_dict
from .fov import FovCamera
from .model import CameraModel
from .pinhole import PinholeCamera
from .radtan import RadTanCamera

MODELS = tuple(LensModel)
_BAD_RESIDUAL = 1e6  # px, stands in for projections of points a trial step put behind the camera
_OMEGA_BOUNDS = (1e-3, 3.0)  # the FOV model needs 0 < ω < π; 3.0 is already a 170° lens


@dataclass
class CalibrationResult:
    """The fitted camera and the per-view report. Arrays are indexed like the views passed in."""

    camera: CameraModel
    rms: float  # RMS reprojection error (px) over the corners of the views used
    view_rms: np.ndarray  # (V,) RMS per view under the final camera, dropped views included
    used: np.ndarray  # (V,) bool, False for views dropped as outliers
    poses_T_cb: np.ndarray  # (V, 4, 4) board -> camera
    tilts_deg: np.ndarray  # (V,) angle between the board's normal and the optical axis

    @property
    def n_used(self) -> int:
        return int(self.used.sum())


def make_camera(model: str, size: tuple[int, int], p: np.ndarray) -> CameraModel:
    """Camera from the parameter vector [fx, fy, cx, cy, distortion...]."""
    w, h = size
    if model == LensModel.FOV:
        return FovCamera(w, h, *p[:5])
    if model == LensModel.RADTAN:
        return RadTanCamera(w, h, *p[:9])
    return PinholeCamera(w, h, *p[:4])


def project_views(
    model: str, size: tuple[int, int], intr: np.ndarray, poses: np.ndarray, points: np.ndarray
) -> np.ndarray:
    """Pixels (V, N, 2) of board ``points`` (N, 3) under poses (V, 6) = (rotation vector, translation)."""
    R = so3.exp(poses[:, :3])
    Xc = np.einsum("vij,nj->vni", R, points) + poses[:, None, 3:]
    return make_camera(model, size, intr).project(Xc)


def view_rms(residuals: np.ndarray) -> np.ndarray:
    """RMS of the 2-D corner errors per view, (V, N, 2) -> (V,)."""
    return np.sqrt(np.mean(np.sum(residuals**2, axis=-1), axis=-1))


_DIST_STEP = 1e-6  # relative central-difference step for the distortion parameters' derivatives


def jacobian(
    model: str, size: tuple[int, int], intr: np.ndarray, poses: np.ndarray, points: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """∂pixels/∂intrinsics (V, N, 2, K) and ∂pixels/∂pose (V, N, 2, 6) of :func:`project_views`.

    Poses and fx, fy, cx, cy are analytic (the camera's ``project_jacobian`` and the SO(3) left Jacobian of
    the rotation vector); the distortion parameters use central differences, two projections each.
    """
    R = so3.exp(poses[:, :3])
    RX = np.einsum("vij,nj->vni", R, points)
    Xc = RX + poses[:, None, 3:]
    V, N = Xc.shape[:2]
    cam = make_camera(model, size, intr)
    Jp = cam.project_jacobian(Xc.reshape(-1, 3)).reshape(V, N, 2, 3)
    dR = -so3.hat(RX) @ so3.left_jacobian(poses[:, :3])[:, None]  # ∂(R X)/∂w, (V, N, 3, 3)
    J_pose = np.concatenate([Jp @ dR, Jp], axis=-1)
    d = cam.distort(Xc[..., :2] / Xc[..., 2:3])
    J_intr = np.zeros((V, N, 2, len(intr)))
    J_intr[..., 0, 0] = d[..., 0]
    J_intr[..., 1, 1] = d[..., 1]
    J_intr[..., 0, 2] = 1.0
    J_intr[..., 1, 3] = 1.0
    for k in range(4, len(intr)):
        h = _DIST_STEP * max(1.0, abs(intr[k]))
        lo, hi = intr.copy(), intr.copy()
        lo[k] -= h
        hi[k] += h
        J_intr[..., k] = (make_camera(model, size, hi).project(Xc) - make_camera(model, size, lo).project(Xc)) / (2 * h)
    return J_intr, J_pose


def fit(
    model: str,
    size: tuple[int, int],
    intr0: np.ndarray,
    poses0: np.ndarray,
    points: np.ndarray,
    observed: np.ndarray,
    cfg: CalibrateConfig,
    free: np.ndarray | None = None,
    max_nfev: int | None = None,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint fit of the intrinsics marked ``free`` (default all) and every pose; returns (intrinsics, poses,
    final robust cost)."""
    intr0 = np.asarray(intr0, dtype=np.float64)
    free = np.ones(len(intr0), dtype=bool) if free is None else np.asarray(free, dtype=bool)
    n_free, V = int(free.sum()), len(poses0)
    rows = 2 * len(points)

    def unpack(x):
        intr = intr0.copy()
        intr[free] = x[:n_free]
        return intr, x[n_free:].reshape(V, 6)

    def residuals(x):
        intr, poses = unpack(x)
        with np.errstate(all="ignore"):
            r = (project_views(model, size, intr, poses, points) - observed).ravel()
        # A trial step that throws points behind the camera must look bad, not crash the solver.
        return np.where(np.isfinite(r), r, _BAD_RESIDUAL)

    rows_idx, cols = _jacobian_pattern(V, rows, n_free)

    def jac(x):
        intr, poses = unpack(x)
        with np.errstate(all="ignore"):
            J_intr, J_pose = jacobian(model, size, intr, poses, points)
        vals = np.concatenate([J_intr[..., free].reshape(V * rows, n_free), J_pose.reshape(V * rows, 6)], axis=1)
        vals = np.where(np.isfinite(vals), vals, 0.0).ravel()
        return csr_matrix((vals, (rows_idx, cols)), shape=(V * rows, n_free + 6 * V))

    x0 = np.concatenate([intr0[free], np.asarray(poses0, dtype=np.float64).ravel()])
    lo, hi = _bounds(model, free, x0)
    sol = least_squares(
        residuals,
        x0,
        jac=jac,
        bounds=(lo, hi),
        method="trf",
        tr_solver="lsmr",
        loss=cfg.loss,
        f_scale=cfg.loss_scale_px,
        x_scale="jac",
        max_nfev=max_nfev or cfg.max_nfev,
    )
    intr, poses = unpack(sol.x)
    return intr, poses, float(sol.cost)


def _jacobian_pattern(V: int, rows: int, n_free: int) -> tuple[np.ndarray, np.ndarray]:
    """Each view's rows depend on the intrinsics and on its own six pose parameters only: a sparse Jacobian
    (dense intrinsic columns, block-diagonal pose columns), solved by LSMR inside the trust region."""
    r_idx = np.arange(V * rows)
    pose_cols = n_free + 6 * np.repeat(np.arange(V), rows)[:, None] + np.arange(6)
    cols = np.concatenate([np.broadcast_to(np.arange(n_free), (V * rows, n_free)), pose_cols], axis=1).ravel()
    return np.repeat(r_idx, n_free + 6), cols


def _bounds(model: str, free: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """No bounds but on the FOV model's ω (PTAM eq. 3-5 need 0 < ω < π); clips ``x0`` into them."""
    lo, hi = np.full(len(x0), -np.inf), np.full(len(x0), np.inf)
    if model == LensModel.FOV and free[4]:
        k = int(free[:4].sum())
        lo[k], hi[k] = _OMEGA_BOUNDS
        x0[k] = np.clip(x0[k], *_OMEGA_BOUNDS)
    return lo, hi


def _opencv_init(
    model: str, size: tuple[int, int], points: np.ndarray, observed: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Zhang's closed form + LM from ``cv2.calibrateCamera``: intrinsics vector and poses (V, 6)."""
    obj = [points.astype(np.float32)] * len(observed)
    img = [o.reshape(-1, 1, 2).astype(np.float32) for o in observed]
    flags = 0
    if model != "radtan":
        flags = cv2.CALIB_ZERO_TANGENT_DIST | cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3
    try:
        _, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, tuple(size), None, None, flags=flags)
    except cv2.error as e:
        raise PtamError(f"calibration failed in OpenCV's initialisation: {str(e).strip().splitlines()[-1]}") from None
    poses = np.concatenate([np.asarray(rvecs).reshape(-1, 3), np.asarray(tvecs).reshape(-1, 3)], axis=1)
    intr = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
    if model == LensModel.RADTAN:
        intr += list(np.ravel(dist)[:5])
    return np.array(intr, dtype=np.float64), poses


def _spread_subset(observed: np.ndarray, n: int) -> np.ndarray:
    """Indices of ``n`` views chosen by farthest-point sampling of their corner sets."""
    V = len(observed)
    if n >= V:
        return np.arange(V)
    flat = observed.reshape(V, -1)
    chosen = [int(np.argmax(np.linalg.norm(flat - flat.mean(0), axis=1)))]
    nearest = np.linalg.norm(flat - flat[chosen[0]], axis=1)
    while len(chosen) < n:
        nearest[chosen] = -1.0
        best = int(np.argmax(nearest))
        chosen.append(best)
        nearest = np.minimum(nearest, np.linalg.norm(flat - flat[best], axis=1))
    return np.sort(np.array(chosen))


def _fov_init(size, points, observed, cfg: CalibrateConfig) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole init, then the ω of the search grid whose short fit (ω fixed) has the lowest cost."""
    intr_p, poses_p = _opencv_init("pinhole", size, points, observed)
    sub = _spread_subset(observed, cfg.omega_search_views)
    first, last, count = cfg.omega_search
    free = np.array([True, True, True, True, False])
    best: tuple[float, np.ndarray] | None = None
    for omega in np.linspace(first, last, int(count)):
        intr, poses, cost = fit(
            "fov",
            size,
            np.append(intr_p, omega),
            poses_p[sub],
            points,
            observed[sub],
            cfg,
            free=free,
            max_nfev=cfg.omega_search_nfev,
        )
        if best is None or cost < best[0]:
            best = (cost, intr)
    assert best is not None  # the loop runs at least once
    intr = best[1]
    # Re-seed every pose under the chosen intrinsics: PnP on the undistorted corners is exact for the model.
    cam = make_camera("fov", size, intr)
    poses = np.empty_like(poses_p)
    for v, obs in enumerate(observed):
        xy = cam.unproject(obs)
        ok, rvec, tvec = cv2.solvePnP(points, xy, np.eye(3), None, flags=cv2.SOLVEPNP_IPPE)
        poses[v] = np.concatenate([rvec.ravel(), tvec.ravel()]) if ok else poses_p[v]
    return intr, poses


def initialise(
    model: str, size: tuple[int, int], points: np.ndarray, observed: np.ndarray, cfg: CalibrateConfig
) -> tuple[np.ndarray, np.ndarray]:
    if model == LensModel.FOV:
        return _fov_init(size, points, observed, cfg)
    return _opencv_init(model, size, points, observed)


def calibrate(
    model: str, size: tuple[int, int], points: np.ndarray, observed: np.ndarray, cfg: CalibrateConfig
) -> CalibrationResult:
    """Fit ``model`` to board ``points`` (N, 3) seen as ``observed`` (V, N, 2) pixels in ``size`` images."""
    if model not in MODELS:
        raise InputError(f"unknown camera model '{model}' (expected one of {', '.join(MODELS)})")
    observed = np.asarray(observed, dtype=np.float64)
    V = len(observed)
    if cfg.min_views > V:
        raise InputError(
            f"only {V} usable chessboard views, need at least {cfg.min_views}: show the board in more "
            "positions and tilts"
        )
    intr, poses = initialise(model, size, points, observed, cfg)
    used = np.ones(V, dtype=bool)
    for _ in range(cfg.max_refits + 1):
        intr, poses_used, _ = fit(model, size, intr, poses[used], points, observed[used], cfg)
        poses[used] = poses_used
        rms = view_rms(project_views(model, size, intr, poses, points) - observed)
        limit = max(cfg.outlier_factor * float(np.median(rms[used])), cfg.outlier_min_rms_px)
        bad = used & (rms > limit)
        if not bad.any() or used.sum() - bad.sum() < cfg.min_views:
            break
        used &= ~bad
    # Dropped views' poses were frozen during refits; refit them alone so their reported RMS is meaningful.
    for v in np.nonzero(~used)[0]:
        _, pv, _ = fit(
            model, size, intr, poses[v : v + 1], points, observed[v : v + 1], cfg, free=np.zeros(len(intr), dtype=bool)
        )
        poses[v] = pv[0]
    rms = view_rms(project_views(model, size, intr, poses, points) - observed)
    try:
        camera = camera_from_dict(make_camera(model, size, intr).to_dict(), where="calibration result")
    except InputError as e:
        raise PtamError(f"calibration did not converge to a valid camera ({e}); check --board and the views") from None
    total = float(np.sqrt(np.mean(rms[used] ** 2)))
    R = so3.exp(poses[:, :3])
    tilts = np.degrees(np.arccos(np.clip(np.abs(R[:, 2, 2]), 0.0, 1.0)))
    return CalibrationResult(camera, total, rms, used, se3.from_Rt(R, poses[:, 3:]), tilts)
