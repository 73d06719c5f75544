"""Adaptive motion-blur sampling (``ptam.synthetic.motion_blur``): a frame gets as many sub-frames as its image
motion needs, and the image it renders to is the one all the sub-frames give, to well below the sensor noise."""

import numpy as np
import pytest

from ptam.camera import PinholeCamera
from ptam.synthetic import load_scene
from ptam.synthetic.motion_blur import probe_pixels, smear_px, subframe_count
from ptam.synthetic.rectangle import Rectangle
from ptam.synthetic.render_kernels import intersect_rays
from ptam.synthetic.scene import Scene
from ptam.synthetic.spec import resolve_scene


def test_subframe_count_is_odd_and_steps_at_most_max_step():
    counts = [subframe_count(s, 1.0, 12) for s in (0.0, 0.5, 2.0, 2.01, 7.5, 10.0, 11.0, np.inf)]
    assert counts == [1, 3, 3, 5, 9, 11, 12, 12]  # 11 px: 13 odd, capped
    assert subframe_count(3.0, 0.0, 12) == 12  # max_step_px 0: always every sub-frame
    assert subframe_count(9.0, 2.0, 16) == 7


def test_smear_of_a_sideways_slide_past_a_wall_is_its_image_shift():
    """A camera sliding parallel to a wall at depth z moves every wall point by fx·Δx/z in the image."""
    cam = PinholeCamera(160, 120, 200.0, 200.0, 79.5, 59.5)
    wall = Rectangle(
        "wall", np.array([-5.0, -5.0, 2.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]), (10.0, 10.0), {}
    )
    rays = cam.unproject_rays(probe_pixels(cam))
    t, k, _, _ = intersect_rays(np.zeros(3), rays, wall.packed()[None])
    assert np.all(k == 0)
    X = t[:, None] * rays  # the wall points the probes see from the identity pose
    dx = 0.03
    poses = np.stack([np.eye(4)] * 7)
    poses[:, 0, 3] = np.linspace(-dx / 2, dx / 2, 7)
    assert smear_px(cam, X, poses) == pytest.approx(200.0 * dx / 2.0, rel=1e-9)
    away = poses.copy()
    away[:, 2, 3] = np.linspace(0.0, 2.5, 7)  # through the wall: points end up behind the camera
    assert smear_px(cam, X, away) == np.inf
    assert smear_px(cam, X[:0], poses) == 0.0  # the probes hit nothing


def test_desk_blur_frames_render_as_with_every_subframe():
    """desk_blur (12 sub-frames): a mapping frame smears ~3 px and is drawn with 5, a sweep frame with all 12. The
    fewer sub-frames change the image by a tenth of a grey level on average (measured 0.17) and by at most about
    one at the 99th percentile (measured 1.1), beside the scene's sensor noise of 2."""
    name, spec, _ = resolve_scene("desk_blur")
    scene = load_scene("desk_blur")
    every = dict(spec["render"]["motion_blur"], max_step_px=0)
    full = Scene(name, {**spec, "render": {**spec["render"], "motion_blur": every}})
    assert scene.noise_sigma == 2.0
    slow, fast = 50, 150
    sub = scene.subframe_poses(slow)
    assert len(sub) == 5 and np.allclose(sub[2], scene.poses_T_wc[slow])  # odd: the middle one is the truth
    assert len(scene.subframe_poses(fast)) == 12
    diff = np.abs(scene.render_view(sub) - full.render_view(full.subframe_poses(slow)))
    print(f"frame {slow}: mean |diff| {diff.mean():.3f}, 99th percentile {np.percentile(diff, 99):.2f} grey levels")
    assert diff.mean() < 0.25 and np.percentile(diff, 99) < 1.5
