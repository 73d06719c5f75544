"""Bundle adjustment: PTAM §6.3, eq. (10) and (11), as PTAM's ``Bundle.cc`` implements it.

Minimises Σ Obj(|e_ji| / σ_ji, σ_T) over keyframe poses E_KW (updates exp(μ)·E, μ = (translation, rotation))
and point positions p_j, with "an almost textbook implementation of Levenberg–Marquardt" (Hartley &
Zisserman A6.4/A6.6): the points are eliminated by the Schur complement so only the 6N×6N pose system is
factorised. Details from PTAM's code:

* Tukey biweight; its cut-off c (PTAM's "sigma") is re-estimated from the median squared error at the
  start of every iteration, floored at ``min_tukey_sigma``; measurement σ = 2^level px.
* Marquardt damping: the diagonals of U and V are multiplied by (1 + λ); λ starts at 1e-4, × 0.3 after an
  accepted step, × ν after a rejected one (ν = 2, doubling per rejection, reset on success).
* Every LM trial counts towards ``max_iterations``; converged when the squared norm of the whole update is
  below ``converge_squared_update``.
* Measurements with zero Tukey weight (or behind the camera) leave the problem for the rest of the run and
  are reported as outliers (PTAM §6.4 gives them a second chance).
* The abort flag is polled before every trial, so a request stops the solver within one iteration; the
  state returned is always the last accepted one, i.e. the best so far.

One deliberate difference: a trial's cost is compared on the measurements that were inliers when the step
was computed (the flagged ones score 1 on both sides); PTAM re-scores the flagged ones in the trial, which
can accept a step only because an outlier moved.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..camera.model import CameraModel
from ..config import BundleConfig
from ..errors import InputError
from ..geometry import se3
from .bundle_kernels import ba_backsub, ba_linearise, ba_residuals, ba_robust_cost, ba_schur, tukey_cutoff_sq
from .bundle_structure import BundleStructure, ReducedSolver, build_structure

AbortFlag = threading.Event | Callable[[], bool] | None


@dataclass(frozen=True)
class BundleResult:
    poses: np.ndarray          # (N, 4, 4) T_cw; rows of fixed or unmeasured keyframes are the input, bit for bit
    points: np.ndarray         # (M, 3); rows of points not adjusted are the input, bit for bit
    iterations: int            # LM trials (PTAM's mnCounter)
    accepted: int              # accepted steps (PTAM's return value)
    converged: bool
    aborted: bool
    hit_max_iterations: bool
    failed: bool               # the reduced system could not be factorised (PTAM: the map is corrupt)
    cost: float                # PTAM's Tukey objective Σ (1 − (1 − e²/c²)³), outliers 1, at the returned state
    tukey_cutoff: float        # the last c, in σ-normalised px
    inlier_rms: float          # RMS per image coordinate of e/σ over the non-outlier measurements
    n_inliers: int
    n_params: int              # free parameters: 6 per adjusted keyframe + 3 per point with an inlier
    outliers: np.ndarray       # input indices of the measurements flagged as outliers (PTAM §6.4)
    phase_seconds: dict = field(default_factory=dict)

    @property
    def sigma_dof(self) -> float:
        """Noise estimate √(Σ|e/σ|² / (2K − P)): the inlier RMS corrected for the fitted parameters."""
        dof = 2 * self.n_inliers - self.n_params
        return float(self.inlier_rms * np.sqrt(2 * self.n_inliers / dof)) if dof > 0 else float("nan")


def _abort_poller(abort: AbortFlag) -> Callable[[], bool]:
    if abort is None:
        return lambda: False
    if hasattr(abort, "is_set"):
        return abort.is_set
    if callable(abort):
        return abort
    raise InputError("bundle adjustment: abort must be a threading.Event, a callable or None")


def _as_array(name: str, a, shape: tuple, dtype) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != len(shape) or any(s is not None and s != t for s, t in zip(shape, a.shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise InputError(f"bundle adjustment: {name} must have shape {want}, got {a.shape}")
    if dtype is bool and a.dtype != np.bool_:
        raise InputError(f"bundle adjustment: {name} must be a boolean mask, got {a.dtype}")
    out = np.ascontiguousarray(a, dtype=dtype)
    if out.dtype.kind == "f" and not np.isfinite(out).all():
        raise InputError(f"bundle adjustment: {name} contains NaN or infinite values")
    return out


class Bundle:
    """PTAM's bundle adjuster for one camera model. ``adjust`` is re-entrant (no state between calls)."""

    def __init__(self, camera: CameraModel, cfg: BundleConfig):
        self.camera = camera
        self.cfg = cfg
        self._cam = np.ascontiguousarray(camera.kernel_params(), dtype=np.float64)

    def adjust(self, poses, points, meas_kf, meas_pt, meas_xy, meas_level, fixed_poses,
               adjust_points=None, abort: AbortFlag = None) -> BundleResult:
        """Adjust the non-fixed poses and the points in ``adjust_points`` (default all).

        poses (N, 4, 4) T_cw, points (M, 3); measurement k is point ``meas_pt[k]`` seen in keyframe
        ``meas_kf[k]`` at level-0 pixel ``meas_xy[k]``, found on pyramid level ``meas_level[k]``.
        Measurements of points outside ``adjust_points`` are not used (PTAM eq. 11). ``abort``: a
        ``threading.Event`` or a callable polled between LM iterations.
        """
        t_start = time.perf_counter()
        poses = _as_array("poses", poses, (None, 4, 4), np.float64)
        points = _as_array("points", points, (None, 3), np.float64)
        n, m = len(poses), len(points)
        meas_kf = _as_array("meas_kf", meas_kf, (None,), np.int64)
        k = len(meas_kf)
        meas_pt = _as_array("meas_pt", meas_pt, (k,), np.int64)
        meas_xy = _as_array("meas_xy", meas_xy, (k, 2), np.float64)
        meas_level = _as_array("meas_level", meas_level, (k,), np.int64)
        fixed_poses = _as_array("fixed_poses", fixed_poses, (n,), bool)
        adjust_points = (np.ones(m, bool) if adjust_points is None
                         else _as_array("adjust_points", adjust_points, (m,), bool))
        if k and (meas_kf.min() < 0 or meas_kf.max() >= n):
            raise InputError(f"bundle adjustment: keyframe index out of range [0, {n})")
        if k and (meas_pt.min() < 0 or meas_pt.max() >= m):
            raise InputError(f"bundle adjustment: point index out of range [0, {m})")
        if k and meas_level.min() < 0:
            raise InputError("bundle adjustment: negative pyramid level")
        should_abort = _abort_poller(abort)

        st = build_structure(meas_kf, meas_pt, fixed_poses, adjust_points)
        inv_sigma = np.ldexp(1.0, -meas_level[st.sel])  # σ = 2^level px (PTAM §5.4)
        phases = {"setup": 0.0, "linearise": 0.0, "schur": 0.0, "solve": 0.0, "backsub": 0.0, "trial": 0.0}
        solver = ReducedSolver(st, dense=st.n_free <= self.cfg.dense_max_cameras)
        phases["setup"] = time.perf_counter() - t_start
        state = _LMState(st, poses[st.cams], points[st.pts], meas_xy[st.sel], inv_sigma)
        status = self._levenberg_marquardt(state, solver, should_abort, phases)

        out_poses = poses.copy()
        free_cams = st.cams[st.free]
        out_poses[free_cams] = state.P[st.free]
        out_points = points.copy()
        out_points[st.pts] = state.X
        summary = state.summary(self._cam)
        phases["total"] = time.perf_counter() - t_start
        return BundleResult(poses=out_poses, points=out_points, **status, **summary,
                            outliers=np.sort(st.sel[state.outlier]), phase_seconds=phases)

    def _levenberg_marquardt(self, s: _LMState, solver, should_abort, phases: dict) -> dict:
        """PTAM's Bundle::Compute / Do_LM_Step loop; updates ``s`` in place and returns the status flags."""
        cfg, cam, st = self.cfg, self._cam, s.st
        lam, nu = cfg.lambda_initial, cfg.lambda_increase_initial
        iterations = accepted = 0
        converged = hit_max = aborted = failed = False
        free_idx = np.flatnonzero(st.free)
        while not (converged or hit_max or failed or aborted) and s.use.any():
            if should_abort():
                aborted = True
                break
            t = time.perf_counter()
            ba_residuals(cam, s.P, s.X, st.mcam, st.mpt, s.uv, s.inv_sigma, s.use, s.err, s.e2, s.bad)
            s.c2 = tukey_cutoff_sq(s.e2, s.use, s.bad, cfg.min_tukey_sigma)
            cost = ba_linearise(cam, s.P, s.X, st.mcam, st.mpt, s.uv, s.inv_sigma, s.use, s.c2, st.cam_row,
                                s.U, s.ea, s.V, s.eb, s.W, s.live)
            flagged = s.use & ~s.live
            n_flagged = float(flagged.sum())
            phases["linearise"] += time.perf_counter() - t
            new_cost = np.inf
            while new_cost > cost and not (converged or hit_max):
                if should_abort():
                    aborted = True
                    break
                t = time.perf_counter()
                ba_schur(s.U, s.ea, s.V, s.eb, s.W, s.live, lam, st.mrow, st.pt_start, st.order, st.pair_id,
                         s.blocks, s.rhs, s.Vinv)
                t1 = time.perf_counter()
                phases["schur"] += t1 - t
                try:
                    dcam = solver.solve(s.blocks, s.rhs) if len(free_idx) else np.zeros(0)
                except np.linalg.LinAlgError:
                    # With one fixed keyframe the scale gauge is free and only the damping keeps the reduced
                    # system definite; after many good steps λ may be too small for it to factorise. That is a
                    # rejected step, not a corrupt map: raise λ and try again (failed only past lambda_max).
                    lam *= nu
                    nu *= cfg.lambda_increase_growth
                    iterations += 1
                    hit_max = iterations >= cfg.max_iterations
                    failed = lam > cfg.lambda_max
                    if failed:
                        break
                    continue
                t2 = time.perf_counter()
                phases["solve"] += t2 - t1
                dpts = ba_backsub(s.Vinv, s.eb, s.W, s.live, st.mrow, st.pt_start, st.order, dcam)
                t3 = time.perf_counter()
                phases["backsub"] += t3 - t2
                if dcam @ dcam + np.vdot(dpts, dpts) < cfg.converge_squared_update:
                    converged = True
                P_new = s.P.copy()
                P_new[free_idx] = se3.exp(dcam.reshape(-1, 6)) @ s.P[free_idx]
                X_new = s.X + dpts
                ba_residuals(cam, P_new, X_new, st.mcam, st.mpt, s.uv, s.inv_sigma, s.live, s.err, s.e2, s.bad)
                new_cost = ba_robust_cost(s.e2, s.bad, s.live, s.c2) + n_flagged
                if new_cost > cost:
                    lam *= nu
                    nu *= cfg.lambda_increase_growth
                iterations += 1
                hit_max = iterations >= cfg.max_iterations
                phases["trial"] += time.perf_counter() - t3
            if new_cost < cost:
                lam *= cfg.lambda_decrease
                nu = cfg.lambda_increase_initial
                s.P, s.X = P_new, X_new
                accepted += 1
            s.outlier |= flagged
            s.use &= ~flagged
        # Nothing left to adjust (no measurements, or all of them outliers) is trivially converged.
        converged = converged or not (s.use.any() or aborted or failed)
        return {"iterations": iterations, "accepted": accepted, "converged": converged, "aborted": aborted,
                "hit_max_iterations": hit_max, "failed": failed}


class _LMState:
    """The compact problem's parameters and per-iteration work arrays."""

    def __init__(self, st: BundleStructure, P, X, uv, inv_sigma):
        kc, mc, nf = len(st.sel), len(st.pts), st.n_free
        self.st = st
        self.P = P.copy()
        self.X = X.copy()
        self.uv = uv
        self.inv_sigma = inv_sigma
        self.use = np.ones(kc, bool)
        self.outlier = np.zeros(kc, bool)
        self.err = np.zeros((kc, 2))
        self.e2 = np.zeros(kc)
        self.bad = np.zeros(kc, bool)
        self.live = np.zeros(kc, bool)
        self.U = np.zeros((nf, 6, 6))
        self.ea = np.zeros((nf, 6))
        self.V = np.zeros((mc, 3, 3))
        self.eb = np.zeros((mc, 3))
        self.W = np.zeros((kc, 6, 3))
        self.blocks = np.zeros((len(st.pair_rows), 6, 6))
        self.rhs = np.zeros(6 * nf)
        self.Vinv = np.zeros((mc, 3, 3))
        self.c2 = np.nan

    def summary(self, cam) -> dict:
        st = self.st
        everything = np.ones(len(st.sel), bool)
        ba_residuals(cam, self.P, self.X, st.mcam, st.mpt, self.uv, self.inv_sigma, everything, self.err,
                     self.e2, self.bad)
        inl = self.use & ~self.bad
        n_inl = int(inl.sum())
        c2 = self.c2 if np.isfinite(self.c2) else tukey_cutoff_sq(self.e2, everything, self.bad, 0.0)
        pts_with_inlier = np.unique(st.mpt[inl]).size
        return {"cost": float(ba_robust_cost(self.e2, self.bad, everything, c2)),
                "tukey_cutoff": float(np.sqrt(c2)),
                "inlier_rms": float(np.sqrt(self.e2[inl].sum() / (2 * n_inl))) if n_inl else float("nan"),
                "n_inliers": n_inl, "n_params": 6 * st.n_free + 3 * pts_with_inlier}
