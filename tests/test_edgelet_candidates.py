"""Agility §4.3: candidate edgelets from Canny edges, linked, broken at corners, cut to edgelet length, measured."""

import cv2
import numpy as np
import pytest

from ptam.edgelet.edgel_linker_kernels import link_edgels, split_chains
from ptam.edgelet.edgelet_candidates import (
    canny_edges,
    extract_candidates,
    gradient_at,
    maximal_edgels,
    segment_edgels,
    smoothed,
)
from ptam.errors import InputError
from tests.reference.edge_gradient import sobel_at_ref
from tests.reference.edgel_linker import link_edgels_ref, split_chains_ref
from tests.reference.edgelet_scenes import polygon_edges, polygon_image

BACKGROUND = 70


def _rect(c, w, h, deg):
    a = np.deg2rad(deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]]) @ R.T + c


@pytest.fixture(scope="module")
def shapes():
    """Four shapes at assorted angles, brighter and darker than the background, 1.5 grey levels of noise."""
    polys = [
        _rect([110, 100], 120, 80, 20),
        np.array([[230.3, 40.2], [300.1, 170.7], [190.6, 150.2]]),
        _rect([240, 235], 90, 50, -35),
        _rect([80, 230], 60, 60, 5),
    ]
    greys = [190, 120, 15, 230]
    img = polygon_image(320, 300, polys, greys, BACKGROUND, noise=1.5)
    return img, *polygon_edges(polys, greys, BACKGROUND)


def _nearest_edge(p, segs):
    a, ab = segs[:, 0], segs[:, 1] - segs[:, 0]
    t = np.clip(np.sum((p[:, None] - a[None]) * ab[None], -1) / np.sum(ab * ab, -1)[None], 0, 1)
    d = np.linalg.norm(p[:, None] - (a[None] + t[..., None] * ab[None]), axis=-1)
    j = np.argmin(d, axis=1)
    return j, d[np.arange(len(j)), j]


def test_linker_kernels_match_references(shapes, cfg):
    img = shapes[0]
    ecfg = cfg.edgelets
    rng = np.random.default_rng(0)
    noisy = np.clip(img + rng.normal(0, 12, img.shape), 0, 255).astype(np.uint8)  # ragged edges, junctions
    for image in (img, noisy):
        edges = canny_edges(smoothed(image, ecfg), ecfg)
        pts, starts = link_edgels(edges)
        pts_r, starts_r = link_edgels_ref(edges)
        assert np.array_equal(pts, pts_r) and np.array_equal(starts, starts_r)
        assert len(pts) == np.count_nonzero(edges)  # every edgel in exactly one chain
        steps = np.abs(np.diff(pts, axis=0)).max(axis=1)
        inner = np.ones(len(pts) - 1, bool)
        inner[starts[1:-1] - 1] = False
        assert np.all(steps[inner] == 1)  # consecutive chain points are 8-neighbours
        got = split_chains(pts, starts, 18.0, 4, np.cos(np.deg2rad(25.0)))
        ref = split_chains_ref(pts, starts, 18.0, 4, np.cos(np.deg2rad(25.0)))
        assert len(got[0]) == len(ref[0]) > 10
        assert np.allclose(got[0], ref[0]) and np.allclose(got[2], ref[2])
        assert np.allclose(np.abs(np.sum(got[1] * ref[1], axis=1)), 1.0)
    # A view that is not contiguous, of a size that is no multiple of eight pixels (the edgel scan's words).
    wide = np.zeros((edges.shape[0], edges.shape[1] + 5), np.uint8)
    wide[:, : edges.shape[1]] = edges
    wide[-1, -9:-5] = 255  # edgels among the last pixels, after the last whole word
    crop = wide[1:, 3:-5]
    assert not crop.flags.c_contiguous and crop.size % 8 > 4
    pts, starts = link_edgels(crop)
    pts_r, starts_r = link_edgels_ref(crop)
    assert np.array_equal(pts, pts_r) and np.array_equal(starts, starts_r) and len(pts) == np.count_nonzero(crop)


def test_chains_break_at_corners(cfg):
    """An L of two straight 60 px arms: the linker yields one chain, split at the corner into straight pieces."""
    edges = np.zeros((100, 100), np.uint8)
    edges[20, 20:80] = 255
    edges[20:80, 79] = 255
    pts, starts = link_edgels(edges)
    assert len(starts) == 2
    c, d, dev = segment_edgels(edges, cfg.edgelets)
    assert len(c) == 6 and dev.max() < 0.6  # three 18 px segments per arm, none spanning the corner
    horizontal = np.abs(d[:, 0]) > 0.99
    assert horizontal.sum() == 3 and np.all(np.abs(d[~horizontal, 1]) > 0.99)


def test_candidates_lie_on_the_true_edges(shapes, cfg):
    """≥ 90 % of the candidates within 1 px and 3° of a true edge with the right polarity (measured: all, within
    0.06 px and 0.6°), and nearly as many as the edges have room for (measured 62 of 65)."""
    img, segs, normals = shapes
    cand = extract_candidates(img, cfg.edgelets)
    j, dist = _nearest_edge(cand.centre, segs)
    tangent = (segs[j, 1] - segs[j, 0]) / np.linalg.norm(segs[j, 1] - segs[j, 0], axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(tangent * cand.direction, axis=1)), 0, 1)))
    polarity = np.sum(cand.normal * normals[j], axis=1) > 0
    good = (dist < 1.0) & (ang < 3.0) & polarity
    assert good.mean() >= 0.9, (good.mean(), dist.max(), ang.max())
    room = np.floor(np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1) / cfg.edgelets.length_px)
    assert 0.8 * room.sum() <= len(cand) <= room.sum()
    per_edge = np.bincount(j, minlength=len(segs))
    assert np.all(per_edge <= room) and np.all(per_edge >= room - 1)  # every edge is covered
    assert np.all(cand.rms <= cfg.edgelets.measure_max_rms_px)


def test_candidates_near_existing_edgelets_are_rejected(shapes, cfg):
    img = shapes[0]
    ecfg = cfg.edgelets
    everything = extract_candidates(img, ecfg)
    existing = everything.centre[::2] + 2.0  # every other candidate is (nearly) in the map already
    fewer = extract_candidates(img, ecfg, existing)
    assert len(fewer) == len(everything) - len(existing)
    d = np.linalg.norm(fewer.centre[:, None] - existing[None], axis=-1).min(axis=1)
    assert d.min() >= ecfg.candidate_min_distance_px
    assert len(extract_candidates(img, ecfg, np.zeros((0, 2)))) == len(everything)


def test_maximal_edgels_include_the_linked_ones(shapes, cfg):
    img = shapes[0]
    faint = cv2.addWeighted(img, 0.2, np.full_like(img, BACKGROUND), 0.8, 0)  # contrast below the high threshold
    sm = smoothed(faint, cfg.edgelets)
    edges, maximal = canny_edges(sm, cfg.edgelets), maximal_edgels(sm, cfg.edgelets)
    assert np.all(maximal[edges > 0] > 0) and np.count_nonzero(maximal) > np.count_nonzero(edges)
    with pytest.raises(InputError):
        extract_candidates(img.astype(np.float32), cfg.edgelets)


def test_gradient_kernel_matches_reference_and_opencv(shapes):
    """The Sobel gradient at points: at pixel centres, halfway between pixels (rounded half to even) and outside
    the image (moved in by a pixel), as the numpy reference and cv2.Sobel have it."""
    img = shapes[0]
    H, W = img.shape
    rng = np.random.default_rng(1)
    xy = np.concatenate(
        [
            rng.uniform([-3, -3], [W + 2, H + 2], (500, 2)),
            rng.integers(0, [W, H], (200, 2)) + 0.5,
            np.array([[0.0, 0.0], [W - 1.0, H - 1.0], [-50.0, H / 2], [W / 2, H + 50.0]]),
        ]
    )
    got = gradient_at(img, xy)
    assert np.array_equal(got, sobel_at_ref(img, xy))
    ix = np.clip(np.round(xy[:, 0]).astype(int), 1, W - 2)
    iy = np.clip(np.round(xy[:, 1]).astype(int), 1, H - 2)
    gx, gy = cv2.Sobel(img, cv2.CV_64F, 1, 0, ksize=3), cv2.Sobel(img, cv2.CV_64F, 0, 1, ksize=3)
    assert np.array_equal(got, np.stack([gx[iy, ix], gy[iy, ix]], axis=-1))
    assert np.abs(got).max() > 100  # the shapes' edges are in it
