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
  below ``converge_squared_update`` (an edgelet's update counted as the largest motion of its sample points that
  one of its measurements sees, ``EdgeletLM.squared_update``).
* Measurements with zero Tukey weight (or behind the camera) leave the problem for the rest of the run and
  are reported as outliers (PTAM §6.4 gives them a second chance).
* The abort flag is polled before every trial, so a request stops the solver within one iteration; the
  state returned is always the last accepted one, i.e. the best so far.

Edgelets (Agility §4.4), when given, are adjusted with the poses and points: 4-DOF blocks eliminated by the same
Schur complement, weighted by the same Tukey biweight (``bundle_edgelets``).

One deliberate difference: a trial's cost is compared on the measurements that were inliers when the step
was computed (the flagged ones score 1 on both sides); PTAM re-scores the flagged ones in the trial, which
can accept a step only because an outlier moved.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..camera.model import CameraModel
from ..config import BundleConfig
from ..edgelet import Edgelets
from ..errors import InputError
from ..geometry import se3
from .bundle_edgelets import EdgeletLM, plane_camera
from .bundle_gauge import ScaleGauge
from .bundle_inputs import EdgeletBundleInput, _checked_inputs, _Inputs
from .bundle_kernels import ba_linearise, ba_residuals, ba_robust_cost, cutoff_sq_of, gather_errors, tukey_cutoff_sq
from .bundle_schur_kernels import ba_backsub, ba_schur
from .bundle_structure import BundleStructure, ReducedSolver, build_structure, seen_twice

AbortFlag = threading.Event | Callable[[], bool] | None


@dataclass(frozen=True)
class BundleResult:
    poses: np.ndarray  # (N, 4, 4) T_cw; rows of fixed or unmeasured keyframes are the input, bit for bit
    points: np.ndarray  # (M, 3); rows of points not adjusted are the input, bit for bit
    iterations: int  # LM trials (PTAM's mnCounter)
    accepted: int  # accepted steps (PTAM's return value)
    converged: bool
    aborted: bool
    hit_max_iterations: bool
    failed: bool  # the reduced system could not be factorised (PTAM: the map is corrupt)
    cost: float  # PTAM's Tukey objective Σ (1 − (1 − e²/c²)³), outliers 1, at the returned state
    tukey_cutoff: float  # the last c, in σ-normalised px
    inlier_rms: float  # RMS per image coordinate of e/σ over the non-outlier measurements
    n_inliers: int
    n_params: int  # free parameters: 6 per adjusted keyframe + 3 per point with an inlier
    outliers: np.ndarray  # input indices of the measurements flagged as outliers (PTAM §6.4)
    phase_seconds: dict = field(default_factory=dict)
    # Agility §4.4, when edgelets were given: all of them (rows not adjusted are the input), the input indices of
    # their measurements flagged as outliers, and the edgelet measurements still in the problem at the end.
    edgelets: Edgelets | None = None
    edgelet_outliers: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    n_edgelet_inliers: int = 0

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


class Bundle:
    """PTAM's bundle adjuster for one camera model. ``adjust`` is re-entrant (no state between calls)."""

    def __init__(self, camera: CameraModel, cfg: BundleConfig) -> None:
        self.camera = camera
        self.cfg = cfg
        self._cam = np.ascontiguousarray(camera.kernel_params(), dtype=np.float64)
        self._plane = plane_camera(camera)  # where the edgelets' measured lines are taken (``bundle_edgelets``)

    def adjust(
        self,
        poses: ArrayLike,
        points: ArrayLike,
        meas_kf: ArrayLike,
        meas_pt: ArrayLike,
        meas_xy: ArrayLike,
        meas_level: ArrayLike,
        fixed_poses: ArrayLike,
        adjust_points: ArrayLike | None = None,
        abort: AbortFlag = None,
        edgelets: EdgeletBundleInput | None = None,
    ) -> BundleResult:
        """Adjust the non-fixed poses and the points in ``adjust_points`` (default all).

        poses (N, 4, 4) T_cw, points (M, 3); measurement k is point ``meas_pt[k]`` seen in keyframe
        ``meas_kf[k]`` at level-0 pixel ``meas_xy[k]``, found on pyramid level ``meas_level[k]``.
        Measurements of points outside ``adjust_points`` are not used (PTAM eq. 11). ``abort``: a
        ``threading.Event`` or a callable polled between LM iterations. ``edgelets``: edgelets adjusted with
        the poses and points (Agility §4.4), their measurements weighted by the same Tukey biweight.
        """
        t_start = time.perf_counter()
        inp = _checked_inputs(poses, points, meas_kf, meas_pt, meas_xy, meas_level, fixed_poses, adjust_points)
        should_abort = _abort_poller(abort)
        edg = None if edgelets is None else edgelets.checked(len(inp.poses))
        edg_meas = None if edg is None else (edg.obs.kf, edg.obs.edgelet, edg.adjust_mask)
        st = build_structure(inp.meas_kf, inp.meas_pt, inp.fixed_poses, inp.adjust_points, edg_meas)
        inv_sigma = np.ldexp(1.0, -inp.meas_level[st.sel])  # σ = 2^level px (PTAM §5.4)
        phases = {"setup": 0.0, "linearise": 0.0, "schur": 0.0, "solve": 0.0, "backsub": 0.0, "trial": 0.0}
        solver = ReducedSolver(st, dense=st.n_free <= self.cfg.dense_max_cameras)
        phases["setup"] = time.perf_counter() - t_start
        edg_lm = EdgeletLM((self._cam, self._plane), st, edg, inp.poses[st.cams])
        state = _LMState(st, inp.poses[st.cams], inp.points[st.pts], inp.meas_xy[st.sel], inv_sigma, edg_lm)
        state.gauge = ScaleGauge.of(st) if self.cfg.hold_scale and edg_lm.n else None  # points alone: PTAM's step
        status = self._levenberg_marquardt(state, solver, should_abort, phases)
        return self._result(inp, state, status, phases, t_start, edg)

    def _result(
        self,
        inp: _Inputs,
        s: _LMState,
        status: dict[str, Any],
        phases: dict[str, float],
        t_start: float,
        edg: EdgeletBundleInput | None,
    ) -> BundleResult:
        """The adjusted state written back into copies of the caller's poses and points, with the run's figures."""
        st = s.st
        out_poses = inp.poses.copy()
        free_cams = st.cams[st.free]
        out_poses[free_cams] = s.P[st.free]
        out_points = inp.points.copy()
        out_points[st.pts] = s.X
        summary = s.summary(self._cam)
        phases["total"] = time.perf_counter() - t_start
        return BundleResult(
            poses=out_poses,
            points=out_points,
            **status,
            **summary,
            outliers=np.sort(st.sel[s.outlier]),
            phase_seconds=phases,
            **s.edg.summary(s.P, edg, s.residuals_current),
        )

    def _levenberg_marquardt(
        self, s: _LMState, solver: ReducedSolver, should_abort: Callable[[], bool], phases: dict[str, float]
    ) -> dict[str, Any]:
        """PTAM's Bundle::Compute / Do_LM_Step loop; updates ``s`` in place and returns the status flags."""
        lm = _LMProgress(self.cfg)
        while not (lm.converged or lm.hit_max or lm.failed or lm.aborted) and s.any_use():
            if should_abort():
                lm.aborted = True
                break
            if self.cfg.hold_underdetermined:
                s.hold_underdetermined()
            cost = self._linearise(s, phases)
            flagged = s.use & ~s.live
            eflagged = s.edg.flag()
            n_flagged = float(flagged.sum()) + float(eflagged.sum()) if s.edg.n else float(flagged.sum())
            step = self._damped_step(s, solver, should_abort, phases, lm, cost, n_flagged)
            if step is not None:
                lm.accept()
                s.P, s.X, F = step
                s.edg.accept(F)
            s.residuals_current = step is not None  # the accepted trial's residuals cover every live measurement
            s.outlier |= flagged
            s.use &= ~flagged
            s.edg.retire(eflagged)
        # Nothing left to adjust (no measurements, or all of them outliers) is trivially converged.
        lm.converged = lm.converged or not (s.any_use() or lm.aborted or lm.failed)
        return lm.status()

    def _linearise(self, s: _LMState, phases: dict[str, float]) -> float:
        """Residuals at the current state, the Tukey cut-off re-estimated from them, and the normal equations'
        blocks; returns the cost (``s.live`` marks the measurements the Tukey weight keeps)."""
        cam, st = self._cam, s.st
        t = time.perf_counter()
        if not s.residuals_current:  # measurements in use are a subset of the accepted trial's, if any
            ba_residuals(cam, s.P, s.X, st.mcam, st.mpt, s.uv, s.inv_sigma, s.use, s.err, s.e2, s.bad)
        n = gather_errors(s.e2, s.use, s.bad, s.errs, 0)
        pooled = n == 0 or not self.cfg.tukey_from_points
        if pooled:  # the cut-off for both (``bundle_edgelets``)
            s.edg.residuals(s.P)
            n = gather_errors(s.edg.e2, s.edg.use, s.edg.bad, s.errs, n)
        s.c2 = c2 = cutoff_sq_of(s.errs, n, self.cfg.min_tukey_sigma)
        cost = ba_linearise(cam, s.P, s.X, st.mcam, st.mpt, s.uv, s.inv_sigma, s.use, c2, st.cam_row, *s.normal, s.live)
        cost += s.edg.linearise(s.P, c2, (s.U, s.ea), rows=not pooled)
        phases["linearise"] += time.perf_counter() - t
        return cost

    def _damped_step(
        self,
        s: _LMState,
        solver: ReducedSolver,
        should_abort: Callable[[], bool],
        phases: dict[str, float],
        lm: _LMProgress,
        cost: float,
        n_flagged: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None] | None:
        """Trial steps, raising λ after each rejected one, until one lowers ``cost`` or the run stops; returns
        the new (poses, points, edgelet frames) of the step that lowered it, else None."""
        cfg = self.cfg
        new_cost = np.inf
        trial: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None = None
        while new_cost > cost and not (lm.converged or lm.hit_max):
            if should_abort():
                lm.aborted = True
                break
            step = self._solve_step(s, solver, lm.lam, phases)
            if step is None:
                # With one fixed keyframe the scale gauge is free and only the damping keeps the reduced
                # system definite; after many good steps λ may be too small for it to factorise. That is a
                # rejected step, not a corrupt map: raise λ and try again (failed only past lambda_max).
                lm.reject()
                lm.count_trial()
                lm.failed = lm.lam > cfg.lambda_max
                if lm.failed:
                    break
                continue
            t = time.perf_counter()
            dcam, dpts, dedg = step
            sq = dcam @ dcam + np.vdot(dpts, dpts)  # the edgelets' share (≥ 0) only where it can decide
            if sq < cfg.converge_squared_update and sq + s.edg.squared_update(dedg) < cfg.converge_squared_update:
                lm.converged = True
            trial, new_cost = self._trial(s, step, n_flagged)
            if new_cost > cost:
                lm.reject()
            lm.count_trial()
            phases["trial"] += time.perf_counter() - t
        return trial if new_cost < cost else None

    def _solve_step(
        self, s: _LMState, solver: ReducedSolver, lam: float, phases: dict[str, float]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The damped step (pose updates μ of the free keyframes, point updates, edgelet updates) from the blocks
        linearised in ``s``: points and edgelets eliminated by the Schur complement; None when the reduced system
        does not factorise."""
        st = s.st
        t = time.perf_counter()
        ba_schur(*s.normal, s.live, lam, st.mrow, st.pt_start, st.order, st.pair_id, s.blocks, s.rhs, s.Vinv)
        s.edg.schur(lam, s.blocks, s.rhs)
        t1 = time.perf_counter()
        phases["schur"] += t1 - t
        try:
            if s.gauge is not None:
                dcam = s.gauge.step(solver, s.blocks, s.rhs, s.P, s.free_idx)
            else:
                dcam = solver.solve(s.blocks, s.rhs) if len(s.free_idx) else np.zeros(0)
        except np.linalg.LinAlgError:
            return None
        t2 = time.perf_counter()
        phases["solve"] += t2 - t1
        dpts = ba_backsub(s.Vinv, s.eb, s.A, s.B, s.live, st.mrow, st.pt_start, st.order, dcam)
        dedg = s.edg.backsub(dcam)
        phases["backsub"] += time.perf_counter() - t2
        return dcam, dpts, dedg

    def _trial(
        self, s: _LMState, step: tuple[np.ndarray, np.ndarray, np.ndarray], n_flagged: float
    ) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray | None], float]:
        """The (poses, points, edgelet frames) after the step and their cost on the measurements live at
        linearisation, the flagged ones scoring 1 each."""
        st = s.st
        dcam, dpts, dedg = step
        P_new = s.P.copy()
        P_new[s.free_idx] = se3.exp_left(dcam, s.P[s.free_idx])
        X_new = s.X + dpts
        ba_residuals(self._cam, P_new, X_new, st.mcam, st.mpt, s.uv, s.inv_sigma, s.live, s.err, s.e2, s.bad)
        F_new, edg_cost = s.edg.trial(P_new, dedg, s.c2)
        return (P_new, X_new, F_new), ba_robust_cost(s.e2, s.bad, s.live, s.c2) + edg_cost + n_flagged


@dataclass
class _LMProgress:
    """Levenberg–Marquardt's damping λ and its growth ν, the trial counters and the stop flags of one run."""

    cfg: BundleConfig
    lam: float = field(init=False)
    nu: float = field(init=False)
    iterations: int = 0
    accepted: int = 0
    converged: bool = False
    hit_max: bool = False
    aborted: bool = False
    failed: bool = False

    def __post_init__(self) -> None:
        self.lam, self.nu = self.cfg.lambda_initial, self.cfg.lambda_increase_initial

    def reject(self) -> None:
        self.lam *= self.nu
        self.nu *= self.cfg.lambda_increase_growth

    def accept(self) -> None:
        self.lam *= self.cfg.lambda_decrease
        self.nu = self.cfg.lambda_increase_initial
        self.accepted += 1

    def count_trial(self) -> None:
        self.iterations += 1
        self.hit_max = self.iterations >= self.cfg.max_iterations

    def status(self) -> dict[str, Any]:
        return {
            "iterations": self.iterations,
            "accepted": self.accepted,
            "converged": self.converged,
            "aborted": self.aborted,
            "hit_max_iterations": self.hit_max,
            "failed": self.failed,
        }


class _LMState:
    """The compact problem's parameters and per-iteration work arrays."""

    def __init__(self, st: BundleStructure, P, X, uv, inv_sigma, edg: EdgeletLM):
        kc, mc, nf = len(st.sel), len(st.pts), st.n_free
        self.st = st
        self.edg = edg
        self.free_idx = np.flatnonzero(st.free)
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
        self.U, self.ea = np.zeros((nf, 6, 6)), np.zeros((nf, 6))
        self.V, self.eb = np.zeros((mc, 3, 3)), np.zeros((mc, 3))
        self.A, self.B = np.zeros((kc, 2, 6)), np.zeros((kc, 2, 3))  # the weighted Jacobian rows, W = AᵀB
        self.blocks = np.zeros((len(st.pair_rows), 6, 6))
        self.rhs = np.zeros(6 * nf)
        self.Vinv = np.zeros((mc, 3, 3))
        self.errs = np.zeros(kc + edg.n)  # the squared errors the Tukey cut-off is taken from
        self.c2 = np.nan
        self.residuals_current = False  # err, e2, bad hold the points' residuals at (P, X) for every measurement in use
        self.gauge: ScaleGauge | None = None

    @property
    def normal(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The points' blocks U, ε_a, V, ε_b and weighted rows A, B, in the kernels' argument order."""
        return self.U, self.ea, self.V, self.eb, self.A, self.B

    def hold_underdetermined(self) -> None:
        """Points (and edgelets) left with fewer than two measurements in the problem are held where they are: one
        measurement fixes no depth, and LM's steps, damped per parameter, slide such a point along its ray by
        amounts that grow as λ falls (1.7 mm per iteration up to the iteration limit on a desk_table global BA while
        edgelets still moved the scale). Their measurements leave the problem without being outliers. Edgelets are
        also held in §4.3's aperture problem (``EdgeletLM.hold_underdetermined``)."""
        self.use &= seen_twice(self.st.mpt, self.use, len(self.st.pts))
        self.edg.hold_underdetermined()

    def any_use(self) -> bool:
        return bool(self.use.any() or self.edg.use.any())

    def summary(self, cam) -> dict:
        st = self.st
        everything = np.ones(len(st.sel), bool)
        ba_residuals(
            cam, self.P, self.X, st.mcam, st.mpt, self.uv, self.inv_sigma, everything, self.err, self.e2, self.bad
        )
        inl = self.use & ~self.bad
        n_inl = int(inl.sum())
        c2 = self.c2 if np.isfinite(self.c2) else tukey_cutoff_sq(self.e2, everything, self.bad, 0.0)
        pts_with_inlier = int(np.count_nonzero(np.bincount(st.mpt[inl], minlength=len(st.pts))))
        return {
            "cost": float(ba_robust_cost(self.e2, self.bad, everything, c2)),
            "tukey_cutoff": float(np.sqrt(c2)),
            "inlier_rms": float(np.sqrt(self.e2[inl].sum() / (2 * n_inl))) if n_inl else float("nan"),
            "n_inliers": n_inl,
            "n_params": 6 * st.n_free + 3 * pts_with_inlier,
        }
