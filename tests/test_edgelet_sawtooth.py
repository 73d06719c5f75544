"""Agility §5.1–§5.2: the blur-matched sawtooth search and the per-edgelet visibility table."""

import cv2
import numpy as np
import pytest

from ptam.camera import PinholeCamera
from ptam.edgelet.edge_sample_kernels import ramp_weights
from ptam.edgelet.sawtooth import build_visibility_table, search_edgelets, table_blurs
from ptam.edgelet.sawtooth_kernels import sawtooth_search, visibility_table
from ptam.synthetic.rectangle import Rectangle
from ptam.synthetic.render import Renderer
from tests.reference.edgelet_measure import ramp_weights_ref
from tests.reference.edgelet_sawtooth import sawtooth_search_ref, visibility_table_ref
from tests.reference.edgelet_scenes import edge_image

LO, HI = 50, 170  # grey levels either side of the test edges: contrast 120


@pytest.fixture(scope="module")
def ecfg(cfg):
    return cfg.edgelets


def _texture(rng, h, w):
    img = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), 3.0)
    return ((img - img.min()) / (img.max() - img.min()) * 255.0).astype(np.uint8)


def test_sawtooth_taps():
    w = np.empty(80)
    for length in (2.0, 3.0, 4.5, 10.0, 37.3, 65.0):
        h = ramp_weights(length, w)
        ref, h_ref = ramp_weights_ref(length)
        assert h == h_ref and np.allclose(w[: 2 * h + 1], ref)
        assert np.allclose(ref, -ref[::-1])  # zero mean, antisymmetric
        # A ramp of contrast C exactly filling the kernel responds with C.
        assert np.isclose(np.dot(ref, np.arange(-h, h + 1) * (100.0 / length)), 100.0)
    assert np.allclose(ramp_weights_ref(2.0)[0], [-1.0, 0.0, 1.0])  # no blur: a central difference


def test_search_kernel_matches_reference_on_random_data():
    rng = np.random.default_rng(0)
    img = _texture(rng, 120, 160)
    n = 400
    c = rng.uniform([-5, -5], [165, 125], (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    nrm = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.5, 2.0, (n, 1))
    blur, radius, tmin = rng.uniform(0, 70, n), rng.uniform(0, 25, n), rng.uniform(0, 20, n)
    got = sawtooth_search(img, c, nrm, blur, radius, tmin, 2.0, 65.0)
    ref = sawtooth_search_ref(img, c, nrm, blur, radius, tmin, 2.0, 65.0)
    assert np.array_equal(got[2], ref[2]) and 50 < got[2].sum() < n
    assert np.allclose(got[0], ref[0], atol=1e-9) and np.allclose(got[1], ref[1], atol=1e-9)


@pytest.mark.parametrize("blur", [5, 10, 20, 30, 40])
@pytest.mark.parametrize("angle_deg", [0.0, 40.0])
def test_finds_box_blurred_edges_within_0_3_px(ecfg, blur, angle_deg):
    """A straight edge motion-blurred by a box of ``blur`` px at ``angle_deg`` to its normal, 1 grey level of
    noise: searched from ±6 px off with the expected blur l = blur·cos(angle) (eq. 10), the edge centre is found
    within 0.3 px (measured max: 0.12 px)."""
    rng = np.random.default_rng(blur + int(angle_deg))
    errors = []
    for k in range(8):
        a = rng.uniform(0, 2 * np.pi)
        n = np.array([np.cos(a), np.sin(a)])
        u = np.array([np.cos(a + np.deg2rad(angle_deg)), np.sin(a + np.deg2rad(angle_deg))])
        p0 = np.array([100.0, 80.0]) + rng.uniform(-1, 1, 2)
        img = edge_image(200, 160, p0, n, LO, HI, blur=blur, blur_dir=u, noise=1.0, seed=k)
        off = rng.uniform(-6, 6)
        c = p0 + off * n + rng.uniform(-5, 5) * np.array([n[1], -n[0]])
        l = np.array([blur * abs(n @ u)])
        r = search_edgelets(img, c[None], n[None], l, np.array([10.0]), np.array([20.0]), ecfg)
        assert r.found[0]
        assert abs(r.response[0] - (HI - LO)) < 0.2 * (HI - LO)  # about the contrast (short ramps: pixel blur)
        errors.append(abs(r.offset[0] + off))
    assert max(errors) < 0.3, errors


def test_rendered_motion_blur_is_found(ecfg):
    """The synthetic renderer's own motion blur (mean over sub-frame poses): a bright card's vertical edge with
    the camera sliding 20 px sideways during the exposure."""
    cam = PinholeCamera(160, 120, 200.0, 200.0, 79.5, 59.5)
    card = Rectangle(
        "card",
        np.array([0.013, -2.0, 2.0]),
        np.array([1.0, 0, 0]),
        np.array([0, 1.0, 0]),
        (4.0, 4.0),
        {"type": "constant", "value": 170.0},
    )
    z, shift_px = 2.0, 20.0
    xs = np.linspace(-0.5, 0.5, 81) * shift_px * z / cam.fx  # camera x positions during the exposure
    poses = np.stack([np.eye(4)] * len(xs))
    poses[:, 0, 3] = xs
    img = Renderer(cam, [card], 4, 50.0).render(poses)
    edge_u = cam.cx + cam.fx * 0.013 / z  # the edge's mean image column
    for start in (-5.0, 3.0):
        c = np.array([[edge_u + start, 60.0]])
        r = search_edgelets(
            img, c, np.array([[1.0, 0.0]]), np.array([shift_px]), np.array([10.0]), np.array([20.0]), ecfg
        )
        assert r.found[0] and abs(r.offset[0] + start) < 0.3, r.offset[0] + start


def test_polarity_and_proximity(ecfg):
    n = np.array([1.0, 0.0])
    img = edge_image(200, 160, [100.0, 80.0], n, LO, HI, blur=10)
    args = (np.array([10.0]), np.array([12.0]), np.array([20.0]), ecfg)
    assert not search_edgelets(img, np.array([[100.0, 80.0]]), -n[None], *args).found[0]
    # Two dark-to-light steps 14 px apart (x = 93 and 107), both within the search radius: the nearer one wins.
    stairs = edge_image(200, 160, [93.0, 80.0], n, 0, 60).astype(int) + edge_image(200, 160, [107.0, 80.0], n, 40, 110)
    stairs = np.clip(stairs, 0, 255).astype(np.uint8)
    for start, expect in ((101.0, 6.0), (99.0, -6.0)):
        c = np.array([[start, 80.0]])
        r = search_edgelets(stairs, c, n[None], np.array([2.0]), np.array([12.0]), np.array([20.0]), ecfg)
        assert r.found[0] and abs(r.offset[0] - expect) < 0.2, r.offset


def test_visibility_kernel_matches_reference_on_random_data():
    rng = np.random.default_rng(5)
    img = _texture(rng, 160, 200)
    n = 60
    c = rng.uniform([-3, -3], [203, 163], (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    nrm = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    blurs = np.arange(3, 66, 2)
    args = (blurs, 20, 1.0, 0.5, 0.5, 2.0, 65.0)
    got = visibility_table(img, c, nrm, *args)
    ref = visibility_table_ref(img, c, nrm, *args)
    assert np.array_equal(got[0], ref[0]) and 0 < got[0].sum() < got[0].size
    for g, r in zip(got[1:], ref[1:]):
        assert np.allclose(g, r, atol=1e-9)


def test_visibility_table_of_a_lone_edge_and_of_a_staircase(ecfg):
    n = np.array([1.0, 0.0])
    lone = edge_image(260, 120, [130.0, 60.0], n, LO, HI, noise=1.0)
    t = build_visibility_table(lone, np.array([[130.0, 60.0]]), n[None], ecfg)
    assert np.array_equal(t.blurs, table_blurs(ecfg)) and t.blurs[0] == 3 and t.blurs[-1] == 65
    assert t.visible.all() and t.max_blur[0] == 65  # nothing nearby: found under every blur
    assert np.allclose(t.t_min, 0.5 * (HI - LO), rtol=0.05)  # t_min = 0.5 t_max, t_max the contrast
    assert np.all(t.r_search == ecfg.table_max_search_px)  # no rival maximum: the cap
    # Two dark-to-light steps 12 px apart: at small blur the rival is 12 px away (r_search = 6 px); once the
    # blur is comparable to their spacing they merge into one ramp whose maximum lies between them.
    stairs = edge_image(260, 120, [124.0, 60.0], n, 0, 60).astype(int) + edge_image(260, 120, [136.0, 60.0], n, 40, 110)
    stairs = np.clip(stairs, 0, 255).astype(np.uint8)
    t = build_visibility_table(stairs, np.array([[124.0, 60.0]]), n[None], ecfg)
    assert t.visible[0, 0] and abs(t.r_search[0, 0] - 6.0) <= 0.5
    assert 5 <= t.max_blur[0] <= 25 and not t.visible[0, -1]
    k = int(np.searchsorted(t.blurs, t.max_blur[0]))
    assert t.visible[0, : k + 1].all() and not t.visible[0, k + 1 :].any()  # visible up to the maximum blur only
    vis, rs, tm = t.lookup(np.array([1.0]))
    assert vis[0] and rs[0] == t.r_search[0, 0] and tm[0] == t.t_min[0, 0]
    assert not t.lookup(np.array([t.max_blur[0] + 1.0]))[0][0] and not t.lookup(np.array([80.0]))[0][0]


def test_unusable_search_parameters_are_handled(ecfg):
    """Unknown blur: searched as the longest. No usable radius, or a search window leaving the image: not found."""
    n = np.array([1.0, 0.0])
    img = edge_image(200, 160, [100.0, 80.0], n, LO, HI, blur=65)
    c = np.array([[97.0, 80.0]] * 5)
    blur = np.array([np.nan, np.inf, 65.0, 65.0, 65.0])
    radius = np.array([10.0, 10.0, np.nan, 1e12, 30.0])
    r = search_edgelets(img, c, np.tile(n, (5, 1)), blur, radius, np.full(5, 20.0), ecfg)
    assert np.array_equal(r.found, [True, True, False, False, True])
    assert np.all(np.abs(r.offset[r.found] - 3.0) < 0.3)
