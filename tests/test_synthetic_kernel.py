"""The ray-cast render kernel against its numpy reference, on random scenes and poses."""

import numpy as np

from ptam.camera import FovCamera
from ptam.synthetic.rectangle import rectangle_from_spec
from ptam.synthetic.render import Renderer
from ptam.synthetic.render_kernels import TILE_PX, _camera_frame, _tile_candidates, intersect_rays, render, tile_cones
from ptam.synthetic.trajectory import look_at
from tests.reference.render import render_ref, tile_cones_ref


def _random_scene(rng, n_rects=4):
    rects = []
    for k in range(n_rects):
        a = rng.normal(size=3)
        a /= np.linalg.norm(a)
        b = np.cross(a, rng.normal(size=3))
        b /= np.linalg.norm(b)
        tex = (
            {"type": "constant", "value": float(rng.uniform(0, 255))}
            if k == 0
            else {"type": "dead_leaves", "seed": int(k), "texel": 0.01, "sizes": [0.02, 0.4], "detail": 3}
        )
        rects.append(
            rectangle_from_spec(
                {
                    "name": f"r{k}",
                    "center": rng.uniform(-1, 1, 3).tolist(),
                    "axes": [a.tolist(), b.tolist()],
                    "size": rng.uniform(0.8, 2.5, 2).tolist(),
                    "texture": tex,
                },
                f"r{k}",
            )
        )
    return rects


def test_kernel_matches_numpy_reference():
    rng = np.random.default_rng(5)
    cam = FovCamera(48, 36, 30.0, 30.0, 23.5, 17.5, 0.9)
    r = Renderer(cam, _random_scene(rng), supersample=2, background=17.0)
    for trial in range(6):
        poses = []
        for _ in range(1 + trial % 3):  # 1-3 motion-blur sub-frames
            c = rng.uniform(-1, 1, 3) + np.array([0.0, 0.0, -3.0 - rng.uniform(0, 3)])
            T = np.eye(4)
            T[:3, :3] = look_at(c, rng.uniform(-0.5, 0.5, 3), [0.0, 1.0, 0.0])
            T[:3, 3] = c
            poses.append(T)
        args = r.kernel_args(np.array(poses))
        out = np.empty((cam.height, cam.width), np.float32)
        render(*args, out)
        ref = render_ref(*args)
        assert np.abs(out - ref).max() < 1e-3  # grey levels
        assert np.mean(out != 17.0) > 0.1  # the rectangles are in view


def test_intersect_ref_nearest_hit():
    # Two parallel unit squares at z = 2 and z = 5 facing the origin; rays along +z.
    spec = {"axes": [[1, 0, 0], [0, 1, 0]], "size": [1, 1], "texture": {"type": "constant", "value": 0}}
    rects = np.stack([rectangle_from_spec({**spec, "center": [0, 0, z]}, "r").packed() for z in (5.0, 2.0)])
    o = np.array([[0.2, 0.1, 0.0], [0.2, 0.1, 3.0], [0.7, 0.0, 0.0]])
    t, k, a, b = intersect_rays(o, np.tile([0.0, 0.0, 1.0], (3, 1)), rects)
    assert np.allclose(t[:2], [2.0, 2.0]) and k.tolist() == [1, 0, -1] and np.isinf(t[2])
    assert np.allclose([a[0], b[0]], [0.7, 0.6])  # from corner (-0.5, -0.5)


def test_tile_culling_keeps_every_hit_and_drops_the_rest():
    # Cameras among and between the rectangles (some behind the camera, some edge-on, some only grazed), tiles
    # of 16 px on a 96 x 64 image: every ray's nearest hit must be among its tile's candidates, and most tiles
    # must test fewer rectangles than the scene has.
    rng = np.random.default_rng(9)
    cam = FovCamera(96, 64, 50.0, 50.0, 47.5, 31.5, 0.9)
    rects = _random_scene(rng, n_rects=8)
    r = Renderer(cam, rects, supersample=2, background=0.0)
    TY, TX = r.tile_axis.shape[:2]
    ty = np.arange(cam.height)[:, None, None] // TILE_PX
    tx = np.arange(cam.width)[None, :, None] // TILE_PX
    counts, hits = [], []
    for _ in range(20):
        c = rng.uniform(-1.5, 1.5, 3)
        T = np.eye(4)
        T[:3, :3] = look_at(c, rng.uniform(-1, 1, 3), [0.0, 1.0, 0.0])
        T[:3, 3] = c
        cand = np.empty((TY, TX, 1, len(rects)), np.int64)
        ncand = np.empty((TY, TX, 1), np.int64)
        _tile_candidates(_camera_frame(r.rects, T[None]), r.rects, r.tile_axis, r.tile_sin, cand, ncand)
        _, k, _, _ = intersect_rays(T[:3, 3], r.rays.reshape(-1, 3) @ T[:3, :3].T, r.rects)
        k = k.reshape(r.rays.shape[:3])
        member = np.arange(len(rects)) < ncand[..., None]  # (TY, TX, 1, K) valid candidate slots
        kept = np.zeros((TY, TX, len(rects) + 1), bool)
        kept[..., -1] = True  # a miss (k = -1) needs no candidate
        yy, xx, jj = np.nonzero(member[:, :, 0])
        kept[yy, xx, cand[yy, xx, 0, jj]] = True
        assert kept[ty, tx, k].all()
        ascending = np.diff(cand[:, :, 0], axis=-1) > 0
        assert np.all(ascending | ~member[:, :, 0, 1:])  # the kernel's order: ties go to the same rectangle
        counts.append(ncand.mean())
        hits.append(np.mean(k >= 0))
    assert np.mean(hits) > 0.5  # the rays do hit rectangles
    assert np.mean(counts) < 0.5 * len(rects)


def test_tile_culling_never_drops_a_rectangle_seen_edge_on():
    # A camera in a rectangle's plane (off the rectangle) and one on the line through one of its edges: the edge
    # planes are degenerate there, and the rectangle must stay a candidate of every tile.
    rng = np.random.default_rng(3)
    cam = FovCamera(64, 48, 40.0, 40.0, 31.5, 23.5, 0.9)
    r = Renderer(cam, _random_scene(rng, n_rects=3), supersample=1, background=0.0)
    o, a, b = r.rects[1, 0:3], r.rects[1, 3:6], r.rects[1, 6:9]
    TY, TX = r.tile_axis.shape[:2]
    for c in (o - 0.7 * a + 0.3 * b, o - 0.5 * a):
        T = np.eye(4)
        T[:3, :3] = look_at(c, o + 0.5 * r.rects[1, 12] * a + 0.5 * r.rects[1, 13] * b, [0.0, 0.0, 1.0])
        T[:3, 3] = c
        cand = np.empty((TY, TX, 1, 3), np.int64)
        ncand = np.empty((TY, TX, 1), np.int64)
        _tile_candidates(_camera_frame(r.rects, T[None]), r.rects, r.tile_axis, r.tile_sin, cand, ncand)
        assert np.all(np.any((cand[..., 0, :] == 1) & (np.arange(3) < ncand), axis=-1))


def test_tile_cones_match_reference_and_hold_every_ray():
    # 50 x 37 px: the last tiles of each row and column are partial.
    cam = FovCamera(50, 37, 40.0, 40.0, 24.5, 18.0, 0.9)
    r = Renderer(cam, _random_scene(np.random.default_rng(1), n_rects=1), supersample=3, background=0.0)
    axis, sin = tile_cones(r.rays)
    axis_ref, sin_ref = tile_cones_ref(r.rays)
    assert axis.shape == (3, 4, 3) and np.abs(axis - axis_ref).max() < 1e-12 and np.abs(sin - sin_ref).max() < 1e-12
    ty = np.arange(cam.height)[:, None, None] // TILE_PX
    tx = np.arange(cam.width)[None, :, None] // TILE_PX
    cos = np.einsum("yxsc,yxsc->yxs", r.rays, axis[ty, tx])
    assert np.all(np.sqrt(1.0 - np.minimum(cos, 1.0) ** 2) < sin[ty, tx] - 0.5e-6)  # within the cone, past the pad
