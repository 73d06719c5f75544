"""Bundle adjustment's free scale held inside each LM step (``mapping/bundle_gauge.py``) and landmarks left with one
measurement held (``bundle.hold_underdetermined``), against synthetic truth."""

import dataclasses

import numpy as np

from ptam.config import default_config
from ptam.edgelet.edgelet_ba import EdgeletObservations
from ptam.geometry import se3
from ptam.map.snapshot import camera_centres
from ptam.mapping.bundle import Bundle
from ptam.mapping.bundle_gauge import ScaleGauge
from ptam.mapping.bundle_inputs import EdgeletBundleInput
from ptam.mapping.bundle_solve_kernels import scale_direction
from ptam.mapping.bundle_structure import ReducedSolver, build_structure
from tests.support.ba_problems import synthetic_edgelets, synthetic_workspace_problem

CFG = default_config()


def _scaled_about(T, c0, s):
    """The poses with every centre moved to c0 + s (C − c0), orientations kept."""
    out = T.copy()
    C = camera_centres(T)
    out[:, :3, 3] = -np.einsum("nij,nj->ni", T[:, :3, :3], c0 + s * (C - c0))
    return out


def test_direction_is_the_keyframes_scaling_about_the_fixed_one():
    rng = np.random.default_rng(0)
    P = se3.exp(np.concatenate([rng.normal(0, 0.5, (6, 3)), rng.normal(0, 0.3, (6, 3))], axis=1))
    free = np.array([0, 1, 3, 4, 5])
    g = scale_direction(P, 2, free).reshape(-1, 6)
    eps = 1e-6
    moved = _scaled_about(P, camera_centres(P[2:3])[0], 1.0 + eps)
    # T ← exp(μ) T with μ = (v, 0) moves the translation by v.
    assert np.allclose(g[:, :3], (moved[free, :3, 3] - P[free, :3, 3]) / eps, atol=1e-6)
    assert not g[:, 3:].any()


def test_the_step_is_the_damped_models_best_that_does_not_scale_the_keyframes():
    """ScaleGauge.step against the KKT system [S g; gᵀ 0] of min ½δᵀSδ − bᵀδ subject to gᵀδ = 0, on a
    reduced system of a real problem (both solvers)."""
    prob = synthetic_workspace_problem(6, 150, seed=3, outlier_fraction=0.0)
    fixed = np.zeros(6, bool)
    fixed[0] = True
    st = build_structure(prob.meas_kf, prob.meas_pt, fixed, np.ones(len(prob.points_true), bool))
    gauge = ScaleGauge.of(st)
    assert gauge is not None and gauge.fixed == 0
    rng = np.random.default_rng(4)
    n = 6 * st.n_free
    A = rng.normal(size=(n, n))
    S = A @ A.T + n * np.eye(n)
    rows, cols = st.pair_rows, st.pair_cols
    blocks = np.stack([S[6 * r : 6 * r + 6, 6 * c : 6 * c + 6] for r, c in zip(rows, cols)])
    for r in range(st.n_free):  # S as the structure stores it: blocks only where keyframes share a point
        for c in range(st.n_free):
            if r != c and not np.any((rows == max(r, c)) & (cols == min(r, c))):
                S[6 * r : 6 * r + 6, 6 * c : 6 * c + 6] = 0.0
    b = rng.normal(size=n)
    P, free = prob.poses_true[st.cams], np.flatnonzero(st.free)
    g = scale_direction(P, gauge.fixed, free)
    kkt = np.block([[S, g[:, None]], [g[None, :], np.zeros((1, 1))]])
    want = np.linalg.solve(kkt, np.r_[b, 0.0])[:n]
    for dense in (True, False):
        x = gauge.step(ReducedSolver(st, dense=dense), blocks, b, P, free)
        assert abs(g @ x) < 1e-12 * np.linalg.norm(g) * np.linalg.norm(x)
        assert np.allclose(x, want, rtol=1e-9, atol=1e-12)
    # Two fixed keyframes fix the scale: no gauge.
    fixed[1] = True
    assert ScaleGauge.of(build_structure(prob.meas_kf, prob.meas_pt, fixed, np.ones(150, bool))) is None


def _keyframe_scale(T, T_start):
    C, C0 = camera_centres(T), camera_centres(T_start)
    return float(np.median(np.linalg.norm(C[1:] - C[0], axis=1) / np.linalg.norm(C0[1:] - C0[0], axis=1)))


def test_edgelets_do_not_scale_a_converged_map():
    """Global BA (one keyframe fixed) from the truth with noisy measurements and a tight convergence test, so that
    λ falls far: edgelets' 4-DOF linearisation has a gradient along the free scale, and the unconstrained steps
    scaled the keyframes by 0.24 % (measured); held, 0.005 %. Points alone move it 0.02-0.03 % either way."""
    prob = synthetic_workspace_problem(10, 400, seed=7, outlier_fraction=0.0)
    eb = synthetic_edgelets(prob, 150, seed=8, gross_fraction=0.0)
    fixed = np.zeros(10, bool)
    fixed[0] = True
    edg = EdgeletBundleInput(eb.truth, eb.obs, CFG.edgelets)
    meas = (prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, fixed)
    scale = {}
    for hold in (True, False):
        cfg = dataclasses.replace(CFG.bundle, hold_scale=hold, max_iterations=60, converge_squared_update=1e-12)
        res = Bundle(prob.camera, cfg).adjust(prob.poses_true, prob.points_true, *meas, edgelets=edg)
        assert res.converged and not res.failed
        scale[hold] = _keyframe_scale(res.poses, prob.poses_true)
    assert abs(scale[True] - 1.0) < 1e-4
    assert abs(scale[False] - 1.0) > 1e-3


def test_a_landmark_seen_once_is_held():
    """One measurement fixes no depth: the point (and an edgelet measured once) stays where it is, and its
    measurement is neither an inlier nor an outlier."""
    prob = synthetic_workspace_problem(10, 400, seed=7, outlier_fraction=0.0)
    eb = synthetic_edgelets(prob, 150, seed=8, gross_fraction=0.0)
    p, e = 17, 5
    keep = (prob.meas_pt != p) | (np.arange(len(prob.meas_pt)) == np.flatnonzero(prob.meas_pt == p)[0])
    xy = prob.meas_xy + 0.5  # every measurement half a pixel off, so that the map must move
    ekeep = (eb.obs.edgelet != e) | (np.arange(len(eb.obs.kf)) == np.flatnonzero(eb.obs.edgelet == e)[0])
    obs = EdgeletObservations(eb.obs.kf[ekeep], eb.obs.edgelet[ekeep], eb.obs.a[ekeep] + 0.5, eb.obs.b[ekeep])
    fixed = np.zeros(10, bool)
    fixed[:2] = True
    args = (prob.meas_kf[keep], prob.meas_pt[keep], xy[keep], prob.meas_level[keep], fixed)
    for hold in (True, False):
        cfg = dataclasses.replace(CFG.bundle, hold_underdetermined=hold)
        edg = EdgeletBundleInput(eb.truth, obs, CFG.edgelets)
        res = Bundle(prob.camera, cfg).adjust(prob.poses_true, prob.points_true, *args, edgelets=edg)
        moved = (
            np.linalg.norm(res.points[p] - prob.points_true[p]),
            np.linalg.norm(res.edgelets.centre[e] - eb.truth.centre[e]),
        )
        if hold:
            assert moved == (0.0, 0.0) and len(res.outliers) == len(res.edgelet_outliers) == 0
            once = np.bincount(prob.meas_pt[keep]) == 1  # p, and one point the problem itself sees once
            e_once = np.bincount(obs.edgelet) == 1
            assert once.sum() == 2 and np.array_equal(res.points[once], prob.points_true[once])
            assert res.n_inliers == keep.sum() - once.sum() and res.n_edgelet_inliers == ekeep.sum() - e_once.sum()
        else:
            assert moved[0] > 1e-3 and moved[1] > 0.0  # fitted to the one offset measurement
