"""Agility §4.1–§4.2, §5.1: the edgelet frame, its 4-DOF update, projection and the tracking Jacobian."""

import numpy as np
import pytest

from ptam.edgelet.edgelet import Edgelets, perp
from ptam.edgelet.edgelet_measure import LineMeasurements
from ptam.edgelet.edgelet_projection import (
    blur_lengths,
    project_edgelets,
    project_edgelets_with_jacobian,
)
from ptam.edgelet.edgelet_triangulation import line_planes, triangulate_edgelets
from ptam.geometry import se3
from tests.reference.edgelet_projection import edgelet_projection_ref
from tests.reference.edgelet_triangulation import line_planes_ref, triangulate_ref
from tests.support.cameras import CAMERAS


def random_edgelets(rng, n, centre=(0.0, 0.0, 2.0), spread=0.4):
    c = np.asarray(centre) + rng.uniform(-spread, spread, (n, 3))
    d = rng.normal(size=(n, 3))
    x = rng.normal(size=(n, 3))
    return Edgelets(c, d, x).orthonormalised()


def random_pose(rng, rot=0.1, trans=0.1):
    return se3.exp(np.concatenate([rng.uniform(-trans, trans, 3), rng.uniform(-rot, rot, 3)]))


def test_frames_are_right_handed_and_round_trip():
    e = random_edgelets(np.random.default_rng(0), 50)
    E = e.frames()
    R = E[:, :3, :3]
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-12) and np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(E[:, :3, 2], e.direction) and np.allclose(E[:, :3, 0], e.normal)
    back = Edgelets.from_frames(E)
    assert np.allclose(back.centre, e.centre) and np.allclose(back.direction, e.direction)
    assert np.allclose(e.updated(np.zeros((50, 4))).frames(), E, atol=1e-15)


def test_four_dof_update_moves_only_perpendicular_and_stays_orthonormal():
    rng = np.random.default_rng(1)
    e = random_edgelets(rng, 40)
    t = rng.uniform(-0.01, 0.01, (40, 2))
    moved = e.updated(np.concatenate([t, np.zeros((40, 2))], axis=1))
    # Pure translations move the centre along x (normal) and y (binormal) only; the axes stay.
    assert np.allclose(moved.centre - e.centre, t[:, :1] * e.normal + t[:, 1:] * e.binormal, atol=1e-15)
    assert np.allclose(moved.direction, e.direction) and np.allclose(moved.normal, e.normal)
    # A rotation about x by w turns the direction towards −y: z' = cos w z − sin w y.
    w = rng.uniform(-0.3, 0.3, 40)
    rot = e.updated(np.stack([0 * w, 0 * w, w, 0 * w], axis=1))
    expect = np.cos(w)[:, None] * e.direction - np.sin(w)[:, None] * e.binormal
    assert np.allclose(rot.direction, expect, atol=1e-12) and np.allclose(rot.centre, e.centre)
    # Many random updates: the frame stays exactly orthonormal (re-orthonormalised each time).
    for _ in range(200):
        e = e.updated(rng.normal(0, 0.2, (40, 4)))
    R = e.frames()[:, :3, :3]
    assert np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max() < 1e-14


@pytest.mark.parametrize("name", list(CAMERAS))
def test_projection_direction_is_the_derivative_along_the_edgelet(name):
    cam = CAMERAS[name]
    rng = np.random.default_rng(2)
    e = random_edgelets(rng, 100)
    T = random_pose(rng)
    p = project_edgelets(cam, T, e)
    assert p.valid.all()
    h = 1e-6
    Xp = se3.transform(T, e.centre + h * e.direction)
    Xm = se3.transform(T, e.centre - h * e.direction)
    d_fd = (cam.project(Xp) - cam.project(Xm)) / (2 * h)
    assert np.allclose(p.direction, d_fd, rtol=1e-6, atol=1e-4)
    assert np.allclose(p.centre, cam.project(se3.transform(T, e.centre)))
    assert np.allclose(p.normal, perp(p.unit_direction)) and np.allclose(np.linalg.norm(p.normal, axis=1), 1.0)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_polarity_follows_the_first_view(name, cfg):
    """Edgelets triangulated with a measured polarity in their source view keep its dark-to-light side: projected
    back, perp(d) is the measured normal; in another view on the same side of the edgelet, the projected x-axis
    (dark -> light in space) lies on the side of ``perp(d)``."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(3)
    e = random_edgelets(rng, 200)
    T0 = random_pose(rng)
    T_tgt = se3.exp(np.array([0.2, 0.15, 0.0, 0.0, 0.0, 0.0])) @ T0  # a baseline across every direction
    p0, pt = project_edgelets(cam, T0, e), project_edgelets(cam, T_tgt, e)
    sign = rng.choice([-1.0, 1.0], (200, 1))  # the measured polarity in the first view
    lines = [LineMeasurements(p.centre, s * p.unit_direction, *_exact(200)) for p, s in ((p0, sign), (pt, 1.0))]
    tri = triangulate_edgelets(cam, T0, lines[0], T_tgt, lines[1], cfg.edgelets)
    met = np.all(np.isfinite(tri.edgelets.normal), axis=1) & (tri.plane_angle_deg > 1.0)  # exact lines: any angle
    f = tri.edgelets.subset(met)
    assert met.mean() > 0.8
    assert np.allclose(project_edgelets(cam, T0, f).normal, perp(lines[0].b[met]), atol=1e-6)
    T1 = random_pose(rng, rot=0.1, trans=0.05) @ T0
    p1 = project_edgelets(cam, T1, f)
    x_img = np.einsum("nij,nj->ni", cam.project_jacobian(p1.camera_centre), f.normal @ T1[:3, :3].T)
    assert np.all(np.sum(x_img * p1.normal, axis=1) > 0)


def _exact(n):
    """A LineMeasurements' fields after a, b for noise-free lines: rms, samples found, points, found, ok."""
    return np.zeros(n), np.full(n, 5), None, None, np.ones(n, bool)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_triangulation_kernels_match_the_numpy_reference(name, cfg):
    """``plane_normals`` and ``triangulate_lines`` against numpy, on noisy lines in two views: hypotheses with
    planes at every angle, some meeting behind a camera, some end-on (direction along the viewing ray)."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(11)
    e = random_edgelets(rng, 300)
    T0, T1 = random_pose(rng), random_pose(rng, rot=0.3, trans=0.3)
    p0, p1 = project_edgelets(cam, T0, e), project_edgelets(cam, T1, e)
    a0, a1 = p0.centre + rng.normal(0, 2.0, (300, 2)), p1.centre + rng.normal(0, 2.0, (300, 2))
    turn = rng.normal(0, 0.2, (300, 1))
    b0 = p0.unit_direction * np.cos(turn) + perp(p0.unit_direction) * np.sin(turn)
    b1 = p1.unit_direction * rng.choice([-1.0, 1.0], (300, 1))
    b0[:3] = 0.0  # a zero direction: no plane
    m, o = line_planes(cam, T1, a1, b1)
    m_ref, o_ref = line_planes_ref(cam, T1, a1, b1)
    assert np.allclose(m, m_ref, rtol=0, atol=1e-9) and np.allclose(o, o_ref, rtol=0, atol=1e-9)
    lines = [LineMeasurements(a, b, *_exact(300)) for a, b in ((a0, b0), (a1, b1))]
    tri = triangulate_edgelets(cam, T0, lines[0], T1, lines[1], cfg.edgelets)
    ref, sin, s, z_tgt = triangulate_ref(cam, T0, a0, b0, T1, a1, b1)
    angle = np.degrees(np.arcsin(np.clip(sin, 0.0, 1.0)))
    assert np.allclose(tri.plane_angle_deg, angle, equal_nan=True, atol=1e-7)
    finite = np.all(np.isfinite(ref.centre), axis=1) & np.all(np.isfinite(ref.normal), axis=1)
    assert not finite[:3].any() and finite.sum() > 250
    assert np.array_equal(np.all(np.isfinite(tri.edgelets.normal), axis=1) & finite, finite)
    for got, want in zip(
        (tri.edgelets.centre, tri.edgelets.direction, tri.edgelets.normal), (ref.centre, ref.direction, ref.normal)
    ):
        err = np.abs(got[finite] - want[finite]) / np.maximum(1.0, np.abs(want[finite]))
        assert err.max() < 1e-9, err.max()
    behind = finite & ((s <= 0) | (z_tgt <= 0))
    assert behind.any() and not tri.ok[behind].any()


@pytest.mark.parametrize("name", list(CAMERAS))
def test_tracking_jacobian_matches_finite_differences(name):
    cam = CAMERAS[name]
    rng = np.random.default_rng(4)
    e = random_edgelets(rng, 60)
    T = random_pose(rng)
    J = project_edgelets_with_jacobian(cam, T, e)[1]
    p = project_edgelets(cam, T, e)
    h = 1e-6
    fd = np.zeros_like(J)
    for k in range(6):
        mu = np.zeros(6)
        mu[k] = h
        up = cam.project(se3.transform(se3.exp(mu) @ T, e.centre))
        dn = cam.project(se3.transform(se3.exp(-mu) @ T, e.centre))
        fd[:, k] = np.sum(p.normal * (up - dn), axis=1) / (2 * h)
    assert np.abs(J - fd).max() < 1e-4 * np.abs(fd).max()


@pytest.mark.parametrize("name", list(CAMERAS))
def test_projection_kernel_matches_the_numpy_reference(name):
    """Centres, directions, normals, validity and eq. 11's Jacobians against numpy, with edgelets behind the
    camera and beyond the lens's range among them."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(5)
    e = random_edgelets(rng, 300, centre=(0.0, 0.0, 0.8), spread=1.6)
    T = random_pose(rng)
    p, J = project_edgelets_with_jacobian(cam, T, e)
    c, d, n, valid, Xc, J_ref = edgelet_projection_ref(cam, T, e.centre, e.direction)
    assert 50 < valid.sum() < len(valid) - 50  # some of each
    assert np.array_equal(p.valid, valid)
    assert np.allclose(p.camera_centre, Xc, rtol=0, atol=1e-14)
    v = valid
    scale = np.abs(c[v]).max()
    assert np.abs(p.centre[v] - c[v]).max() < 1e-12 * scale
    assert np.abs(p.direction[v] - d[v]).max() < 1e-12 * np.abs(d[v]).max()
    assert np.abs(p.normal[v] - n[v]).max() < 1e-12
    assert np.abs(J[v] - J_ref[v]).max() < 1e-12 * np.abs(J_ref[v]).max()
    assert np.array_equal(project_edgelets(cam, T, e).centre, p.centre)
    assert project_edgelets_with_jacobian(cam, T, e, jacobian=False)[1].shape == (0, 6)


def test_blur_length_of_a_sideways_slide():
    """A vertical edge 2 m ahead, the camera sliding 1 cm along x during the exposure: l = f·0.01/2 px (eq. 10)."""
    cam = CAMERAS["pinhole"]
    e = Edgelets(np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    J = project_edgelets_with_jacobian(cam, np.eye(4), e)[1]
    gamma = np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert np.isclose(blur_lengths(J, gamma)[0], cam.fx * 0.01 / 2.0, rtol=1e-9)
    assert np.isclose(blur_lengths(J, np.array([0, 0.01, 0, 0, 0, 0.0]))[0], 0.0, atol=1e-12)  # along the edge
    # A small pan about y moves the image by ~f·ω px.
    assert np.isclose(blur_lengths(J, np.array([0, 0, 0, 0, 0.02, 0.0]))[0], cam.fx * 0.02, rtol=1e-9)
