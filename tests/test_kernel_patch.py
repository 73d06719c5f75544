"""Patch kernels (template warping, zero-mean SSD search, inverse-compositional sub-pixel) vs numpy references."""

import cv2
import numpy as np
import pytest

from ptam.image.pyramid import row_lut
from ptam.patch.search_kernels import search_patches
from ptam.patch.subpix_kernels import refine_subpix
from ptam.patch.template_kernels import make_templates
from tests.reference.search import search_patches_ref
from tests.reference.subpix import refine_subpix_ref
from tests.reference.template import make_templates_ref

SIZE = 8


def _texture(rng, h, w, blur):
    img = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)).astype(np.float32), (0, 0), blur)
    img = (img - img.min()) / (img.max() - img.min()) * 255.0
    return img.astype(np.uint8)


def _pyramid(rng):
    levels = tuple(_texture(rng, 240 >> L, 320 >> L, 1.5) for L in range(3))
    corners, luts = [], []
    for im in levels:
        k = im.size // 20
        xy = np.stack([rng.integers(0, im.shape[1], k), rng.integers(0, im.shape[0], k)], axis=1)
        xy = np.unique(xy[:, ::-1], axis=0)[:, ::-1].astype(np.int32)  # sorted by y then x
        corners.append(xy)
        luts.append(row_lut(xy, im.shape[0]))
    return levels, tuple(corners), tuple(luts)


def _window(img, xy):
    """The zero-mean 8x8 window whose centre pixel (PTAM's convention: x - 4 ... x + 3) is ``xy``."""
    x, y = xy
    win = img[y - SIZE // 2 : y + SIZE // 2, x - SIZE // 2 : x + SIZE // 2].astype(np.float64)
    return win - win.mean()


def test_make_templates_matches_reference():
    rng = np.random.default_rng(0)
    kf_images = tuple(np.stack([_texture(rng, 120 >> L, 160 >> L, 1.0) for _ in range(3)]) for L in range(3))
    n = 500
    level = rng.integers(0, 3, n).astype(np.int8)
    kf = rng.integers(0, 3, n).astype(np.int32)
    wh = np.array([[160 >> int(L), 120 >> int(L)] for L in level], dtype=np.float64)
    xy = rng.uniform(0.0, 1.0, (n, 2)) * (wh - 1)
    M = rng.normal(size=(n, 2, 2)) * 0.7 + np.eye(2)
    t, ok = make_templates(kf_images, kf, level, xy, M, SIZE)
    t_r, ok_r = make_templates_ref(kf_images, kf, level, xy, M, SIZE)
    assert np.array_equal(ok, ok_r) and 50 < ok.sum() < n
    assert np.allclose(t[ok], t_r[ok], atol=1e-3)
    assert np.abs(t[ok].mean(axis=(1, 2))).max() < 1e-3
    # Identity warp at an integer pixel copies the image window [x - 4, x + 3].
    img = kf_images[0][1]
    t1, ok1 = make_templates(
        kf_images, np.array([1], np.int32), np.array([0], np.int8), np.array([[50.0, 40.0]]), np.eye(2)[None], SIZE
    )
    win = img[36:44, 46:54].astype(np.float64)
    assert ok1[0] and np.allclose(t1[0], win - win.mean(), atol=1e-3)


@pytest.mark.parametrize("flat_fraction", [np.inf, 1.0])
def test_search_patches_matches_reference_and_finds_the_source(flat_fraction):
    rng = np.random.default_rng(1)
    levels, corners, luts = _pyramid(rng)
    n = 400
    level = rng.integers(0, 3, n).astype(np.int32)
    pick = np.array([rng.integers(0, len(corners[L])) for L in level])
    truth = np.array([corners[L][j] for L, j in zip(level, pick)])
    # Templates cut from the image at the true corner.
    kf_images = tuple(im[None] for im in levels)
    t, ok = make_templates(
        kf_images,
        np.zeros(n, np.int32),
        level.astype(np.int8),
        truth.astype(np.float64),
        np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
        SIZE,
    )
    center = truth + rng.integers(-4, 5, (n, 2))
    radius = np.full(n, 6, np.int32)
    max_ssd = 500.0 * SIZE * SIZE
    args = (t, level, center.astype(np.int32), radius, max_ssd, flat_fraction)
    best, score, found = search_patches(levels, corners, luts, *args)
    best_r, score_r, found_r = search_patches_ref(levels, corners, *args)
    # The kernel sums in float32 (exact for ΣI and ΣI², rounded in ΣI·T): scores agree to a fraction of a grey
    # level squared, so acceptance may differ only right at the threshold.
    energy = (t.astype(np.float64) ** 2).sum(axis=(1, 2))
    limit = np.minimum(max_ssd, flat_fraction * energy) if np.isfinite(flat_fraction) else np.full(n, max_ssd)
    clear = np.abs(score_r - limit) > 1.0
    assert np.array_equal(found[clear], found_r[clear])
    both = found & found_r
    assert np.allclose(score[both], score_r[both], rtol=1e-5, atol=0.5)
    assert np.array_equal(best[both], best_r[both])
    inside = ok & (((truth - center) ** 2).sum(axis=1) <= 36)
    assert inside.sum() > 200
    assert np.array_equal(best[inside], truth[inside]) and np.all(score[inside] < 0.5)


def test_a_faint_template_is_found_at_its_source_but_not_in_unrelated_texture():
    """A template fainter than PTAM's absolute limit (grey-level std 12, 144 < 500 per pixel) matches any
    corner of similar faintness under that limit alone; below its own energy (what a flat window scores) only
    its source passes."""
    rng = np.random.default_rng(3)
    img = np.clip(128 + rng.normal(0, 12, (120, 160)), 0, 255).astype(np.uint8)
    ys, xs = np.mgrid[8:112:3, 8:152:3]
    corners = np.stack([xs.ravel(), ys.ravel()], axis=1).astype(np.int32)
    levels, corners_t, luts = (img,), (corners,), (row_lut(corners, img.shape[0]),)
    source = corners[len(corners) // 2]
    n = 200
    other = np.clip(128 + rng.normal(0, 12, (n, SIZE, SIZE)), 0, 255)
    templates = np.concatenate([_window(img, source)[None], other - other.mean(axis=(1, 2), keepdims=True)])
    templates = templates.astype(np.float32)
    center = np.broadcast_to(source, (n + 1, 2)).astype(np.int32).copy()
    args = (templates, np.zeros(n + 1, np.int32), center, np.full(n + 1, 12, np.int32), 500.0 * SIZE * SIZE)
    _, _, ptam_found = search_patches(levels, corners_t, luts, *args, np.inf)
    best, score, found = search_patches(levels, corners_t, luts, *args, 1.0)
    assert ptam_found[0] and found[0] and np.array_equal(best[0], source) and score[0] < 0.5
    assert ptam_found[1:].mean() > 0.9  # the unrelated templates: chance matches under the absolute limit
    assert not found[1:].any()


def test_refine_subpix_matches_reference_and_recovers_shifts():
    rng = np.random.default_rng(2)
    levels, _, _ = _pyramid(rng)
    n = 300
    level = rng.integers(0, 2, n).astype(np.int32)
    wh = np.array([levels[L].shape[::-1] for L in level])
    truth = rng.uniform(0.0, 1.0, (n, 2)) * (wh - 24) + 12
    # Templates sampled at the sub-pixel truth (identity warp) with a brightness offset of up to 20 levels.
    kf_images = tuple(im[None] for im in levels)
    t, ok = make_templates(
        kf_images,
        np.zeros(n, np.int32),
        level.astype(np.int8),
        truth,
        np.broadcast_to(np.eye(2), (n, 2, 2)).copy(),
        SIZE,
    )
    t = t + rng.uniform(-20.0, 20.0, (n, 1, 1)).astype(np.float32)
    start = np.rint(truth) + rng.integers(-1, 2, (n, 2))
    xy, conv = refine_subpix(levels, t, level, start, 10, 0.03)
    xy_r, conv_r = refine_subpix_ref(levels, t, level, start, 10, 0.03)
    assert np.array_equal(conv, conv_r)
    assert np.allclose(xy[conv], xy_r[conv], atol=1e-6)
    assert conv.mean() > 0.9
    err = np.linalg.norm(xy[conv] - truth[conv], axis=1)
    assert np.median(err) < 0.05 and np.percentile(err, 90) < 0.15
    # Off the image edge: not converged.
    edge, conv_e = refine_subpix(levels, t[:1], level[:1], np.array([[1.0, 1.0]]), 10, 0.03)
    assert not conv_e[0]
