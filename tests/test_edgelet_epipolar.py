"""Agility §4.3's epipolar search for edgelets: the runs of maximal edgels a rasterised epipolar curve crosses, and
the culls of those matches by polarity and crossing angle."""

import numpy as np
import pytest

from ptam.edgelet.edgelet import perp
from ptam.edgelet.edgelet_triangulation import line_rays
from ptam.geometry import se3
from ptam.mapping.edgelet_cull_kernels import polarity_cull
from ptam.mapping.edgelet_epipolar_kernels import curve_hits, curve_vertices
from tests.reference.edgelet_epipolar import curve_hits_ref, curve_vertices_ref, polarity_cull_ref
from tests.support.cameras import CAMERAS


def test_a_curve_finds_each_edge_it_crosses_once_at_its_centre():
    """A horizontal curve across five 3-px-wide vertical edge bands: five matches, each within half a sample
    step of the band's centre, with the inverse depth interpolated along the piece and the unit tangent."""
    edgels = np.zeros((120, 200), np.uint8)
    centres = [30, 61, 100, 137, 170]
    for x in centres:
        edgels[:, x - 1 : x + 2] = 255
    uv = np.array([[[10.0, 60.0], [100.0, 60.0], [190.0, 60.0]]])
    length = np.array([[90.0, 90.0]])
    inv_z = np.array([1.0, 0.5, 0.25])
    cand, pts, iz, tangent = curve_hits(uv, np.ones((1, 2), bool), length, inv_z, 0.5, edgels, 3.0)
    assert np.array_equal(cand, np.zeros(5)) and np.allclose(pts[:, 1], 60.0)
    assert np.abs(pts[:, 0] - centres).max() <= 0.5
    expect = np.interp(pts[:, 0], [10.0, 100.0, 190.0], inv_z)
    assert np.allclose(iz, expect, atol=1e-12) and np.allclose(tangent, [1.0, 0.0])


def test_a_piece_clipped_to_the_longest_length_keeps_a_unit_tangent():
    """A piece longer than ``curve_vertices``' limit has its length clipped (sampling stops there), but the
    tangent the cull compares gradients with is still the piece's unit direction."""
    edgels = np.zeros((120, 200), np.uint8)
    edgels[:, 49:52] = 255
    uv = np.array([[[10.0, 10.0], [1010.0, 1010.0]]])
    cand, pts, iz, tangent = curve_hits(uv, np.ones((1, 1), bool), np.array([[300.0]]), np.ones(2), 0.5, edgels, 3.0)
    assert len(cand) == 1 and np.allclose(tangent, [[np.sqrt(0.5), np.sqrt(0.5)]], atol=1e-12)


def test_curve_kernel_matches_reference_on_random_curves():
    """Random polylines over a random edgel image, with pieces marked invalid (no length: nothing sampled on
    them), pieces leaving the image and a border: the same matches as the numpy reference."""
    rng = np.random.default_rng(3)
    edgels = np.where(rng.random((240, 320)) < 0.08, 255, 0).astype(np.uint8)
    edgels[:, 150:153] = 255
    n, v = 60, 17
    uv = rng.uniform([-40, -40], [360, 280], (n, 1, 2)) + np.cumsum(rng.normal(0, 15, (n, v, 2)), axis=1)
    seg_ok = rng.random((n, v - 1)) > 0.15
    length = np.where(seg_ok, np.linalg.norm(np.diff(uv, axis=1), axis=2), 0.0)
    inv_z = 1.0 / np.linspace(0.3, 4.0, v)
    got = curve_hits(uv, seg_ok, length, inv_z, 0.5, edgels, 4.0)
    ref = curve_hits_ref(uv, seg_ok, length, inv_z, 0.5, edgels, 4.0)
    assert np.array_equal(got[0], ref[0]) and len(got[0]) > 500
    for g, r in zip(got[1:], ref[1:]):
        assert np.allclose(g, r, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_cull_kernel_matches_reference(name):
    """§4.3 step 4 (``polarity_cull``) against numpy on random matches: source lines all over keyframe k, depths
    from 0.2 to 5 m, a target turned so that some matches are behind it, random gradients (some zero) and curve
    tangents (some along the gradient's edge)."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(8)
    n = 2000
    T_k = se3.exp(rng.uniform(-0.2, 0.2, 6))
    T_t = se3.exp(np.array([0.3, -0.1, 0.05, 0.1, 1.2, 0.05])) @ T_k
    a = rng.uniform([20, 20], [cam.width - 20, cam.height - 20], (n, 2))
    ang = rng.uniform(0, 2 * np.pi, n)
    b = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    z = rng.uniform(0.2, 5.0, n)
    g = rng.normal(0, 50.0, (n, 2))
    g[:20] = 0.0
    tangent = rng.normal(size=(n, 2))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    tangent[20:60] = perp(g[20:60] / np.linalg.norm(g[20:60], axis=1, keepdims=True))  # along the edge
    rays = line_rays(cam, a, b)
    min_deg = 15.0
    got = polarity_cull(cam.kernel_params(), T_k, T_t, rays, z, b, g, tangent, np.sin(np.deg2rad(min_deg)))
    ref = polarity_cull_ref(cam, T_k, T_t, a, b, z, g, tangent, min_deg)
    assert np.array_equal(got, ref)
    Xt = se3.transform(T_t, se3.transform(se3.inv(T_k), rays[:, 0] * z[:, None]))
    # measured: 474-597 of the matches behind the target, 28-30 % kept
    assert (Xt[:, 2] < 0).sum() > 100 and 0.2 < got.mean() < 0.6 and not got[:60].any()


@pytest.mark.parametrize("name", list(CAMERAS))
def test_curve_vertices_match_reference(name):
    """The epipolar curves' vertices (``curve_vertices``) against numpy: rays over the whole source image, depths
    from 0.1 to 20 m, a target turned so that the near or far ends of some curves are behind it or beyond the
    lens's range (measured: 69-85 % of the pieces valid)."""
    cam = CAMERAS[name]
    rng = np.random.default_rng(4)
    a = rng.uniform([0, 0], [cam.width - 1, cam.height - 1], (300, 2))
    ray = np.concatenate([cam.unproject(a), np.ones((300, 1))], axis=1)
    z = 1.0 / np.linspace(1.0 / 0.3, 1.0 / 20.0, 9)
    T_ts = se3.exp(np.array([0.15, 0.05, -0.05, 0.05, 0.3, 0.0]))
    max_len = float(np.hypot(cam.width, cam.height))
    uv, seg_ok, length = curve_vertices(cam.kernel_params(), T_ts, ray, z, max_len)
    uv_ref, ok_ref, length_ref = curve_vertices_ref(cam, T_ts, ray, z, max_len)
    assert np.array_equal(seg_ok, ok_ref) and 0.3 < seg_ok.mean() < 0.95, seg_ok.mean()
    assert np.allclose(uv, uv_ref, rtol=1e-12, atol=1e-9) and np.allclose(length, length_ref, rtol=1e-12, atol=1e-9)
