"""The AR rasteriser's numba kernels against their numpy references, and their geometry through the lens model."""

import math

import cv2
import numpy as np
import pytest

from ptam.ar.overlay import camera_ray_table
from ptam.ar.raster_kernels import (
    BALL,
    DECAL_LEN,
    EYE,
    PLAIN,
    SPHERE_LEN,
    blend_coverage,
    draw_decals,
    draw_spheres,
    outline_boxes,
    rasterise_polylines,
)
from ptam.camera import FovCamera
from ptam.geometry import so3
from tests.reference.raster import draw_decals_ref, draw_spheres_ref, outline_boxes_ref, rasterise_polylines_ref

CAM = FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9)  # PTAM's wide-angle lens (two_wall's camera)
SHADING = np.array([0.5, 0.5, 1.0, 50.0])


@pytest.fixture(scope="module")
def rays():
    return camera_ray_table(CAM)


def _background(rng):
    return rng.integers(0, 256, (CAM.height, CAM.width, 3), dtype=np.uint8)


def _random_spheres(rng, n):
    rec = np.zeros((n, SPHERE_LEN))
    rec[:, 0:2] = rng.uniform(-1.2, 1.2, (n, 2))
    rec[:, 2] = rng.uniform(1.0, 3.0, n)
    rec[:, 3] = rng.uniform(0.05, 0.3, n)
    rec[:, 4:13] = so3.exp(rng.normal(size=(n, 3))).reshape(n, 9)
    rec[:, 13:22] = rng.uniform(0, 255, (n, 9))
    rec[:, 22] = rng.choice([PLAIN, EYE, BALL], n)
    rec[:, 23] = np.where(rec[:, 22] == BALL, 6, 0.95)
    rec[:, 24] = 0.8
    rec[:, 25] = rng.uniform(0.0, 1.0, n)
    return rec


def _full_boxes(n):
    return np.tile(np.array([[0, 0, CAM.width, CAM.height]]), (n, 1))


def test_spheres_kernel_matches_reference(rays):
    rng = np.random.default_rng(0)
    rec = _random_spheres(rng, 12)
    light = np.array([1.0, -0.5, -1.0]) / math.sqrt(2.25)
    img, z = _background(rng), np.full((CAM.height, CAM.width), np.inf)
    img_ref, z_ref = img.copy(), z.copy()
    boxes = _full_boxes(len(rec))
    boxes[:3] = [[100, 50, 400, 300], [0, 0, 0, 0], [600, 400, 640, 480]]  # partial, empty and corner boxes
    draw_spheres(img, z, rays, rec, boxes, light, SHADING)
    draw_spheres_ref(img_ref, z_ref, rays, rec, boxes, light, SHADING)
    diff = np.abs(img.astype(int) - img_ref.astype(int))
    drawn = np.isfinite(z)
    print(f"{drawn.sum()} sphere pixels, {np.count_nonzero(diff)} channel values differ, max {diff.max()}")
    assert drawn.sum() > 20000
    assert np.array_equal(drawn, np.isfinite(z_ref)) and np.allclose(z[drawn], z_ref[drawn], rtol=1e-12)
    assert diff.max() <= 1 and np.count_nonzero(diff) < 1e-4 * diff.size  # rounding at .5 only


def test_decals_kernel_matches_reference(rays):
    rng = np.random.default_rng(1)
    R = so3.exp(np.array([1.0, 0.2, 0.1]))  # a plane tilted away from the camera, 1.5 in front of it
    plane = np.concatenate([[0.1, -0.2, 1.5], R[:, 0], R[:, 1], R[:, 2]])
    dec = np.zeros((10, DECAL_LEN))
    dec[:, 0:2] = rng.uniform(-0.8, 0.8, (10, 2))
    dec[:, 3] = rng.uniform(0.05, 0.4, 10)
    dec[:, 2] = np.where(rng.random(10) < 0.5, 0.0, 0.6 * dec[:, 3])
    dec[:, 4] = rng.uniform(0.0, 0.1, 10)
    dec[:, 5:8] = rng.uniform(0, 255, (10, 3))
    dec[:, 8] = rng.uniform(0.2, 1.0, 10)
    img = _background(rng)
    z = np.full((CAM.height, CAM.width), np.inf)
    z[200:260, 300:400] = 0.5  # something nearer than the plane hides the decals there
    img_ref, background = img.copy(), img.copy()
    boxes = _full_boxes(len(dec))
    draw_decals(img, z, rays, plane, dec, boxes)
    draw_decals_ref(img_ref, z, rays, plane, dec, boxes)
    diff = np.abs(img.astype(int) - img_ref.astype(int))
    changed = np.any(img != background, axis=2)
    print(f"{changed.sum()} decal pixels, {np.count_nonzero(diff)} channel values differ")
    assert changed.sum() > 10000 and not changed[200:260, 300:400].any()
    assert diff.max() <= 1 and np.count_nonzero(diff) < 1e-4 * diff.size


def test_polyline_kernel_matches_reference():
    rng = np.random.default_rng(2)
    H, W = 120, 160
    t = np.linspace(0.0, 1.0, 25)
    a = rng.uniform(-20, 180, (6, 1, 2))
    b = rng.uniform(-20, 180, (6, 1, 2))
    bend = rng.normal(0, 15, (6, 1, 2)) * (t * (1 - t))[None, :, None]
    uv = a + (b - a) * t[None, :, None] + bend
    ok = rng.random((6, 25)) > 0.1
    cov = np.zeros((H, W), np.float32)
    touched = np.empty(H * W, np.int64)
    n = rasterise_polylines(cov, touched, uv, ok, 1.0)
    ref = rasterise_polylines_ref((H, W), uv, ok, 1.0)
    assert np.abs(cov - ref).max() < 1e-6 and (ref > 0).sum() > 500
    assert n == np.count_nonzero(cov) and set(touched[:n]) == set(np.flatnonzero(cov))
    img = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    expect = img * (1 - 0.4 * ref[..., None]) + np.array([10.0, 200.0, 30.0]) * 0.4 * ref[..., None] + 0.5
    blend_coverage(img, cov, touched, n, np.array([10.0, 200.0, 30.0]), 0.4)
    assert np.abs(img.astype(int) - expect.astype(np.uint8).astype(int)).max() <= 1
    assert not cov.any()  # cleared for the next frame


def test_a_full_touched_buffer_keeps_its_first_pixels_and_the_coverage_stays_exact():
    rng = np.random.default_rng(4)
    H, W = 60, 80
    uv = rng.uniform(-5, 85, (3, 10, 2))
    ok = np.ones((3, 10), bool)
    cov, small = np.zeros((H, W), np.float32), np.zeros((H, W), np.float32)
    touched, few = np.empty(H * W + 1, np.int64), np.full(11, -1, np.int64)  # capacity 10 + the scratch slot
    n = rasterise_polylines(cov, touched, uv, ok, 1.0)
    m = rasterise_polylines(small, few, uv, ok, 1.0)
    assert n > 100 and m == 10
    assert np.array_equal(few[:m], touched[:m]) and np.array_equal(small, cov)
    assert np.array_equal(cov, rasterise_polylines_ref((H, W), uv, ok, 1.0).astype(np.float32))


def test_blending_into_one_grey_channel_equals_each_channel_of_bgr():
    rng = np.random.default_rng(3)
    H, W = 60, 80
    uv = rng.uniform(-5, 85, (4, 12, 2))
    ok = np.ones((4, 12), bool)
    grey = rng.integers(0, 256, (H, W, 1), dtype=np.uint8)
    bgr = np.repeat(grey, 3, axis=2)
    cov = np.zeros((H, W), np.float32)
    touched = np.empty(H * W, np.int64)
    for img in (grey, bgr):
        n = rasterise_polylines(cov, touched, uv, ok, 1.0)
        blend_coverage(img, cov, touched, n, np.array([255.0, 255.0, 255.0]), 0.7)
    assert n > 300
    for c in range(3):
        assert np.array_equal(bgr[..., c], grey[..., 0])


def test_sphere_silhouette_lands_on_the_projected_tangent_circle(rays):
    """The ray-cast outline of spheres follows the lens model: the tangent circle (where the camera's cone
    touches the sphere), projected with ``FovCamera.project``, is the boundary of the drawn mask: the pixel
    nearest a point 1.2 px inside it (so at least 0.49 px inside) is drawn, one 1.2 px outside is not — near the
    image centre and near the corner where the FOV distortion is strongest."""
    for centre, radius in (([0.05, -0.02, 1.5], 0.2), ([1.35, 0.95, 1.6], 0.12)):
        c = np.array(centre)
        rec = np.zeros((1, SPHERE_LEN))
        rec[0, 0:3], rec[0, 3], rec[0, 4:13] = c, radius, np.eye(3).ravel()
        rec[0, 13:22] = 200.0
        z = np.full((CAM.height, CAM.width), np.inf)
        draw_spheres(
            np.zeros((CAM.height, CAM.width, 3), np.uint8),
            z,
            rays,
            rec,
            _full_boxes(1),
            np.array([0.0, 0.0, -1.0]),
            SHADING,
        )
        mask = np.isfinite(z)  # pixels at least half covered
        L = np.linalg.norm(c)
        d = c / L
        e1 = np.cross(d, [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(d, e1)
        phi = np.linspace(0, 2 * np.pi, 90, endpoint=False)
        rho = radius * math.sqrt(1 - (radius / L) ** 2)
        ring = c * (1 - (radius / L) ** 2) + rho * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        uv = CAM.project(ring)
        centre_uv = CAM.project(c[None])[0]
        inward = (centre_uv - uv) / np.linalg.norm(centre_uv - uv, axis=1, keepdims=True)
        inside = np.rint(uv + 1.2 * inward).astype(int)
        outside = np.rint(uv - 1.2 * inward).astype(int)
        ok_in = mask[inside[:, 1], inside[:, 0]]
        ok_out = ~mask[outside[:, 1], outside[:, 0]]
        print(f"sphere at {centre}: outline near {centre_uv.round(1)}, {ok_in.mean():.2f} in, {ok_out.mean():.2f} out")
        assert ok_in.all() and ok_out.all()


def test_spheres_occlude_each_other_in_either_order(rays):
    near = np.zeros(SPHERE_LEN)
    near[0:4] = [0.0, 0.0, 1.0, 0.15]
    near[4:13] = np.eye(3).ravel()
    near[13:16] = [0.0, 0.0, 250.0]
    far = near.copy()
    far[0:4] = [0.1, 0.0, 1.4, 0.25]
    far[13:16] = [250.0, 0.0, 0.0]
    imgs = []
    for rec in (np.stack([near, far]), np.stack([far, near])):
        img = np.zeros((CAM.height, CAM.width, 3), np.uint8)
        z = np.full((CAM.height, CAM.width), np.inf)
        draw_spheres(img, z, rays, rec, _full_boxes(2), np.array([0.0, 0.0, -1.0]), SHADING)
        imgs.append((img, z))
    (a, za), (b, zb) = imgs
    assert np.array_equal(za, zb)
    core = CAM.project(np.array([[0.0, 0.0, 1.0]]))[0].astype(int)  # inside both outlines: the near one shows
    y, x = core[1], core[0]
    for img in (a, b):
        assert img[y, x, 2] > 100 and img[y, x, 0] == 0
    # Only the near sphere's anti-aliased rim depends on the order (it blends over what is already there).
    near_mask = (za < 1.08).astype(np.uint8)
    kernel = np.ones((5, 5), np.uint8)
    rim = (cv2.dilate(near_mask, kernel) > 0) & ~(cv2.erode(near_mask, kernel) > 0)
    same = ~rim & np.isfinite(za)
    assert same.sum() > 10000 and np.array_equal(a[same], b[same])


def test_outline_boxes_kernel_matches_reference():
    """Outlines in front of the camera, beyond the projectable cone, reaching behind the camera, and invisible."""
    rng = np.random.default_rng(6)
    n, k = 40, 32
    centres = np.column_stack([rng.uniform(-3, 3, (n, 2)), rng.uniform(-0.5, 3.0, n)])
    phi = np.linspace(0.0, 2.0 * np.pi, k, endpoint=False)
    radius = rng.uniform(0.05, 0.6, n)
    samples = centres[:, None] + radius[:, None, None] * np.stack([np.cos(phi), np.sin(phi), 0.3 * np.cos(phi)], -1)
    visible = rng.random(n) > 0.2
    max_radius = 1.5 * CAM.max_radius * (1.0 - 1e-9)
    boxes = outline_boxes(samples, visible, CAM.kernel_params(), max_radius, CAM.width, CAM.height, 2)
    ref = outline_boxes_ref(samples, visible, CAM, max_radius, 2)
    behind = (samples[..., 2] <= 0).any(axis=1) & visible
    beyond = (np.hypot(samples[..., 0], samples[..., 1]) > max_radius * samples[..., 2]).any(axis=1) & ~behind
    empty = (boxes[:, 2] <= boxes[:, 0]) | (boxes[:, 3] <= boxes[:, 1])
    assert behind.sum() >= 3 and beyond.sum() >= 3 and (visible & ~behind & ~empty).sum() >= 10
    assert np.array_equal(boxes, ref)
