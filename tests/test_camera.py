"""Camera models: round trips over the whole image, Jacobians, the paper's FOV equations, camera.yaml IO."""

import math

import numpy as np
import pytest

from ptam.camera import camera_from_dict, load_camera, save_camera
from ptam.errors import InputError
from tests.support.cameras import CAMERAS, H, W


def _grid():
    u, v = np.meshgrid(np.arange(0, W, 4.0), np.arange(0, H, 4.0))
    return np.stack([u.ravel(), v.ravel()], axis=1)


@pytest.mark.parametrize("name", list(CAMERAS))
def test_project_unproject_round_trip_whole_image(name):
    cam = CAMERAS[name]
    uv = np.concatenate([_grid(), [[0, 0], [W - 1, 0], [0, H - 1], [W - 1, H - 1]]])
    xy = cam.unproject(uv)
    depth = np.linspace(0.5, 10.0, len(uv))[:, None]
    X = np.concatenate([xy, np.ones((len(uv), 1))], axis=1) * depth
    assert np.max(np.abs(cam.project(X) - uv)) < 1e-6
    assert np.all(cam.valid(X))


@pytest.mark.parametrize("name", list(CAMERAS))
def test_projection_jacobian_against_finite_differences(name):
    cam = CAMERAS[name]
    rng = np.random.default_rng(1)
    X = np.concatenate([rng.uniform(-1.0, 1.0, (200, 2)), rng.uniform(1.5, 5.0, (200, 1))], axis=1)
    X[0] = [0.0, 0.0, 2.0]  # the optical axis, where the FOV model uses its series
    J = cam.project_jacobian(X)
    eps = 1e-6
    num = np.zeros_like(J)
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        num[:, :, k] = (cam.project(X + d) - cam.project(X - d)) / (2 * eps)
    assert np.max(np.abs(num - J)) < 1e-5


def test_fov_matches_paper_equations():
    """PTAM eq. 3–5 evaluated literally, one point at a time."""
    cam = CAMERAS["fov"]
    rng = np.random.default_rng(2)
    X = np.concatenate([rng.uniform(-1.5, 1.5, (50, 2)), rng.uniform(1.0, 4.0, (50, 1))], axis=1)
    uv = cam.project(X)
    for (x, y, z), (u, v) in zip(X, uv):
        r = math.sqrt((x * x + y * y) / (z * z))
        rp = math.atan(2 * r * math.tan(cam.omega / 2)) / cam.omega
        assert abs(u - (cam.cx + cam.fx * rp / r * x / z)) < 1e-9
        assert abs(v - (cam.cy + cam.fy * rp / r * y / z)) < 1e-9
    # On the axis the distortion ratio tends to 2·tan(ω/2)/ω.
    eps_uv = cam.project(np.array([[1e-9, 0.0, 1.0]]))[0]
    assert abs((eps_uv[0] - cam.cx) / (cam.fx * 1e-9) - 2 * math.tan(cam.omega / 2) / cam.omega) < 1e-6


def test_validity_rejects_behind_and_far_outside():
    cam = CAMERAS["fov"]
    r_max = cam.max_radius
    X = np.array([[0.0, 0.0, -1.0], [1.4 * r_max, 0.0, 1.0], [1.6 * r_max, 0.0, 1.0]])
    assert cam.valid(X).tolist() == [False, True, False]


def test_yaml_round_trip(tmp_path):
    for name, cam in CAMERAS.items():
        p = tmp_path / f"{name}.yaml"
        save_camera(cam, p)
        back = load_camera(p)
        assert type(back) is type(cam)
        assert back.to_dict() == cam.to_dict()


def test_ptam_normalised_vector_is_accepted():
    cam = camera_from_dict({"model": "fov", "width": 640, "height": 480, "ptam": [0.6, 0.8, 0.5, 0.5, 0.9]})
    assert cam.fx == pytest.approx(384.0) and cam.fy == pytest.approx(384.0)
    assert cam.cx == pytest.approx(319.5) and cam.cy == pytest.approx(239.5)
    assert cam.ptam_vector() == pytest.approx([0.6, 0.8, 0.5, 0.5, 0.9])


@pytest.mark.parametrize(
    "patch, message",
    [
        ({"fx": -1.0}, "focal lengths must be positive"),
        ({"cx": 700.0}, "principal point"),
        ({"omega": 3.5}, "omega"),
        ({"omega": 0.0}, "omega"),
        ({"width": None}, "width"),
        ({"model": "fisheye"}, "unknown camera model"),
    ],
)
def test_yaml_validation(tmp_path, patch, message):
    d = dict(CAMERAS["fov"].to_dict())
    d.update(patch)
    d = {k: v for k, v in d.items() if v is not None}
    with pytest.raises(InputError, match=message):
        camera_from_dict(d)


def test_missing_and_corrupt_files(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_camera(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("model: fov\nwidth: [\n")
    with pytest.raises(InputError, match="cannot read"):
        load_camera(bad)


def test_bundled_camera_files_load_and_round_trip():
    from ptam.resources import resource_path

    files = sorted((resource_path("configs") / "cameras").glob("*.yaml"))
    assert len(files) >= 4
    for f in files:
        cam = load_camera(f)
        uv = np.array([[5.0, 5.0], [cam.width / 2, cam.height / 2], [cam.width - 6.0, cam.height - 6.0]])
        xy = cam.unproject(uv)
        assert np.max(np.abs(cam.project(np.concatenate([xy, np.ones((3, 1))], axis=1)) - uv)) < 1e-6
