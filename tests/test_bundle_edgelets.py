"""Agility §4.4: edgelets in PTAM's bundle adjustment (4-DOF blocks eliminated by the Schur complement like
points, one Tukey biweight for both), against numpy references and on synthetic maps with known truth."""

import numpy as np
import pytest

from ptam.camera.camproj_kernels import UNDISTORT_ITERS, UNDISTORT_TOL
from ptam.camera.radtan import RadTanCamera
from ptam.config import default_config
from ptam.edgelet import EdgeletObservations, Edgelets, perp, project_edgelets, sample_along
from ptam.edgelet.edgelet_ba_kernels import edgelet_ba_terms, frames_of, frames_updated
from ptam.geometry import so3
from ptam.map.snapshot import camera_centres
from ptam.mapping import bundle_edgelet_kernels as EK
from ptam.mapping import bundle_kernels as K
from ptam.mapping import bundle_schur_kernels as SK
from ptam.mapping.bundle import Bundle
from ptam.mapping.bundle_edgelets import plane_camera
from ptam.mapping.bundle_inputs import EdgeletBundleInput
from ptam.mapping.bundle_structure import build_structure
from tests.reference import bundle as R
from tests.reference import bundle_edgelets as RE
from tests.reference.edgelet_ba import edgelet_ba_terms_ref, edgelets_updated_ref
from tests.support.ba_problems import edgelet_errors, synthetic_edgelets, synthetic_workspace_problem

CFG = default_config()


@pytest.fixture(scope="module")
def problem():
    # 10 keyframes on a 90° arc, 400 points (5% gross outliers), 150 edgelets (3% of their measurements 25 px
    # off); poses start 2 cm / 1° off, points 5 cm, edgelets 3 cm / 3°.
    prob = synthetic_workspace_problem(10, 400, seed=5, outlier_fraction=0.05)
    return prob, synthetic_edgelets(prob, 150, seed=6, gross_fraction=0.03)


def close(a, b, rel=1e-9):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.allclose(a, b, rtol=rel, atol=rel * max(np.abs(b).max(initial=0.0), 1e-300))


def assemble(blocks, rows, cols, n_free):
    S = np.zeros((6 * n_free, 6 * n_free))
    for B, r, c in zip(blocks, rows, cols):
        S[6 * r : 6 * r + 6, 6 * c : 6 * c + 6] = B
        S[6 * c : 6 * c + 6, 6 * r : 6 * r + 6] = B.T
    return S


def run(problem, n_fixed=2, points=True, edgelets=True, start="init"):
    prob, eb = problem
    fixed = np.zeros(len(prob.poses_true), bool)
    fixed[:n_fixed] = True
    poses = (prob.poses_init if start == "init" else prob.poses_true).copy()
    poses[fixed] = prob.poses_true[fixed]
    pts = prob.points_init if start == "init" else prob.points_true
    ein = EdgeletBundleInput(eb.init if start == "init" else eb.truth, eb.obs, CFG.edgelets) if edgelets else None
    adjust = np.full(len(pts), points)
    return Bundle(prob.camera, CFG.bundle).adjust(
        poses, pts, prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, fixed, adjust, edgelets=ein
    )


def pose_errors(T, T_true):
    """Worst camera-centre (mm) and rotation (deg) error; two keyframes fixed at the truth fix the gauge."""
    dc = 1e3 * np.linalg.norm(camera_centres(T) - camera_centres(T_true), axis=1)
    dr = np.degrees(np.linalg.norm(so3.log(T[:, :3, :3] @ np.swapaxes(T_true[:, :3, :3], 1, 2)), axis=1))
    return dc.max(), dr.max()


def test_points_and_edgelets_converge_to_truth(problem):
    prob, eb = problem
    assert pose_errors(prob.poses_init[2:], prob.poses_true[2:]) == pytest.approx((20.0, 1.0), rel=1e-3)
    d0, a0 = edgelet_errors(eb.init, eb.truth)
    assert np.median(d0) > 15.0 and np.median(a0) > 1.5
    res = run(problem)
    assert res.converged and not (res.failed or res.aborted)
    dc, dr = pose_errors(res.poses, prob.poses_true)
    assert dc < 7.0 and dr < 0.1
    d, a = edgelet_errors(res.edgelets, eb.truth)
    # 0.5 px / 2° line noise at 3 m (f = 384 px: 1 px is 8 mm across): measured median 2.6 mm / 1.0°.
    assert np.median(d) < 3.5 and np.median(a) < 1.3
    assert np.percentile(d, 90) < 9.0 and np.percentile(a, 90) < 4.0
    # The solver reaches the estimator's optimum: started at the truth it ends at the same state, up to the
    # convergence threshold, for all but the least determined edgelets (measured: median 0.03 mm, worst 1 mm).
    ref = run(problem, start="truth")
    assert pose_errors(res.poses, ref.poses)[0] < 0.2
    d_ref, a_ref = edgelet_errors(res.edgelets, ref.edgelets)
    assert np.median(d_ref) < 0.05 and np.percentile(d_ref, 90) < 0.1 and np.percentile(a_ref, 90) < 0.01


def test_edgelets_alone_pull_the_keyframes_back(problem):
    """No point measurements at all: the pose Jacobians of the perpendicular distances (eq. 8) carry the poses."""
    prob, _ = problem
    res = run(problem, points=False)
    assert res.converged and res.n_inliers == 0
    dc, dr = pose_errors(res.poses, prob.poses_true)
    assert dc < 10.0 and dr < 0.15


def test_outlier_edgelet_measurements_are_flagged(problem):
    _, eb = problem
    res = run(problem)
    flagged = np.zeros(len(eb.gross), bool)
    flagged[res.edgelet_outliers] = True
    assert eb.gross.sum() >= 30
    assert (flagged & eb.gross).sum() == eb.gross.sum()
    assert (flagged & ~eb.gross).sum() <= 0.002 * (~eb.gross).sum()
    assert res.n_edgelet_inliers == (~flagged).sum()


def test_without_edgelets_the_result_is_the_points_only_one(problem):
    """An empty edgelet input changes nothing, bit for bit."""
    prob, eb = problem
    a = run(problem, edgelets=False)
    none = EdgeletBundleInput(eb.init, eb.obs, CFG.edgelets, adjust=np.zeros(len(eb.init), bool))
    fixed = np.zeros(len(prob.poses_true), bool)
    fixed[:2] = True
    poses = prob.poses_init.copy()
    poses[fixed] = prob.poses_true[fixed]
    b = Bundle(prob.camera, CFG.bundle).adjust(
        poses, prob.points_init, prob.meas_kf, prob.meas_pt, prob.meas_xy, prob.meas_level, fixed, edgelets=none
    )
    assert np.array_equal(a.poses, b.poses) and np.array_equal(a.points, b.points)
    assert np.array_equal(a.outliers, b.outliers) and a.iterations == b.iterations
    assert np.array_equal(b.edgelets.centre, eb.init.centre) and len(b.edgelet_outliers) == 0


def _image_plane(n):
    """``to_px`` for lines measured in the image itself: the identity."""
    return np.repeat(np.eye(2)[None], n, axis=0)


def _linearised(problem):
    """The inputs of the edgelet kernels at the perturbed start, 3 of 10 keyframes fixed, 5 edgelets not adjusted,
    10 % of the measurements not in use; the per-measurement terms ``ba_edgelet_rows`` computes there (err, jp, je,
    along) and the numpy reference's residuals and Jacobians at the numpy sample points (``sample_along``)."""
    prob, eb = problem
    fixed = np.zeros(len(prob.poses_true), bool)
    fixed[[0, 4, 7]] = True
    adjust_e = np.ones(len(eb.init), bool)
    adjust_e[:5] = False
    edgelet_meas = (eb.obs.kf, eb.obs.edgelet, adjust_e)
    st = build_structure(prob.meas_kf, prob.meas_pt, fixed, np.ones(len(prob.points_true), bool), edgelet_meas)
    es = st.edgelets
    P, cam = prob.poses_init[st.cams], prob.camera
    ed = eb.init.subset(es.ids)
    obs = type(eb.obs)(es.mcam, es.medg, eb.obs.a[es.sel], eb.obs.b[es.sel])
    along_ref = sample_along(cam, P, ed, obs, CFG.edgelets)
    m_hat = perp(obs.b)
    use = np.random.default_rng(1).random(len(es.sel)) < 0.9
    n = len(use)
    err, e2, bad = np.empty((n, 2)), np.empty(n), np.empty(n, bool)
    jp, je, along = np.full((n, 2, 6), 7.0), np.full((n, 2, 4), 7.0), np.empty((n, 2))
    meas = (es.mcam, es.medg, obs.a, m_hat)
    offset = CFG.edgelets.ba_sample_offset_px
    EK.ba_edgelet_place(cam.kernel_params(), P, ed.frames(), es.mcam, es.medg, offset, _image_plane(n), along)
    EK.ba_edgelet_rows(cam.kernel_params(), P, ed.frames(), meas, use, along, err, jp, je, e2, bad)
    ref = edgelet_ba_terms_ref(cam, P, ed.frames(), es.mcam, es.medg, obs.a, m_hat, along_ref)
    c2 = float(np.median(e2[use])) * 9.0
    rows = (err, jp, je, along, along_ref)
    return st, (cam.kernel_params(), P, ed.frames(), meas, use, e2, bad, c2), rows, ref


def test_rows_kernel_matches_reference(problem):
    """Sample points (eq. 6), residuals (eq. 7) and Jacobian rows (eq. 8–9) of one linearisation pass against the
    numpy ``sample_along`` and ``edgelet_ba_terms_ref``."""
    st, (_, _, _, _, use, e2, bad, _), (err, jp, je, along, along_ref), (r_err, r_Jp, r_Je, r_valid) = _linearised(
        problem
    )
    assert close(along, along_ref, 1e-12) and np.all(along[:, 0] < 0) and np.all(along[:, 1] == -along[:, 0])
    assert np.array_equal(bad, use & ~r_valid) and r_valid.sum() > 0.9 * len(r_valid)
    ok = use & r_valid
    assert close(err[ok], r_err[ok]) and not err[~use].any() and close(e2, np.where(ok, np.sum(r_err**2, 1), 0.0))
    assert close(jp[ok], r_Jp[ok]) and close(je[ok], r_Je[ok])


@pytest.fixture(scope="module")
def radtan_problem():
    """The workspace of ``problem`` through a radial-tangential lens with a barrel like ω = 0.9's (the image
    corners at normalised radius 1.29 against the FOV lens's 1.41 and 1.04 undistorted)."""
    cam = RadTanCamera(640, 480, 384.0, 384.0, 319.5, 239.5, -0.2, 0.05, 1e-3, -1e-3, 0.0)
    prob = synthetic_workspace_problem(10, 400, seed=5, camera=cam, outlier_fraction=0.05)
    return prob, synthetic_edgelets(prob, 150, seed=6, gross_fraction=0.03)


def lens_linearised(camera, a, b):
    """The measured lines moved to the normalised plane as ``EdgeletLM`` moves them: its camera, xy, g, to_px."""
    m = len(a)
    xy, g, to_px = np.empty((m, 2)), np.empty((m, 2)), np.empty((m, 2, 2))
    EK.ba_edgelet_planes(camera.kernel_params(), a, b, UNDISTORT_ITERS, UNDISTORT_TOL, xy, g, to_px)
    return plane_camera(camera), xy, g, to_px


@pytest.mark.parametrize("lens", ["problem", "radtan_problem"])
def test_lens_linearised_kernel_matches_numpy(lens, request):
    """``ba_edgelet_planes`` against the numpy reference (the lens's own unproject and Jacobian): the FOV lens's
    closed-form inverse and the kernel's Gauss–Newton agree to 1e-12 of a normalised unit, out to the corners."""
    prob, eb = request.getfixturevalue(lens)
    obs = eb.obs
    plane, xy, g, to_px = lens_linearised(prob.camera, obs.a, obs.b)
    r_xy, r_g, r_to_px = RE.lens_linearised_ref(prob.camera, obs.a, obs.b)
    assert len(xy) == len(eb.obs.kf) > 100
    assert np.abs(xy - r_xy).max() < 1e-12
    assert np.abs(to_px - r_to_px).max() < 1e-9 * np.abs(r_to_px).max()
    assert np.abs(g - r_g).max() < 1e-9 * np.abs(r_g).max()
    assert plane[1] == plane[2] == 1.0 and plane[10] == prob.camera.max_radius


def test_setup_kernel_is_the_three_start_kernels(problem):
    """``ba_edgelet_setup``, one call at an adjustment's start, gives what ``ba_edgelet_planes``,
    ``ba_edgelet_plane_angles`` and ``ba_edgelet_place`` give one by one (each against numpy elsewhere here)."""
    prob, eb = problem
    cam, obs, P, F = prob.camera, eb.obs, prob.poses_init, eb.init.frames()
    off, n = CFG.edgelets.ba_sample_offset_px, len(eb.obs.kf)
    plane, xy, g, to_px = lens_linearised(cam, obs.a, obs.b)
    angle, along = np.empty(n), np.empty((n, 2))
    EK.ba_edgelet_plane_angles(P, F, obs.kf, obs.edgelet, angle)
    EK.ba_edgelet_place(plane, P, F, obs.kf, obs.edgelet, off, to_px, along)
    lines = (obs.a, obs.b, np.arange(n))
    got = EK.ba_edgelet_setup(
        cam.kernel_params(), plane, P, F, obs.kf, obs.edgelet, lines, UNDISTORT_ITERS, UNDISTORT_TOL, off
    )
    assert np.isfinite(angle).sum() > 0.95 * n and np.all(along[:, 1] > 0.0)
    for a, b in zip(got, (xy, g, to_px, angle, along), strict=True):
        assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("lens", ["problem", "radtan_problem"])
def test_lines_moved_to_the_normalised_plane_keep_their_pixel_distances(lens, request):
    """``lens_linearised``: at the true poses and edgelets (FOV lens, ω = 0.9, or radial-tangential; measurements
    out to the image corners) the plane's sample points, residuals and Jacobian rows are the image's to first order
    in the sample points' distance from the measured point (5 px from the projected centres, which lie 1.5 px from
    it, 3.2 px at most): distances within 0.05 px (the lines' noise: 0.5 px), rows within 2 %."""
    prob, eb = request.getfixturevalue(lens)
    cam, P, F, off = prob.camera, prob.poses_true, eb.truth.frames(), CFG.edgelets.ba_sample_offset_px
    obs, n = eb.obs, len(eb.obs.kf)
    m_hat = perp(obs.b / np.linalg.norm(obs.b, axis=1, keepdims=True))

    def terms(kernel_cam, a, normal, to_px):
        along, err, e2, bad = np.empty((n, 2)), np.empty((n, 2)), np.empty(n), np.empty(n, bool)
        jp, je = np.zeros((n, 2, 6)), np.zeros((n, 2, 4))
        EK.ba_edgelet_place(kernel_cam, P, F, obs.kf, obs.edgelet, off, to_px, along)
        meas = (obs.kf, obs.edgelet, a, normal)
        EK.ba_edgelet_rows(kernel_cam, P, F, meas, np.ones(n, bool), along, err, jp, je, e2, bad)
        return along, err, jp, je, bad

    image = terms(cam.kernel_params(), obs.a, m_hat, _image_plane(n))
    plane = terms(*lens_linearised(cam, obs.a, obs.b))
    ok = ~image[4] & ~eb.gross
    assert np.array_equal(plane[4], image[4]) and ok.sum() > 0.95 * n
    assert np.abs(plane[0][ok] / image[0][ok] - 1.0).max() < 0.02
    assert np.abs(plane[1] - image[1])[ok].max() < 0.05
    for p_rows, i_rows in zip(plane[2:4], image[2:4]):
        rel = np.linalg.norm(p_rows[ok] - i_rows[ok], axis=2) / np.linalg.norm(i_rows[ok], axis=2)
        assert rel.max() < 0.02


def _image_offsets(camera, poses, ed, mcam, medg, z):
    """The image distances (M, 2) of the sample points at E-frame ∓z from the projected centre."""
    T, c, d = poses[mcam], ed.centre[medg], ed.direction[medg]
    uv = [
        camera.project(np.einsum("mij,mj->mi", T[:, :3, :3], c + s * z[:, None] * d) + T[:, :3, 3])
        for s in (-1.0, 0.0, 1.0)
    ]
    return np.stack([np.linalg.norm(uv[0] - uv[1], axis=1), np.linalg.norm(uv[2] - uv[1], axis=1)], axis=1)


def test_residuals_kernel_matches_reference(problem):
    """The trial steps' residuals at the linearisation's sample points, and the sample points re-placed from their
    projections (eq. 6 with the chord for |d|) at another state: 5 px from the projected centre on average within
    0.5 px for every measurement (the numpy tangent ``sample_along``: 1.35 px; both are first-order placements,
    apart for edgelets that point at the camera) and within 0.01 px for 99 % of them."""
    prob, eb = problem
    st, (cam, P, F, meas, use, _, _, _), (_, _, _, along, _), (r_err, _, _, r_valid) = _linearised(problem)
    n = len(use)
    err, e2, bad, placed = np.empty((n, 2)), np.empty(n), np.empty(n, bool), np.empty((n, 2))
    offset = CFG.edgelets.ba_sample_offset_px
    EK.ba_edgelet_residuals(cam, P, F, meas, along, offset, _image_plane(n), use, err, e2, bad, placed)
    assert np.array_equal(bad, use & ~r_valid)
    ok = use & r_valid
    assert close(err[ok], r_err[ok]) and not err[~use].any() and close(e2, np.where(ok, np.sum(r_err**2, 1), 0.0))
    assert np.array_equal(placed[~ok], along[~ok])
    es = st.edgelets
    P_true = prob.poses_true[st.cams]
    EK.ba_edgelet_residuals(cam, P_true, F, meas, along, offset, _image_plane(n), use, err, e2, bad, placed)
    ed = eb.init.subset(es.ids)
    moved = use & ~bad
    dev = np.abs(_image_offsets(prob.camera, P_true, ed, es.mcam, es.medg, placed[:, 1]).mean(axis=1) - offset)[moved]
    before = np.abs(_image_offsets(prob.camera, P_true, ed, es.mcam, es.medg, along[:, 1]).mean(axis=1) - offset)
    assert dev.max() < 0.5 and np.percentile(dev, 99) < 0.01 and before[moved].max() > 1.0


def test_one_call_kernels_are_their_parts(problem):
    """``ba_edgelet_linearise_at`` and ``ba_edgelet_trial`` (one call each per LM iteration) give exactly what their
    parts give called one by one: ``ba_edgelet_rows``, ``ba_edgelet_linearise`` and the robust cost; and
    ``frames_updated``, ``ba_edgelet_residuals`` and the robust cost (each part against numpy elsewhere here)."""
    st, (cam, P, F, meas, use, _, _, c2), (_, _, _, along, _), _ = _linearised(problem)
    es, nf, ne, n = st.edgelets, st.n_free, len(st.edgelets.ids), len(use)

    def terms():
        return np.zeros((n, 2)), np.zeros((n, 2, 6)), np.zeros((n, 2, 4)), np.zeros(n), np.zeros(n, bool)

    def normal():
        return tuple(np.zeros(s) for s in ((nf, 6, 6), (nf, 6), (ne, 4, 4), (ne, 4), (n, 2, 6), (n, 2, 4)))

    parts, p_normal, p_live = terms(), normal(), np.zeros(n, bool)
    EK.ba_edgelet_rows(cam, P, F, meas, use, along, *parts)
    EK.ba_edgelet_linearise(*parts, use, c2, es.medg, es.mrow, *p_normal, p_live)
    p_cost = K.ba_robust_cost(parts[3], parts[4], use, c2)
    one, o_normal, o_live = terms(), normal(), np.zeros(n, bool)
    o_cost = EK.ba_edgelet_linearise_at(cam, P, F, meas, along, True, one, use, c2, es.mrow, o_normal, o_live)
    assert 0 < p_live.sum() < use.sum() and p_cost > 0.0 and o_cost == p_cost and np.array_equal(o_live, p_live)
    for a, b in zip(one + o_normal, parts + p_normal, strict=True):
        assert np.array_equal(a, b)

    de = np.random.default_rng(4).normal(0.0, [0.01, 0.01, 0.02, 0.02], (ne, 4))
    F_parts = np.empty_like(F)
    frames_updated(F, de, F_parts)
    r_parts = (np.zeros((n, 2)), np.zeros(n), np.zeros(n, bool), np.zeros((n, 2)))
    offset, to_px = CFG.edgelets.ba_sample_offset_px, _image_plane(n)
    EK.ba_edgelet_residuals(cam, P, F_parts, meas, along, offset, to_px, p_live, *r_parts)
    cost = K.ba_robust_cost(r_parts[1], r_parts[2], p_live, c2)
    r_one = (np.zeros((n, 2)), np.zeros(n), np.zeros(n, bool), np.zeros((n, 2)))
    F_one, cost_one = EK.ba_edgelet_trial(cam, P, F, de, meas, along, offset, to_px, p_live, r_one, c2)
    assert cost_one == cost > 0.0 and np.array_equal(F_one, F_parts) and not np.array_equal(F_one, F)
    for a, b in zip(r_one, r_parts, strict=True):
        assert np.array_equal(a, b)


def test_kernels_match_reference(problem):
    st, args, (err, jp, je, _, _), (r_err, r_Jp, r_Je, _) = _linearised(problem)
    cam, P, F, meas, use, e2, bad, c2 = args
    es, nf, ne = st.edgelets, st.n_free, len(st.edgelets.ids)
    U0 = np.random.default_rng(2).normal(size=(nf, 6, 6))
    U0 = U0 + U0.transpose(0, 2, 1)  # the points' U: symmetric
    U, ea = U0.copy(), np.ones((nf, 6))
    V, eb, live = np.empty((ne, 4, 4)), np.empty((ne, 4)), np.empty(len(use), bool)
    A, B = np.full((len(use), 2, 6), 7.0), np.full((len(use), 2, 4), 7.0)
    EK.ba_edgelet_linearise(err, jp, je, e2, bad, use, c2, es.medg, es.mrow, U, ea, V, eb, A, B, live)
    rU, rea, rV, reb, rW, rlive = RE.ba_edgelet_linearise_ref(
        r_err, r_Jp, r_Je, e2, bad, use, c2, es.mrow, es.medg, nf, ne
    )
    assert np.array_equal(live, rlive) and 0 < live.sum() < use.sum()
    W = R.w_blocks(A, B, live, es.mrow)
    assert close(U - U0, rU) and close(ea - 1.0, rea) and close(V, rV) and close(eb, reb) and close(W, rW)

    V[0] = 0.0  # an edgelet without live measurements: V* is singular and the edgelet stays where it is
    lam = 1e-3
    blocks, rhs, Vinv = np.zeros((len(st.pair_rows), 6, 6)), np.zeros(6 * nf), np.empty_like(V)
    SK.ba_edgelet_schur(V, eb, A, B, live, lam, es.mrow, es.e_start, es.order, es.pair_id, blocks, rhs, Vinv)
    rS, rrhs, rVinv = RE.ba_edgelet_schur_ref(V, eb, W, live, lam, es.mrow, es.medg, nf)
    assert close(assemble(blocks, st.pair_rows, st.pair_cols, nf), rS) and close(rhs, rrhs) and close(Vinv, rVinv)
    assert not Vinv[0].any()
    dcam = np.random.default_rng(3).normal(size=6 * nf)
    de = SK.ba_backsub(Vinv, eb, A, B, live, es.mrow, es.e_start, es.order, dcam)
    assert close(de, RE.ba_edgelet_backsub_ref(Vinv, eb, W, live, es.mrow, es.medg, dcam))


def test_one_walk_numbers_the_pairs_of_points_and_edgelets(problem):
    """The reduced system of points and edgelets together is the sum of the two references'."""
    prob, _ = problem
    st, args, rows, _ = _linearised(problem)
    cam_p, P, F, meas, use, e2, bad, c2 = args
    es, nf, ne, m = st.edgelets, st.n_free, len(st.edgelets.ids), len(st.pts)
    X = prob.points_init[st.pts]
    k = len(st.sel)
    inv_sigma = np.ldexp(1.0, -prob.meas_level[st.sel])
    U, ea, V, eb = np.empty((nf, 6, 6)), np.empty((nf, 6)), np.empty((m, 3, 3)), np.empty((m, 3))
    Ap, Bp, live = np.zeros((k, 2, 6)), np.zeros((k, 2, 3)), np.empty(k, bool)
    uv, every = prob.meas_xy[st.sel], np.ones(k, bool)
    K.ba_linearise(cam_p, P, X, st.mcam, st.mpt, uv, inv_sigma, every, 1e6, st.cam_row, U, ea, V, eb, Ap, Bp, live)
    Ve, ebe, livee = np.empty((ne, 4, 4)), np.empty((ne, 4)), np.empty(len(use), bool)
    Ae, Be = np.zeros((len(use), 2, 6)), np.zeros((len(use), 2, 4))
    err, jp, je = rows[:3]
    EK.ba_edgelet_linearise(err, jp, je, e2, bad, use, c2, es.medg, es.mrow, U, ea, Ve, ebe, Ae, Be, livee)
    lam = 1e-2
    blocks, rhs = np.empty((len(st.pair_rows), 6, 6)), np.empty(6 * nf)
    SK.ba_schur(
        U, ea, V, eb, Ap, Bp, live, lam, st.mrow, st.pt_start, st.order, st.pair_id, blocks, rhs, np.empty_like(V)
    )
    SK.ba_edgelet_schur(
        Ve, ebe, Ae, Be, livee, lam, es.mrow, es.e_start, es.order, es.pair_id, blocks, rhs, np.empty_like(Ve)
    )
    pS, prhs, _ = R.ba_schur_ref(U, ea, V, eb, R.w_blocks(Ap, Bp, live, st.mrow), live, lam, st.mrow, st.mpt)
    eS, erhs, _ = RE.ba_edgelet_schur_ref(Ve, ebe, R.w_blocks(Ae, Be, livee, es.mrow), livee, lam, es.mrow, es.medg, nf)
    assert close(assemble(blocks, st.pair_rows, st.pair_cols, nf), pS + eS) and close(rhs, prhs + erhs)


def test_frames_update_kernel_matches_reference(problem):
    """The frame update of eq. 9 with re-orthonormalisation (``Edgelets.updated``, the BA's trial steps) against
    numpy's batched SE(3) exponential and Gram–Schmidt, for steps up to a few centimetres and degrees."""
    _, eb = problem
    de = np.random.default_rng(4).normal(size=(len(eb.init), 4)) * np.array([0.02, 0.02, 0.05, 0.05])
    out = np.empty((len(eb.init), 4, 4))
    frames_updated(eb.init.frames(), de, out)
    assert close(out, edgelets_updated_ref(eb.init, de).frames(), 1e-12)
    assert close(eb.init.updated(de).frames(), out, 1e-15)
    RtR = np.einsum("nji,njk->nik", out[:, :3, :3], out[:, :3, :3])
    assert close(RtR, np.broadcast_to(np.eye(3), (len(de), 3, 3)), 1e-12)


def test_frames_kernel_orthonormalises_as_numpy(problem):
    """``frames_of`` (an adjustment's starting frames) against ``Edgelets.orthonormalised().frames()``, on edgelets
    whose directions are scaled and whose normals lean 20° towards them, for a subset in another order."""
    _, eb = problem
    rng = np.random.default_rng(6)
    e = eb.init
    raw = Edgelets(e.centre, e.direction * rng.uniform(0.5, 2.0, (len(e), 1)), e.normal + 0.36 * e.direction)
    ids = rng.permutation(len(e))[: len(e) // 2]
    out = np.empty((len(ids), 4, 4))
    frames_of(raw.centre, raw.direction, raw.normal, ids, out)
    assert close(out, raw.orthonormalised().subset(ids).frames(), 1e-14)


def test_seen_update_kernel_matches_reference(problem):
    """The convergence test's edgelet share (``ba_edgelet_seen_update``) against its numpy reference, for a random
    update at the perturbed start's linearisation."""
    st, (_, _, _, _, use, _, bad, _), (_, jp, je, _, _), _ = _linearised(problem)
    n = len(st.edgelets.ids)
    de = np.random.default_rng(3).normal(size=(n, 4)) * np.array([1e-3, 1e-3, 1e-2, 1e-2])
    seen = np.empty(n)
    total = EK.ba_edgelet_seen_update(jp, je, de, st.edgelets.medg, use, bad, seen)
    ref = RE.ba_edgelet_seen_update_ref(jp, je, de, st.edgelets.medg, use, bad, n)
    assert close(seen, ref, 1e-12) and np.isclose(total, ref.sum(), rtol=1e-12) and np.count_nonzero(ref) > 0.9 * n


def test_convergence_counts_the_edgelet_motion_its_measurements_see(problem):
    """An edgelet on a line parallel to the keyframes' baseline (§4.3's aperture problem: every back-projected plane
    is the one through the line and the baseline) can slide and turn within that plane unseen: such an update
    counts nothing towards the convergence test. Moved 1 mm out of the plane it counts (1 mm)², as a point's
    update in metres; turned 1e-3 rad out of it, the motion of the sample points ~1 cm out (eq. 6)."""
    cam = problem[0].camera
    centres = np.array([[-0.1, 0.0, 0.0], [0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    poses = np.repeat(np.eye(4)[None], 3, axis=0)
    poses[:, :3, 3] = -centres
    plane_normal = np.array([0.0, 1.0, -0.02]) / np.hypot(1.0, 0.02)
    ed = Edgelets(np.array([[0.05, 0.02, 1.0]]), np.array([[1.0, 0.0, 0.0]]), plane_normal[None])
    mkf, medg = np.arange(3), np.zeros(3, np.int64)
    a = np.stack([project_edgelets(cam, T, ed).centre[0] for T in poses])
    m_hat = np.stack([project_edgelets(cam, T, ed).normal[0] for T in poses])
    along = sample_along(cam, poses, ed, EdgeletObservations(mkf, medg, a, perp(m_hat)), CFG.edgelets)
    _, jp, je, valid = edgelet_ba_terms(cam.kernel_params(), poses, ed.frames(), mkf, medg, a, m_hat, along)
    use, bad, seen = np.ones(3, bool), ~valid, np.empty(1)

    def counted(de) -> float:
        return EK.ba_edgelet_seen_update(jp, je, np.asarray([de], float), medg, use, bad, seen)

    assert counted([0.0, 1e-3, 0.0, 0.0]) < 1e-9 * 1e-6  # slid within the plane (y = z × x lies in it)
    assert counted([0.0, 0.0, 1e-2, 0.0]) < 1e-9 * 1e-6  # turned about the plane's normal, within it
    assert np.isclose(counted([1e-3, 0.0, 0.0, 0.0]), 1e-6, rtol=0.01)
    z = np.abs(along[:, 1]).max()
    assert 0.5 * (1e-3 * z) ** 2 < counted([0.0, 0.0, 0.0, 1e-3]) <= 1.01 * (1e-3 * z) ** 2 and 0.005 < z < 0.02
