"""The bundle-adjustment kernels against their numpy references on random problems (PTAM §6.3)."""

import numpy as np
import pytest

from ptam.camera import FovCamera, PinholeCamera, RadTanCamera
from ptam.geometry import se3
from ptam.mapping import bundle_kernels as K
from ptam.mapping import bundle_schur_kernels as SK
from ptam.mapping import bundle_solve_kernels as ba_solve
from ptam.mapping.bundle_structure import ReducedSolver, build_structure
from ptam.mapping.bundle_structure_kernels import landmark_layout
from tests.reference import bundle as R

CAMERAS = {
    "fov": FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9),
    "pinhole": PinholeCamera(640, 480, 500.0, 505.0, 320.0, 240.0),
    "radtan": RadTanCamera(640, 480, 450.0, 455.0, 322.0, 236.0, -0.2, 0.05, 1e-3, -1e-3, 0.0),
}


def close(a, b, rel=1e-9):
    """Equal to ``rel`` relative to the reference's magnitude."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and np.allclose(a, b, rtol=rel, atol=rel * max(np.abs(b).max(initial=0.0), 1e-300))


def assemble(blocks, rows, cols, n_free):
    """The symmetric (6N)² matrix from its lower-triangle blocks."""
    S = np.zeros((6 * n_free, 6 * n_free))
    for B, r, c in zip(blocks, rows, cols):
        S[6 * r : 6 * r + 6, 6 * c : 6 * c + 6] = B
        S[6 * c : 6 * c + 6, 6 * r : 6 * r + 6] = B.T
    return S


def random_problem(rng, n_cams=7, n_pts=60, n_fixed=2):
    mu = np.concatenate([rng.normal(0, 0.3, (n_cams, 3)), rng.normal(0, 0.2, (n_cams, 3))], axis=1)
    poses = se3.exp(mu)
    X = rng.uniform([-1.5, -1.0, 2.0], [1.5, 1.0, 5.0], (n_pts, 3))
    X[:3, 2] = -2.0  # behind the cameras: PTAM's "bad" measurements
    kf, pt = np.nonzero(rng.random((n_cams, n_pts)) < 0.6)
    uv = rng.uniform([0, 0], [640, 480], (len(kf), 2))
    level = rng.integers(0, 4, len(kf))
    fixed = np.zeros(n_cams, bool)
    fixed[rng.choice(n_cams, n_fixed, replace=False)] = True
    st = build_structure(kf, pt, fixed, np.ones(n_pts, bool))
    return poses, X, kf, pt, uv, level, fixed, st


@pytest.fixture(params=list(CAMERAS))
def problem(request):
    rng = np.random.default_rng(11)
    cam = CAMERAS[request.param]
    poses, X, kf, pt, uv, level, fixed, st = random_problem(rng)
    P = poses[st.cams]
    Xs = X[st.pts]
    uvs = uv[st.sel]
    # Centre the observations on the projections so the Tukey cut-off splits inliers from outliers.
    Xc = np.einsum("kij,kj->ki", P[st.mcam, :3, :3], Xs[st.mpt]) + P[st.mcam, :3, 3]
    front = Xc[:, 2] > 0
    uvs[front] = cam.project(Xc[front]) + rng.normal(0, 3.0, (front.sum(), 2))
    inv_sigma = np.ldexp(1.0, -level[st.sel])
    use = rng.random(len(st.sel)) < 0.9
    return cam, P, Xs, uvs, inv_sigma, use, st


def test_residuals_and_cost(problem):
    cam, P, X, uv, inv_sigma, use, st = problem
    n = len(st.sel)
    err, e2, bad = np.empty((n, 2)), np.empty(n), np.empty(n, bool)
    K.ba_residuals(cam.kernel_params(), P, X, st.mcam, st.mpt, uv, inv_sigma, use, err, e2, bad)
    r_err, r_e2, r_bad = R.ba_residuals_ref(cam, P, X, st.mcam, st.mpt, uv, inv_sigma, use)
    assert np.array_equal(bad, r_bad) and bad.sum() > 0
    assert close(err, r_err) and close(e2, r_e2)
    # Floors below, at and above the median's own cut-off: the floor's shortcut gives the selection's answer.
    c_median = np.sqrt(R.tukey_cutoff_sq_ref(e2, use, bad, 0.0))
    for min_c in (0.4, c_median * (1 - 1e-12), c_median, c_median * (1 + 1e-12), 50.0):
        c2 = K.tukey_cutoff_sq(e2, use, bad, min_c)
        assert close(c2, R.tukey_cutoff_sq_ref(e2, use, bad, min_c))
        assert close(K.ba_robust_cost(e2, bad, use, c2), R.ba_robust_cost_ref(e2, bad, use, c2))
    assert K.tukey_cutoff_sq(e2, np.zeros(n, bool), bad, 0.4) == pytest.approx(0.16)


@pytest.mark.parametrize("kind", ["random", "sorted", "reversed", "few values", "all equal", "sawtooth"])
def test_select_kth_matches_a_sort(kind):
    """The quickselect behind the Tukey cut-off returns the k-th smallest value exactly, on inputs that defeat
    naive pivots, for every k tried."""
    rng = np.random.default_rng(4)
    n = 2001
    a = {
        "random": rng.chisquare(2, n),
        "sorted": np.sort(rng.random(n)),
        "reversed": np.sort(rng.random(n))[::-1].copy(),
        "few values": rng.integers(0, 3, n).astype(float),
        "all equal": np.full(n, 0.25),
        "sawtooth": np.tile(np.sort(rng.random(n // 3)), 4)[:n],
    }[kind]
    for k in (0, 1, n // 2, n - 2, n - 1):
        work = a.copy()
        assert K.select_kth(work, n, k) == np.sort(a)[k]
        assert np.array_equal(np.sort(work), np.sort(a))  # reordered, nothing lost
    # Errors gathered from two sets (points, edgelets) give the cut-off of their concatenation.
    e2, use, bad = a[:1000], rng.random(1000) < 0.8, rng.random(1000) < 0.05
    f2, fuse, fbad = a[1000:], rng.random(n - 1000) < 0.8, np.zeros(n - 1000, bool)
    out = np.empty(n)
    m = K.gather_errors(f2, fuse, fbad, out, K.gather_errors(e2, use, bad, out, 0))
    joint = R.tukey_cutoff_sq_ref(
        np.concatenate([e2, f2]), np.concatenate([use, fuse]), np.concatenate([bad, fbad]), 0.1
    )
    assert m == (use & ~bad).sum() + fuse.sum() and K.cutoff_sq_of(out, m, 0.1) == joint


def linearised(problem):
    cam, P, X, uv, inv_sigma, use, st = problem
    n, nf, m = len(st.sel), st.n_free, len(st.pts)
    e2, bad = np.empty(n), np.empty(n, bool)
    K.ba_residuals(cam.kernel_params(), P, X, st.mcam, st.mpt, uv, inv_sigma, use, np.empty((n, 2)), e2, bad)
    c2 = K.tukey_cutoff_sq(e2, use, bad, 0.4)
    U, ea, V, eb = np.empty((nf, 6, 6)), np.empty((nf, 6)), np.empty((m, 3, 3)), np.empty((m, 3))
    A, B, live = np.full((n, 2, 6), 7.0), np.full((n, 2, 3), 7.0), np.empty(n, bool)
    cost = K.ba_linearise(
        cam.kernel_params(), P, X, st.mcam, st.mpt, uv, inv_sigma, use, c2, st.cam_row, U, ea, V, eb, A, B, live
    )
    return c2, (U, ea, V, eb, (A, B), live, cost)


def test_linearise_blocks(problem):
    cam, P, X, uv, inv_sigma, use, st = problem
    c2, (U, ea, V, eb, AB, live, cost) = linearised(problem)
    W = R.w_blocks(*AB, live, st.mrow)
    rU, rea, rV, reb, rW, rlive, rcost = R.ba_linearise_ref(
        cam, P, X, st.mcam, st.mpt, uv, inv_sigma, use, c2, st.cam_row, len(st.pts)
    )
    assert np.array_equal(live, rlive) and 0 < live.sum() < use.sum()
    assert close(cost, rcost)
    for a, b in ((U, rU), (ea, rea), (V, rV), (eb, reb)):
        assert close(a, b)
    w = live & (st.mrow >= 0)
    assert close(W[w], rW[w])


def test_schur_backsub_and_solvers(problem):
    cam, P, X, uv, inv_sigma, use, st = problem
    _, (U, ea, V, eb, AB, live, _) = linearised(problem)
    W = R.w_blocks(*AB, live, st.mrow)
    V[0] = 0.0  # a point without measurements: V* is singular and PTAM leaves the point alone
    lam = 1e-3
    nf = st.n_free
    blocks, rhs, Vinv = np.empty((len(st.pair_rows), 6, 6)), np.empty(6 * nf), np.empty_like(V)
    SK.ba_schur(U, ea, V, eb, *AB, live, lam, st.mrow, st.pt_start, st.order, st.pair_id, blocks, rhs, Vinv)
    S = assemble(blocks, st.pair_rows, st.pair_cols, nf)
    rS, rrhs, rVinv = R.ba_schur_ref(U, ea, V, eb, W, live, lam, st.mrow, st.mpt)
    assert close(S, rS) and close(rhs, rrhs) and close(Vinv, rVinv)
    assert not Vinv[0].any()

    x = ReducedSolver(st, dense=True).solve(blocks, rhs)
    assert close(x, np.linalg.solve(rS, rrhs), 1e-8)
    assert close(ReducedSolver(st, dense=False).solve(blocks, rhs), x, 1e-8)

    dp = SK.ba_backsub(Vinv, eb, *AB, live, st.mrow, st.pt_start, st.order, x)
    assert close(dp, R.ba_backsub_ref(Vinv, eb, W, live, st.mrow, st.mpt, x))


def test_envelope_cholesky_on_a_banded_system():
    """A chain of keyframes in shuffled order: the reordered envelope is a band, the solution exact."""
    rng = np.random.default_rng(5)
    nb, band = 40, 3
    order = rng.permutation(nb)
    pairs = [(max(order[i], order[j]), min(order[i], order[j])) for i in range(nb) for j in range(max(0, i - band), i)]
    rows = np.r_[np.arange(nb), [p[0] for p in pairs]].astype(np.int64)
    cols = np.r_[np.arange(nb), [p[1] for p in pairs]].astype(np.int64)
    blocks = rng.normal(size=(len(rows), 6, 6))
    blocks[:nb] += np.swapaxes(blocks[:nb], 1, 2)
    S = assemble(blocks, rows, cols, nb)
    S += np.diag(np.abs(S).sum(axis=1))  # diagonally dominant, so positive definite
    blocks[:nb] = np.stack([S[6 * r : 6 * r + 6, 6 * r : 6 * r + 6] for r in range(nb)])
    rhs = rng.normal(size=(6 * nb, 2))  # two right-hand sides on one factorisation
    for dense in (True, False):
        rank = np.arange(nb) if dense else np.argsort(order)
        first, ptr = ba_solve.ba_envelope(rows, cols, rank, dense)
        x, ok = ba_solve.ba_envelope_solve(blocks, rows, cols, rank, first, ptr, rhs)
        assert ok and close(x, np.linalg.solve(S, rhs), 1e-10)
        # Sparse: block row I keeps blocks max(0, I − band)..I, so 21·nb + 36·band·nb − 18·band·(band + 1) entries.
        band_size = 21 * nb + 36 * band * nb - 18 * band * (band + 1)
        assert ptr[-1] == (6 * nb * (6 * nb + 1) // 2 if dense else band_size)


def test_pair_script(problem):
    st = problem[-1]
    ref = R.ba_pair_script_ref(st.pt_start, st.order, st.mrow)
    pair_id, rows, cols = SK.ba_pair_script(st.pt_start, st.order, st.mrow, st.n_free)
    assert len(ref) > 100 and np.array_equal(np.c_[rows[pair_id], cols[pair_id]], ref)
    assert len(np.unique(rows * st.n_free + cols)) == len(rows) == len(np.unique(ref[:, 0] * st.n_free + ref[:, 1]))


@pytest.mark.parametrize("duplicate", [False, True])
def test_landmark_layout_matches_numpy(duplicate):
    """Measurements by landmark and then camera row, fixed keyframes (row −1) first, ties in input order, as
    ``np.lexsort``; a keyframe measuring a landmark twice is found wherever the pair falls."""
    rng = np.random.default_rng(3)
    n_cams, n_lm = 12, 400
    cam_row = np.where(rng.random(n_cams) < 0.4, -1, 0)
    cam_row[cam_row >= 0] = np.arange(np.count_nonzero(cam_row >= 0))
    cam, lm = np.nonzero(rng.random((n_cams, n_lm)) < 0.3)
    perm = rng.permutation(len(cam))
    cam, lm = cam[perm], lm[perm]
    if duplicate:
        cam, lm = np.append(cam, cam[17]), np.append(lm, lm[17])
    got = landmark_layout(lm, cam, cam_row[cam], n_lm, n_cams)
    ref = R.landmark_layout_ref(lm, cam, cam_row[cam], n_lm)
    assert len(ref[0]) < n_lm and ref[4] > 500 and ref[5] is not duplicate
    for g, r in zip(got[:4], ref[:4]):
        assert np.array_equal(g, r)
    assert got[4:] == ref[4:]


def test_not_positive_definite_is_reported():
    one = np.zeros(1, np.int64)
    first, ptr = ba_solve.ba_envelope(one, one, one, True)
    _, ok = ba_solve.ba_envelope_solve(-np.eye(6)[None], one, one, one, first, ptr, np.ones((6, 1)))
    assert not ok
