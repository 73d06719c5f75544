"""Acceptance: the AR grid lands where the camera model, the pose and the plane put it (PTAM §7.5).

Ground-truth poses of the synthetic two-wall sequence, the AR plane set to the true wall (y = 0, +z towards the
camera), a grid over the whole view. The grid vertices the renderer draws are (1) the exact projections of the
true 3-D vertices, and (2) in the rendered image — detected from the drawn lines alone — within 0.5 px of where
the synthetic ray caster (which goes through ``unproject``, not ``project``) sees the true vertices, including
near the image border where the FOV lens moves points by tens of pixels.
"""

import numpy as np
import pytest

from ptam.ar import Augmenter
from ptam.camera import PinholeCamera
from ptam.config import load_config
from ptam.geometry import se3
from ptam.synthetic import load_scene

FRAMES = (0, 70, 140)
SPACING_M = 0.4
HALF_CELLS = 15
ORIGIN = np.array([-10.5, 0.0, 3.0])  # on the wall, in front of the first frames
R_PW = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # plane x = world x, y = up, z = -y
T_PW = se3.from_Rt(R_PW, -R_PW @ ORIGIN)
BORDER_PX = 40


@pytest.fixture(scope="module")
def scene():
    return load_scene("two_wall_short")


@pytest.fixture(scope="module")
def rendered(scene):
    cfg = load_config().replace(**{"ar.grid_spacing": SPACING_M, "ar.grid_half_cells": HALF_CELLS})
    aug = Augmenter(scene.camera, cfg, "grid", T_PW)
    out = []
    black = np.zeros((scene.camera.height, scene.camera.width), np.uint8)
    for i in FRAMES:
        T_cw = se3.inv(scene.poses_T_wc[i])
        img = aug.augment(black, T_cw, scene.timestamps[i])
        out.append((i, T_cw, img[..., 0].astype(np.float64), aug.renderer.last_grid))
    return aug.renderer.grid, out


def _world_vertices(grid):
    return grid.vertices @ R_PW + ORIGIN  # plane (x, y, 0) -> world


def test_renderer_vertices_are_the_exact_projections(scene, rendered):
    grid, frames = rendered
    cam = scene.camera
    pin = PinholeCamera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy)
    Xw = _world_vertices(grid)
    for i, T_cw, _, pg in frames:
        Xc = np.array([T_cw[:3, :3] @ X + T_cw[:3, 3] for X in Xw])  # one point at a time, from the world
        uv = cam.project(Xc)
        inside = cam.in_image(uv) & (Xc[:, 2] > 0)
        assert np.array_equal(pg.vertex_ok[inside], np.ones(inside.sum(), bool))
        err = np.abs(pg.vertex_uv[inside] - uv[inside]).max()
        distortion = np.linalg.norm(uv - pin.project(Xc), axis=1)
        near = inside & ~cam.in_image(uv, BORDER_PX)
        print(
            f"frame {i}: {inside.sum()} vertices in view, max |renderer - project| {err:.2e} px; "
            f"{near.sum()} within {BORDER_PX} px of the border, lens moves them {distortion[near].min():.0f}-"
            f"{distortion[near].max():.0f} px"
        )
        assert err < 1e-6
        assert near.sum() >= 20 and distortion[near].max() > 60


def _line_points(img, p, d, normal_axis):
    """Sub-pixel crossings of a drawn line with pixel rows (normal_axis 0 → along x in each row) or columns,
    3..7 px either side of the vertex p along the line direction d: intensity centroids over a ±4 px window."""
    pts = []
    for s in (-7, -6, -5, -4, -3, 3, 4, 5, 6, 7):
        c = p + s * d / np.abs(d[1 - normal_axis])  # step one row (or column) at a time
        fixed = int(round(c[1 - normal_axis]))
        c = p + (fixed - p[1 - normal_axis]) / d[1 - normal_axis] * d
        lo = int(round(c[normal_axis])) - 4
        idx = np.arange(lo, lo + 9)
        prof = img[fixed, idx] if normal_axis == 0 else img[idx, fixed]
        if prof.sum() <= 0:
            return None
        pos = (prof * idx).sum() / prof.sum()
        pts.append((pos, fixed) if normal_axis == 0 else (fixed, pos))
    return np.array(pts, np.float64)


def _fit_line(pts):
    m = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - m)
    return m, vt[0]


def _intersect(l1, l2):
    (m1, d1), (m2, d2) = l1, l2
    a = np.array([d1, -d2]).T
    s = np.linalg.solve(a, m2 - m1)
    return m1 + s[0] * d1


def _detect(img, uv, n):
    """Detected vertex positions (V, 2) (NaN where not measurable) from the drawn image, guided by the
    approximate line directions between neighbouring vertices."""
    grid_uv = uv.reshape(n, n, 2)
    out = np.full((n * n, 2), np.nan)
    H, W = img.shape
    for i in range(1, n - 1):
        for j in range(1, n - 1):
            p = grid_uv[i, j]
            neigh = np.stack([grid_uv[i, j - 1], grid_uv[i, j + 1], grid_uv[i - 1, j], grid_uv[i + 1, j]])
            if not (np.all(np.isfinite(neigh)) and 12 <= p[0] <= W - 13 and 12 <= p[1] <= H - 13):
                continue
            if np.linalg.norm(neigh - p, axis=1).min() < 18:  # cells too small to isolate the crossing
                continue
            d_x = grid_uv[i, j + 1] - grid_uv[i, j - 1]  # the line along plane x (mostly horizontal)
            d_y = grid_uv[i + 1, j] - grid_uv[i - 1, j]  # the line along plane y (mostly vertical)
            a = _line_points(img, p, d_x / np.linalg.norm(d_x), 1)
            b = _line_points(img, p, d_y / np.linalg.norm(d_y), 0)
            if a is None or b is None:
                continue
            out[i * n + j] = _intersect(_fit_line(a), _fit_line(b))
    return out


def _pixel_error_by_raycast(scene, T_wc, q, X_true):
    """Pixel offset from q to the true vertex, from the synthetic ray caster's surface points around q."""
    h = 0.5
    probes = np.concatenate([q, q + [h, 0], q - [h, 0], q + [0, h], q - [0, h]])
    X, _, hit = scene.raycast(T_wc, probes)
    n = len(q)
    X = X.reshape(5, n, 3)
    J = np.stack([(X[1] - X[2]) / (2 * h), (X[3] - X[4]) / (2 * h)], axis=2)  # (n, 3, 2) metres per pixel
    delta = np.array([np.linalg.lstsq(J[k], X_true[k] - X[0, k], rcond=None)[0] for k in range(n)])
    return delta, hit.reshape(5, n).all(axis=0)


def test_drawn_grid_vertices_within_half_a_pixel_of_the_truth(scene, rendered):
    grid, frames = rendered
    n = grid.n_lines_per_axis
    Xw = _world_vertices(grid)
    errs, border_errs = [], []
    for i, T_cw, img, pg in frames:
        uv = np.where(pg.vertex_ok[:, None], pg.vertex_uv, np.nan)
        found = _detect(img, uv, n)
        ok = np.all(np.isfinite(found), axis=1)
        delta, hit = _pixel_error_by_raycast(scene, se3.inv(T_cw), found[ok], Xw[ok])
        e = np.linalg.norm(delta[hit], axis=1)
        near = ~scene.camera.in_image(found[ok][hit], BORDER_PX)
        errs.append(e)
        border_errs.append(e[near])
        print(
            f"frame {i}: {len(e)} vertices detected, error median {np.median(e):.3f} px, max {e.max():.3f} px; "
            f"{near.sum()} within {BORDER_PX} px of the border, max {e[near].max():.3f} px"
        )
    e, eb = np.concatenate(errs), np.concatenate(border_errs)
    assert len(e) >= 300 and len(eb) >= 40
    assert e.max() < 0.5 and eb.max() < 0.5


def test_a_grey_frame_with_the_grid_alone_is_drawn_grey_with_the_same_pixels(scene):
    """``grey_ok``: the white grid over a grey frame is drawn in one channel, equal to each channel of the BGR
    drawing; anything coloured (the game) is drawn in BGR as without it (its grid still drawn grey first)."""
    rng = np.random.default_rng(5)
    frame = rng.integers(0, 256, (scene.camera.height, scene.camera.width), dtype=np.uint8)
    cfg = load_config().replace(**{"ar.grid_spacing": SPACING_M, "ar.grid_half_cells": HALF_CELLS})
    for name, grey_shape in (("grid", frame.shape), ("game", (*frame.shape, 3))):
        bgr_aug, grey_aug = Augmenter(scene.camera, cfg, name, T_PW), Augmenter(scene.camera, cfg, name, T_PW)
        for i in FRAMES:
            T_cw = se3.inv(scene.poses_T_wc[i])
            bgr = bgr_aug.augment(frame, T_cw, scene.timestamps[i])
            grey = grey_aug.augment(frame, T_cw, scene.timestamps[i], grey_ok=True)
            assert bgr.shape == (*frame.shape, 3) and grey.shape == grey_shape
            drawn = np.count_nonzero(bgr[..., 0] != frame)
            assert drawn > 5000  # the overlay is there
            if name == "grid":
                for c in range(3):
                    assert np.array_equal(bgr[..., c], grey)
            else:
                assert np.array_equal(bgr, grey)
            assert np.isinf(grey_aug.renderer.zbuf).all()  # emptied where the spheres wrote it, for the next frame
