"""Agility §4.3: edgelets triangulated from two keyframes and checked in a third.

The geometry is checked on exact lines (the analytic projections of a card's edges, every camera model), the
whole chain on rendered keyframes: measure (§4.2) in source and target, intersect the planes, check in a third
keyframe, then refine the edgelet on all its keyframe measurements (the edgelet blocks of §4.4's BA)."""

import cv2
import numpy as np
import pytest

from ptam.edgelet.edgelet import Edgelets, perp
from ptam.edgelet.edgelet_ba import EdgeletObservations, refine_edgelets
from ptam.edgelet.edgelet_measure import LineMeasurements, measure_in_keyframe
from ptam.edgelet.edgelet_projection import project_edgelets
from ptam.edgelet.edgelet_triangulation import line_planes, triangulate_edgelets, verify_edgelets
from ptam.geometry import se3
from ptam.synthetic.rectangle import Rectangle
from ptam.synthetic.render import Renderer
from tests.support.cameras import CAMERAS

CARD_GREY, BACKGROUND = 200.0, 40.0
CENTRE = np.array([0.02, -0.01, 1.0])
# Camera centres: the source, a target 25 cm along x, one 25 cm along y, and a check keyframe off both axes.
POSITIONS = np.array([[0.0, 0.0, 0.0], [0.25, 0.0, 0.02], [0.0, 0.25, -0.02], [-0.15, -0.12, 0.05]])


def _rot(axis, deg):
    return cv2.Rodrigues(np.asarray(axis, float) * np.deg2rad(deg))[0]


def _look_at(pos, target):
    z = (target - pos) / np.linalg.norm(target - pos)
    x = np.cross([0.0, -1.0, 0.0], z)
    x /= np.linalg.norm(x)
    return se3.from_Rt(np.stack([x, np.cross(z, x), z], axis=1), pos)  # T_wc


def _card_and_truth():
    """A bright card (0.4 × 0.3 m, turned 15° in its plane and tilted 25°) 1 m ahead, and true edgelets at 30%,
    50% and 70% along each of its four edges."""
    R = _rot([0, 0, 1], 15) @ _rot([0, 1, 0], 25)
    a, b, size = R[:, 0], R[:, 1], (0.4, 0.3)
    corner0 = CENTRE - a * size[0] / 2 - b * size[1] / 2
    card = Rectangle("card", corner0, a, b, size, {"type": "constant", "value": CARD_GREY})
    corners = card.corners()
    centres, dirs = [], []
    for k in range(4):
        p, q = corners[k], corners[(k + 1) % 4]
        for f in (0.3, 0.5, 0.7):
            centres.append(p + f * (q - p))
            dirs.append((q - p) / np.linalg.norm(q - p))
    truth = Edgelets(np.array(centres), np.array(dirs), np.cross(dirs, card.normal)).orthonormalised()
    return card, truth


def _poses_cw():
    return se3.inv(np.stack([_look_at(p, CENTRE) for p in POSITIONS]))


@pytest.fixture(scope="module", params=["pinhole", "fov"])
def scene(request):
    """The card over a dark background rendered into the four keyframes (64 samples a pixel), with a 0.7 px lens
    blur and 1 grey level of noise."""
    cam = CAMERAS[request.param]
    card, truth = _card_and_truth()
    renderer = Renderer(cam, [card], 8, BACKGROUND)  # 8×8 samples: 4×4 leaves 0.7° wobbles on the edges
    T_cw = _poses_cw()
    rng = np.random.default_rng(0)
    images = []
    for T in se3.inv(T_cw):
        img = cv2.GaussianBlur(renderer.render(T[None]), (0, 0), 0.7) + rng.normal(0, 1.0, (cam.height, cam.width))
        images.append(np.clip(np.round(img), 0, 255).astype(np.uint8))
    return cam, T_cw, images, truth


def _predict(cam, T_cw, truth, rng):
    """The truth projected, moved 1.5 px off the edge and turned 3° (a candidate's prior), with the dark-to-light
    normal pointing into the bright card."""
    p = project_edgelets(cam, T_cw, truth)
    inward = cam.project(se3.transform(T_cw, CENTRE[None]))[0] - p.centre
    n = p.normal * np.where(np.sum(p.normal * inward, axis=1) < 0, -1.0, 1.0)[:, None]
    turn = np.deg2rad(3.0) * rng.choice([-1.0, 1.0], len(p.centre))
    d = p.unit_direction
    d = np.stack([np.cos(turn) * d[:, 0] - np.sin(turn) * d[:, 1], np.sin(turn) * d[:, 0] + np.cos(turn) * d[:, 1]], 1)
    return p.centre + 1.5 * rng.choice([-1.0, 1.0], (len(n), 1)) * n, d, n


def _measure(cam, T_cw, image, truth, rng, ecfg):
    return measure_in_keyframe(image, *_predict(cam, T_cw, truth, rng), ecfg)


def _line_errors(est: Edgelets, truth: Edgelets):
    """Distance (mm) of each estimated centre from the true 3-D line, direction error (deg), along-line offset (mm)."""
    off = est.centre - truth.centre
    along = np.sum(off * truth.direction, axis=1)
    perp_mm = np.linalg.norm(off - along[:, None] * truth.direction, axis=1) * 1000
    ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(est.direction * truth.direction, axis=1)), 0, 1)))
    return perp_mm, ang, np.abs(along) * 1000


def _exact_lines(cam, T_cw, truth):
    p = project_edgelets(cam, T_cw, truth)
    n = len(truth)
    return LineMeasurements(p.centre, p.unit_direction, np.zeros(n), np.full(n, 5), None, None, np.ones(n, bool))


def _better_of(tri_x, tri_y):
    """Per edgelet, the hypothesis from the more orthogonally translated target (the wider plane angle, §4.3)."""
    use_x = tri_x.plane_angle_deg > tri_y.plane_angle_deg
    pick = lambda u, v: np.where(use_x[:, None], u, v)  # noqa: E731
    e = Edgelets(
        pick(tri_x.edgelets.centre, tri_y.edgelets.centre),
        pick(tri_x.edgelets.direction, tri_y.edgelets.direction),
        pick(tri_x.edgelets.normal, tri_y.edgelets.normal),
    )
    return e, use_x, np.where(use_x, tri_x.ok, tri_y.ok)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_exact_lines_give_the_true_edgelets(name, cfg):
    """Noise-free lines (the analytic projections; tangents of the curved images through a distorting lens):
    plane-plane intersection and the source ray recover the true edgelet to 1 µm and 0.001°."""
    cam, ecfg = CAMERAS[name], cfg.edgelets
    _, truth = _card_and_truth()
    T_cw = _poses_cw()
    lines = [_exact_lines(cam, T, truth) for T in T_cw]
    tri_x = triangulate_edgelets(cam, T_cw[0], lines[0], T_cw[1], lines[1], ecfg)
    tri_y = triangulate_edgelets(cam, T_cw[0], lines[0], T_cw[2], lines[2], ecfg)
    # The aperture problem: near-vertical edges meet the x-translated target's planes at a wide angle and the
    # y-translated one's at a narrow angle (below 6°), and vice versa; the narrow ones are flagged by the gate.
    vertical = np.abs(lines[0].b[:, 1]) > np.abs(lines[0].b[:, 0])
    est, use_x, ok = _better_of(tri_x, tri_y)
    assert np.array_equal(use_x, vertical) and ok.all()
    assert np.minimum(tri_x.plane_angle_deg, tri_y.plane_angle_deg).max() < 6.0
    assert np.maximum(tri_x.plane_angle_deg, tri_y.plane_angle_deg).min() > 12.0
    for tri in (tri_x, tri_y):
        assert np.array_equal(tri.ok, tri.plane_angle_deg >= ecfg.triangulate_min_plane_angle_deg)
    perp_mm, ang, along_mm = _line_errors(est, truth)
    assert perp_mm.max() < 1e-3 and ang.max() < 1e-3 and along_mm.max() < 1e-3
    # Polarity: the frame's projected normal is the dark-to-light side in every keyframe.
    for T in T_cw:
        p = project_edgelets(cam, T, est)
        inward = cam.project(se3.transform(T, CENTRE[None]))[0] - p.centre
        assert np.all(np.sum(p.normal * inward, axis=1) > 0)


def test_rendered_keyframes_give_edgelets_within_1_mm(scene, cfg):
    """Measured lines (§4.2) in rendered keyframes. Two views: centres within 1 mm of the true edge (measured
    max 0.26 mm), directions within 1.5° (measured 1.21°: an 18 px edgelet's image angle is good to ~0.2°, and
    planes meeting at 12–15° amplify that ~4×). Refined on the edgelet's four keyframe measurements (source,
    both targets, check): within 0.8° (measured 0.69°)."""
    cam, T_cw, images, truth = scene
    ecfg = cfg.edgelets
    rng = np.random.default_rng(1)
    m = [_measure(cam, T_cw[k], images[k], truth, rng, ecfg) for k in range(3)]
    assert all(x.ok.all() for x in m)
    tri_x = triangulate_edgelets(cam, T_cw[0], m[0], T_cw[1], m[1], ecfg)
    tri_y = triangulate_edgelets(cam, T_cw[0], m[0], T_cw[2], m[2], ecfg)
    est, use_x, ok = _better_of(tri_x, tri_y)
    assert ok.all() and np.array_equal(use_x, np.abs(m[0].b[:, 1]) > np.abs(m[0].b[:, 0]))
    perp_mm, ang, along_mm = _line_errors(est, truth)
    assert perp_mm.max() < 1.0 and ang.max() < 1.5 and along_mm.max() < 5.0, (perp_mm, ang, along_mm)
    check = verify_edgelets(cam, T_cw[3], images[3], est, ecfg)
    assert check.ok.all() and check.distance_px.max() < 0.3, check.distance_px
    # A hypothesis at the wrong depth (10 cm further along the source ray: 3-4 px off in the check view) fails.
    C0 = se3.inv(T_cw[0])[:3, 3]
    ray = (est.centre - C0) / np.linalg.norm(est.centre - C0, axis=1, keepdims=True)
    wrong = Edgelets(est.centre + 0.1 * ray, est.direction, est.normal)
    assert not verify_edgelets(cam, T_cw[3], images[3], wrong, ecfg).ok.any()
    n = len(truth)
    obs = EdgeletObservations(
        np.repeat(np.arange(4), n),
        np.tile(np.arange(n), 4),
        np.concatenate([x.a for x in m] + [check.measurement.a]),
        np.concatenate([x.b for x in m] + [check.measurement.b]),
    )
    refined = refine_edgelets(cam, T_cw, est, obs, ecfg, 5)
    perp_mm, ang, _ = _line_errors(refined, truth)
    assert perp_mm.max() < 0.5 and ang.max() < 0.8, (perp_mm, ang)


def test_line_planes_contain_the_true_line(scene, cfg):
    """Each measured line's back-projected plane passes within 0.5 mm of the true edge's points."""
    cam, T_cw, images, truth = scene
    rng = np.random.default_rng(2)
    for k in range(4):
        m = measure_in_keyframe(images[k], *_predict(cam, T_cw[k], truth, rng), cfg.edgelets)
        assert m.ok.all()
        normal, offset = line_planes(cam, T_cw[k], m.a, m.b)
        assert np.allclose(np.linalg.norm(normal, axis=1), 1.0)
        assert np.abs(np.sum(normal * truth.centre, axis=1) - offset).max() < 0.5e-3
        assert np.abs(np.sum(normal * truth.direction, axis=1)).max() < np.sin(np.deg2rad(0.3))
        assert np.all(np.sum(perp(m.b) * _predict(cam, T_cw[k], truth, rng)[2], axis=1) > 0)
