"""Agility §4.3's epipolar search for edgelets: the runs of maximal edgels a rasterised epipolar curve crosses."""

import numpy as np

from ptam.mapping.edgelet_epipolar_kernels import curve_hits
from tests.reference.edgelet_epipolar import curve_hits_ref


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
