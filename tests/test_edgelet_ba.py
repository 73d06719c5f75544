"""Agility §4.4: edgelet residuals (two perpendicular distances) and their Jacobians for bundle adjustment."""

import numpy as np
import pytest

from ptam.edgelet.edgelet import EDGELET_DOF, Edgelets, perp
from ptam.edgelet.edgelet_ba import EdgeletObservations, edgelet_terms, refine_edgelets, sample_along, update_poses
from ptam.edgelet.edgelet_ba_kernels import edgelet_ba_terms, edgelet_normal_equations
from ptam.edgelet.edgelet_projection import project_edgelets
from ptam.edgelet.edgelet_refine_kernels import solvable, solve_in_place, symmetric_eigenvalues
from ptam.geometry import se3
from tests.reference.edgelet_ba import edgelet_ba_terms_ref, refine_edgelets_ref
from tests.support.cameras import CAMERAS


@pytest.fixture(scope="module")
def ecfg(cfg):
    return cfg.edgelets


def _look_at(centre, target):
    z = target - centre
    z /= np.linalg.norm(z)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R_wc = np.stack([x, np.cross(z, x), z], axis=1)
    return se3.inv(se3.from_Rt(R_wc, centre))


def _problem(rng, cam, n_kf=4, n_e=40):
    """Keyframes on an arc 2.5 m from a 0.8 m cube of edgelets; measured lines are the true projections moved
    by up to 1 px and turned by up to 2°, so residuals are non-zero."""
    poses = np.stack(
        [
            _look_at(np.array([np.sin(a) * 2.5, 0.2 * k, -np.cos(a) * 2.5]), np.zeros(3))
            for k, a in enumerate(np.linspace(-0.4, 0.4, n_kf))
        ]
    )
    c = rng.uniform(-0.4, 0.4, (n_e, 3))
    e = Edgelets(c, rng.normal(size=(n_e, 3)), rng.normal(size=(n_e, 3))).orthonormalised()
    kf, ed = np.meshgrid(np.arange(n_kf), np.arange(n_e), indexing="ij")
    kf, ed = kf.ravel(), ed.ravel()
    a, b = [], []
    for k in range(n_kf):
        p = project_edgelets(cam, poses[k], e)
        ang = np.deg2rad(rng.uniform(-2, 2, n_e))
        u = p.unit_direction
        b.append(
            np.stack([np.cos(ang) * u[:, 0] - np.sin(ang) * u[:, 1], np.sin(ang) * u[:, 0] + np.cos(ang) * u[:, 1]], 1)
        )
        a.append(p.centre + rng.uniform(-1, 1, (n_e, 1)) * p.normal)
    return poses, e, EdgeletObservations(kf, ed, np.concatenate(a), np.concatenate(b))


@pytest.mark.parametrize("name", list(CAMERAS))
def test_kernel_matches_reference(name, ecfg):
    cam = CAMERAS[name]
    rng = np.random.default_rng(0)
    poses, e, obs = _problem(rng, cam)
    along = sample_along(cam, poses, e, obs, ecfg)
    t = edgelet_terms(cam, poses, e, obs, along)
    m_hat = perp(obs.b)
    ref = edgelet_ba_terms_ref(cam, poses, e.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along)
    assert t.valid.all() and np.array_equal(t.valid, ref[3])
    assert np.allclose(t.err, ref[0], atol=1e-9) and np.abs(t.err).max() > 0.5
    assert np.allclose(t.J_pose, ref[1], rtol=1e-9, atol=1e-6) and np.allclose(
        t.J_edgelet, ref[2], rtol=1e-9, atol=1e-6
    )
    # Behind the camera: invalid, zero terms, like the reference.
    flipped = poses.copy()
    flipped[1] = se3.from_Rt(np.diag([1.0, -1.0, -1.0]), np.zeros(3)) @ poses[1]
    got = edgelet_ba_terms(cam.kernel_params(), flipped, e.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along)
    ref = edgelet_ba_terms_ref(cam, flipped, e.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along)
    assert np.array_equal(got[3], ref[3]) and (~got[3]).sum() >= 40
    assert all(np.allclose(g, r, atol=1e-6) for g, r in zip(got[:3], ref[:3]))


@pytest.mark.parametrize("name", list(CAMERAS))
def test_normal_equations_kernel_matches_reference(name, ecfg):
    """Σ JᵀJ and Σ Jᵀε per edgelet, as the reference's terms sum them; one keyframe turned away from the edgelets
    leaves its measurements out (and the counts one lower)."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(1)
    poses, e, obs = _problem(rng, cam)
    along = sample_along(cam, poses, e, obs, ecfg)
    poses[1] = se3.from_Rt(np.diag([1.0, -1.0, -1.0]), np.zeros(3)) @ poses[1]
    m_hat = perp(obs.b)
    err, _, Je, valid = edgelet_ba_terms_ref(cam, poses, e.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along)
    n = len(e)
    H_ref = np.zeros((n, 4, 4))
    g_ref = np.zeros((n, 4))
    np.add.at(H_ref, obs.edgelet[valid], np.einsum("msi,msj->mij", Je, Je)[valid])
    np.add.at(g_ref, obs.edgelet[valid], np.einsum("msi,ms->mi", Je, err)[valid])
    H, g, count = edgelet_normal_equations(
        cam.kernel_params(), poses, e.frames(), obs.kf, obs.edgelet, obs.a, m_hat, along, n
    )
    assert np.array_equal(count, np.bincount(obs.edgelet[valid], minlength=n)) and count.max() == 3
    assert np.allclose(H, H_ref, rtol=1e-9, atol=1e-6) and np.allclose(g, g_ref, rtol=1e-9, atol=1e-6)
    assert np.abs(g).max() > 1.0


def test_sample_points_are_five_pixels_from_the_centre(ecfg):
    """Eq. 6: p = (0, 0, ∓5/|d|) project 5 px either side of the centre (to first order: perspective makes the
    nearer one a little longer) and 10 px apart."""
    cam = CAMERAS["pinhole"]
    poses, e, obs = _problem(np.random.default_rng(1), cam)
    along = sample_along(cam, poses, e, obs, ecfg)
    assert np.all(along[:, 0] < 0) and np.allclose(along[:, 0], -along[:, 1])
    T = poses[obs.kf]
    c = e.centre[obs.edgelet]
    d = e.direction[obs.edgelet]

    def project(X):
        return cam.project(np.einsum("mij,mj->mi", T[:, :3, :3], X) + T[:, :3, 3])

    s1, s2, uc = project(c + along[:, :1] * d), project(c + along[:, 1:] * d), project(c)
    off = ecfg.ba_sample_offset_px
    assert np.allclose(np.linalg.norm(s1 - uc, axis=1), off, rtol=0.1)
    assert np.allclose(np.linalg.norm(s2 - uc, axis=1), off, rtol=0.1)
    assert np.allclose(np.linalg.norm(s2 - s1, axis=1), 2 * off, rtol=0.01)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_jacobians_match_central_differences(name, ecfg):
    """Relative error < 1e-4 for the keyframe pose (T ← exp(μ) T) and the edgelet (E ← E exp(μ), 4 DOF)."""
    cam = CAMERAS[name]
    poses, e, obs = _problem(np.random.default_rng(2), cam)
    along = sample_along(cam, poses, e, obs, ecfg)
    t = edgelet_terms(cam, poses, e, obs, along)
    h = 1e-6
    fd_pose = np.zeros_like(t.J_pose)
    for k in range(6):
        mu = np.zeros((len(poses), 6))
        mu[:, k] = h
        up = edgelet_terms(cam, update_poses(poses, mu), e, obs, along).err
        dn = edgelet_terms(cam, update_poses(poses, -mu), e, obs, along).err
        fd_pose[..., k] = (up - dn) / (2 * h)
    fd_e = np.zeros_like(t.J_edgelet)
    for j in range(4):
        mu = np.zeros((len(e), 4))
        mu[:, j] = h
        up = edgelet_terms(cam, poses, e.updated(mu), obs, along).err
        dn = edgelet_terms(cam, poses, e.updated(-mu), obs, along).err
        fd_e[..., j] = (up - dn) / (2 * h)
    for J, fd in ((t.J_pose, fd_pose), (t.J_edgelet, fd_e)):
        rel = np.abs(J - fd).max(axis=(1, 2)) / np.abs(fd).max(axis=(1, 2))  # per measurement
        assert rel.max() < 1e-4, rel.max()
    assert EDGELET_DOF == (0, 1, 3, 4)


def test_gauss_newton_on_the_edgelet_terms_recovers_the_line(ecfg):
    """Measurements are the true lines in four keyframes; an edgelet moved 3 cm and turned 3° returns onto the
    true 3-D line (its position along the line is a gauge the 4-DOF update leaves alone). Pinhole: with lens
    distortion a 3-D line images as a curve and its tangent, the measured line, is not exactly met."""
    cam = CAMERAS["pinhole"]
    rng = np.random.default_rng(3)
    poses, truth, _ = _problem(rng, cam, n_e=5)
    a, b = [], []
    for k in range(len(poses)):
        p = project_edgelets(cam, poses[k], truth)
        a.append(p.centre)
        b.append(p.unit_direction)
    obs = EdgeletObservations(
        np.repeat(np.arange(len(poses)), 5), np.tile(np.arange(5), len(poses)), np.concatenate(a), np.concatenate(b)
    )
    e = truth.updated(np.concatenate([rng.uniform(-0.03, 0.03, (5, 2)), np.deg2rad(rng.uniform(-3, 3, (5, 2)))], 1))
    for _ in range(8):
        along = sample_along(cam, poses, e, obs, ecfg)
        t = edgelet_terms(cam, poses, e, obs, along)
        mu = np.zeros((5, 4))
        for j in range(5):
            sel = obs.edgelet == j
            J = t.J_edgelet[sel].reshape(-1, 4)
            mu[j] = -np.linalg.lstsq(J, t.err[sel].ravel(), rcond=None)[0]
        e = e.updated(mu)
    off_line = e.centre - truth.centre
    off_line -= np.sum(off_line * truth.direction, axis=1, keepdims=True) * truth.direction
    assert np.linalg.norm(off_line, axis=1).max() < 1e-8
    assert np.abs(np.abs(np.sum(e.direction * truth.direction, axis=1)) - 1).max() < 1e-12


def test_jacobi_eigenvalues_and_solve_match_lapack():
    """The refinement kernel's 4×4 helpers against LAPACK: eigenvalues of symmetric matrices (rank 4, rank 2 and
    zero) within 1e-12 of the largest, and solutions of well-conditioned systems within 1e-12."""
    rng = np.random.default_rng(5)
    a = np.empty((4, 4))
    for rank in (4, 4, 2, 0):
        A = rng.normal(size=(4, rank)) * rng.uniform(0.01, 100.0, rank)
        H = A @ A.T
        symmetric_eigenvalues(H, a)
        ref = np.linalg.eigvalsh(H)
        assert np.allclose(np.sort(np.diag(a)), ref, atol=1e-12 * max(1.0, ref.max()))
        if rank == 4:
            x = rng.normal(size=4)
            solve_in_place(H.copy(), x_got := x.copy())
            assert np.allclose(x_got, np.linalg.solve(H, x), rtol=1e-12, atol=1e-12)
    assert not solvable(np.zeros((4, 4)), 3, a) and not solvable(np.eye(4), 1, a) and solvable(np.eye(4), 2, a)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_refine_kernel_matches_reference(name, ecfg):
    """Three Gauss–Newton steps on 40 edgelets, poses fixed (``refine_edgelets``), against the numpy reference:
    frames within 1e-9; edgelets left with one measurement, or with two measurements from one keyframe (a
    singular H), are not moved; the others reach the least-squares optimum."""
    cam = CAMERAS[name]
    poses, e, obs = _problem(np.random.default_rng(6), cam)
    keep = ~((obs.edgelet < 5) & (obs.kf > 0))  # edgelets 0-4: one measurement
    obs = EdgeletObservations(obs.kf[keep], obs.edgelet[keep], obs.a[keep], obs.b[keep])
    twice = obs.edgelet == 5  # edgelet 5: its keyframe-0 measurement twice, nothing else
    first = twice & (obs.kf == 0)
    obs = EdgeletObservations(
        np.concatenate([obs.kf[~twice], obs.kf[first], obs.kf[first]]),
        np.concatenate([obs.edgelet[~twice], obs.edgelet[first], obs.edgelet[first]]),
        np.concatenate([obs.a[~twice], obs.a[first], obs.a[first]]),
        np.concatenate([obs.b[~twice], obs.b[first], obs.b[first]]),
    )
    got = refine_edgelets(cam, poses, e, obs, ecfg, 3)
    ref = refine_edgelets_ref(cam, poses, e, obs, sample_along(cam, poses, e, obs, ecfg), 3)
    assert np.allclose(got.frames(), ref.frames(), rtol=1e-9, atol=1e-9)
    assert np.allclose(got.frames()[:6], e.frames()[:6], atol=1e-12)
    # Converging: after 8 steps the gradient Σ Jᵀε of the moved edgelets has all but vanished (the noise stays
    # in ε).
    along = sample_along(cam, poses, e, obs, ecfg)
    args = (cam.kernel_params(), poses)
    rest = (obs.kf, obs.edgelet, obs.a, perp(obs.b), along, len(e))
    g_before = edgelet_normal_equations(*args, e.frames(), *rest)[1][6:]
    more = refine_edgelets(cam, poses, e, obs, ecfg, 8)
    g_after = edgelet_normal_equations(*args, more.frames(), *rest)[1][6:]
    assert np.abs(g_after).max() < 1e-3 * np.abs(g_before).max() and np.abs(g_before).max() > 1.0
