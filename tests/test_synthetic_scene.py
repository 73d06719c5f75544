"""Scene files and trajectories: the two-wall path of PTAM §7.3, key-pose interpolation, bad input."""

import numpy as np
import pytest

from ptam.errors import InputError
from ptam.geometry import so3
from ptam.synthetic import list_scenes, load_scene
from ptam.synthetic.trajectory import Jitter, KeyPose, Trajectory, look_at


@pytest.fixture(scope="module")
def two_wall():
    return load_scene("two_wall")


def _rot_deg(Ra, Rb):
    return np.degrees(np.linalg.norm(so3.log(np.swapaxes(Ra, -1, -2) @ Rb), axis=-1))


def test_bundled_scenes():
    assert {"two_wall", "two_wall_short", "two_wall_noisy"} <= set(list_scenes())
    short, noisy = load_scene("two_wall_short"), load_scene("two_wall_noisy")
    full = load_scene("two_wall")
    assert short.n_frames == 200 and noisy.n_frames == 600
    assert np.array_equal(short.poses_T_wc, full.poses_T_wc[:200])  # the same path, truncated
    assert np.array_equal(noisy.poses_T_wc, full.poses_T_wc)
    assert noisy.noise_sigma == 2.0 and noisy.blur_subframes > 1


def test_two_wall_matches_the_paper(two_wall):
    """PTAM §7.3: 600 frames, 18.2 m of travel; a wide-angle fov camera, 640x480 at 30 fps."""
    s = two_wall
    assert s.n_frames == 600 and s.fps == 30 and (s.camera.width, s.camera.height) == (640, 480)
    assert s.camera.model == "fov" and abs(s.camera.fx - 384) < 1e-9 and abs(s.camera.omega - 0.9) < 1e-9
    print(f"two_wall path length {s.path_length:.3f} m")
    assert abs(s.path_length - 18.2) < 0.02 * 18.2
    assert np.allclose(s.timestamps[:3], [0.0, 1 / 30, 2 / 30])
    assert np.abs(s.poses_T_wc[:, 2, 3] - 3.0).max() < 0.01  # Fig. 5: "ground truth lies on z = 3"


def test_two_wall_path_is_smooth_and_always_sees_the_walls(two_wall):
    s = two_wall
    T = s.poses_T_wc
    step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
    turn = _rot_deg(T[:-1, :3, :3], T[1:, :3, :3])
    print(f"per frame: speed max {100 * step.max():.2f} cm, rotation max {turn.max():.2f} deg")
    assert step.max() < 0.05 and turn.max() < 2.0  # hand-held pace: < 5 cm and < 2 deg per frame
    cam = s.camera
    vv, uu = np.mgrid[0 : cam.height : 16, 0 : cam.width : 16]
    uv = np.stack([uu.ravel(), vv.ravel()], 1).astype(np.float64)
    uv = np.concatenate([uv, [[0, 0], [cam.width - 1, 0], [0, cam.height - 1], [cam.width - 1, cam.height - 1]]])
    wall_fraction = []
    for i in range(0, s.n_frames, 3):
        X, depth, hit = s.raycast(T[i], uv)
        assert hit.all(), f"frame {i} sees past the walls"
        assert 2.9 < np.median(depth) < 5.0  # m: the walls stay about 3 m away
        wall_fraction.append(np.mean(X[:, 2] > 1e-9))
    print(f"fraction of the image on the walls (not the floor): min {min(wall_fraction):.3f}")
    assert min(wall_fraction) > 0.9


def test_first_frames_are_a_stereo_initialisation_baseline(two_wall):
    """PTAM §6.1: a smooth sideways translation, ~10% of the scene depth, over the first 40 frames."""
    T = two_wall.poses_T_wc
    d = T[40, :3, 3] - T[0, :3, 3]
    depth = np.median(two_wall.raycast(T[0], np.array([[319.5, 239.5], [100.0, 100.0], [500.0, 400.0]]))[1])
    sideways = np.degrees(np.arccos(abs(d @ T[0, :3, 0]) / np.linalg.norm(d)))
    print(
        f"frames 0-40: baseline {np.linalg.norm(d):.3f} m at depth {depth:.2f} m, {sideways:.2f} deg off the "
        f"camera x axis, rotation {_rot_deg(T[0, :3, :3], T[40, :3, :3]):.3f} deg"
    )
    assert 0.08 < np.linalg.norm(d) / depth < 0.15
    assert sideways < 2.0 and _rot_deg(T[0, :3, :3], T[40, :3, :3]) < 0.5


def _keys():
    up = np.array([0.0, 0.0, 1.0])
    pts = [([0, 0, 0], 0, 0.0), ([1, 0, 0], 10, 0.0), ([2, 1, 0], 25, 20.0), ([2, 3, 0], 60, 0.0)]
    return [
        KeyPose(f, np.array(p, float), look_at(np.array(p, float), np.array(p, float) + [0, 1, 0], up), h)
        for p, f, h in pts
    ]


def test_trajectory_passes_through_keys_and_holds():
    tr = Trajectory(_keys())
    T = tr.smooth_poses(np.array([0.0, 10.0, 25.0, 45.0, 60.0]))  # keys, end of the hold
    assert np.allclose(T[:, :3, 3], [[0, 0, 0], [1, 0, 0], [2, 1, 0], [2, 1, 0], [2, 3, 0]], atol=1e-12)
    held = tr.smooth_poses(np.linspace(25.0, 45.0, 21))
    assert np.abs(held[:, :3, 3] - [2, 1, 0]).max() < 1e-12  # a pause is a true stop
    dense = tr.smooth_poses(np.linspace(0.0, 60.0, 2401))[:, :3, 3]
    assert np.all(np.diff(dense[:, 0]) >= -1e-12) and np.all(np.diff(dense[:, 1]) >= -1e-12)  # no overshoot
    assert dense[:, 0].max() <= 2.0 + 1e-12
    eps = 1e-5  # velocity just before and just after each key: continuous (C1)
    for k in (10.0, 25.0, 45.0):
        p = tr.smooth_poses(np.array([k - eps, k, k + eps]))[:, :3, 3]
        v_in, v_out = (p[1] - p[0]) / eps, (p[2] - p[1]) / eps
        assert np.linalg.norm(v_in - v_out) < 1e-3 * max(np.linalg.norm(v_in), 1e-3)


def test_rotation_interpolation_is_smooth_and_exact_at_keys():
    up = np.array([0.0, 0.0, 1.0])
    keys = [
        KeyPose(f, np.zeros(3), look_at(np.zeros(3), [np.sin(a), np.cos(a), 0.0], up))
        for f, a in ((0, 0.0), (10, 0.3), (30, 1.2), (40, 1.5))
    ]
    tr = Trajectory(keys)
    assert _rot_deg(tr.smooth_poses(np.array([10.0]))[0, :3, :3], keys[1].R_wc) < 1e-9
    eps = 1e-5
    for k in (10.0, 30.0):  # angular velocity continuous across the keys
        R = tr.smooth_poses(np.array([k - eps, k, k + eps]))[:, :3, :3]
        w_in = so3.log(R[1] @ R[0].T) / eps
        w_out = so3.log(R[2] @ R[1].T) / eps
        assert np.linalg.norm(w_in - w_out) < 1e-3 * np.linalg.norm(w_in)
    R = tr.smooth_poses(np.linspace(0, 40, 801))[:, :3, :3]
    assert np.abs(R[:, 2, 0]).max() < 1e-9  # a yaw-only path stays level: the camera x axis keeps z = 0


def test_jitter_has_the_requested_spread():
    j = Jitter(seed=3, position_m=0.002, rotation_rad=np.radians(0.1), freq_lo_hz=0.3, freq_hi_hz=2.0, components=6)
    tr = Trajectory(_keys(), j, fps=30.0)
    off = tr.jitter_offsets(np.arange(0, 30 * 600, 1.0))  # long enough to average the sinusoids
    assert np.allclose(off[:, :3].std(0), 0.002, rtol=0.25)
    assert np.allclose(off[:, 3:].std(0), np.radians(0.1), rtol=0.25)
    assert np.array_equal(Trajectory(_keys(), j, 30.0).poses(np.arange(40.0)), tr.poses(np.arange(40.0)))


BAD_SCENES = {
    "not a mapping": "- 1\n- 2\n",
    "unknown key": "extends: two_wall\ncolour: red\n",
    "missing camera": "extends: two_wall\ncamera: null\n",
    "not a rectangle": "extends: two_wall\nrectangles:\n  - {corners: [[0,0,0],[1,0,0],[1,1,0.5],[0,1,0]],"
    " texture: {type: constant, value: 1}}\n",
    "bad texture": "extends: two_wall\nrectangles:\n  - {center: [0,0,1], axes: [[1,0,0],[0,1,0]], size: [1,1],"
    " texture: {type: plaid}}\n",
    "too many frames": "extends: two_wall\nframes: 900\n",
    "keys out of order": "extends: two_wall\ntrajectory:\n  keys:\n"
    "    - {frame: 5, position: [0,0,0], look_at: [0,1,0]}\n"
    "    - {frame: 2, position: [1,0,0], look_at: [1,1,0]}\n",
    "unparsable": "camera: [1, 2\n",
    "extends itself": "extends: me\n",
    "more rectangles not a list": "extends: two_wall\nmore_rectangles: {name: poster}\n",
}


@pytest.mark.parametrize("case", list(BAD_SCENES))
def test_bad_scene_files_raise_input_error(tmp_path, case):
    path = tmp_path / "me.yaml"
    path.write_text(BAD_SCENES[case])
    with pytest.raises(InputError) as e:
        load_scene(path)
    assert "\n" not in str(e.value)


def test_a_scene_adds_rectangles_to_the_one_it_extends(tmp_path):
    """``more_rectangles`` appends to the base's rectangles, drawn after them; ``rectangles`` would replace them."""
    poster = (
        "  - {corners: [[0, 2.9, 1], [1, 2.9, 1], [1, 2.9, 0], [0, 2.9, 0]], texture: {type: constant, value: 9}}\n"
    )
    (tmp_path / "more.yaml").write_text("extends: two_wall\nmore_rectangles:\n" + poster)
    (tmp_path / "only.yaml").write_text("extends: two_wall\nrectangles:\n" + poster)
    base, more, only = (load_scene(s) for s in ("two_wall", tmp_path / "more.yaml", tmp_path / "only.yaml"))
    assert len(more.rectangles) == len(base.rectangles) + 1 and len(only.rectangles) == 1
    assert all(np.array_equal(a.corners(), b.corners()) for a, b in zip(more.rectangles, base.rectangles))
    assert np.array_equal(more.rectangles[-1].corners(), only.rectangles[0].corners())


def test_unknown_scene_name():
    with pytest.raises(InputError, match="unknown scene 'no_such_scene'.*two_wall"):
        load_scene("no_such_scene")
