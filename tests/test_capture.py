"""Frame sources on tiny inputs written by the tests: video (FFV1, lossless), image folder, TUM, EuRoC."""

import os

import cv2
import numpy as np
import pytest
import yaml

from ptam.camera import camera_from_dict, load_camera
from ptam.capture import (
    Frame,
    find_calibration,
    open_dataset,
    open_folder,
    open_source,
    parse_size,
)
from ptam.capture.dataset import dataset_kind
from ptam.cli import main as cli_main
from ptam.config import default_config
from ptam.errors import InputError
from ptam.eval import write_tum as write_trajectory
from tests.support import capture

W, H = 64, 48


def colour_frames(n, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]


def write_video(path, frames, fps=25.0):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (W, H))
    assert writer.isOpened()
    for f in frames:
        writer.write(f)
    writer.release()


@pytest.fixture(scope="module")
def video(tmp_path_factory):
    frames = colour_frames(10)
    path = tmp_path_factory.mktemp("video") / "ten.avi"
    write_video(path, frames)
    return path, frames


def test_video_frames_timestamps_and_pixels(video):
    path, frames = video
    with open_source(capture(), video=str(path)) as src:
        assert len(src) == 10 and src.length == 10
        assert src.size == (W, H)
        assert src.fps == pytest.approx(25.0)
        got = list(src)
        assert [f.index for f in got] == list(range(10))
        # The container's clock: frame i at i/25 s.
        np.testing.assert_allclose([f.timestamp for f in got], np.arange(10) * 0.04, atol=1e-9)
        for f, ref in zip(got, frames):
            assert isinstance(f, Frame)
            assert f.image.dtype == np.uint8 and f.image.shape == (H, W)
            np.testing.assert_array_equal(f.colour, ref)
            np.testing.assert_array_equal(f.image, cv2.cvtColor(ref, cv2.COLOR_BGR2GRAY))
        # A second pass starts again from the first frame.
        again = list(src)
        assert len(again) == 10
        np.testing.assert_array_equal(again[3].colour, frames[3])


def test_truncated_and_corrupt_videos(video, tmp_path):
    path, _ = video
    data = path.read_bytes()
    half = tmp_path / "half.avi"
    half.write_bytes(data[: len(data) // 2])
    src = open_source(capture(), video=str(half))
    with pytest.raises(InputError, match=r"ended after \d of 10 frames"):
        list(src)
    src.close()
    header = tmp_path / "header.avi"
    header.write_bytes(data[:200])
    with pytest.raises(InputError, match="cannot open video"):
        open_source(capture(), video=str(header))
    noise = tmp_path / "noise.avi"
    noise.write_bytes(np.random.default_rng(1).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="cannot open video"):
        open_source(capture(), video=str(noise))
    with pytest.raises(InputError, match="video file not found"):
        open_source(capture(), video=str(tmp_path / "missing.avi"))


def test_image_folder_natural_order(tmp_path):
    frames = colour_frames(12, seed=2)
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"img{i}.png"), f)
    (tmp_path / "notes.txt").write_text("not an image")
    src = open_source(capture(), dataset=str(tmp_path), fps=20.0)
    assert dataset_kind(str(tmp_path)) == "folder"
    assert len(src) == 12 and src.size == (W, H) and src.fps == 20.0
    got = list(src)
    # img2 before img10: natural, not lexical, order.
    for f, ref in zip(got, frames):
        np.testing.assert_array_equal(f.colour, ref)
    np.testing.assert_allclose([f.timestamp for f in got], np.arange(12) / 20.0, atol=1e-12)


def test_image_folder_grey_default_fps_and_errors(tmp_path):
    grey = np.arange(W * H, dtype=np.uint32).reshape(H, W).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "a.pgm"), grey)
    cv2.imwrite(str(tmp_path / "b.pgm"), 255 - grey)
    src = open_dataset(str(tmp_path), capture().default_fps)
    assert src.fps == default_config().capture.default_fps
    a, b = list(src)
    assert a.colour is None
    np.testing.assert_array_equal(a.image, grey)
    np.testing.assert_array_equal(b.image, 255 - grey)

    cv2.imwrite(str(tmp_path / "c.pgm"), np.zeros((H + 2, W), np.uint8))
    with pytest.raises(InputError, match=r"c.pgm is 64x50, expected 64x48"):
        list(open_dataset(str(tmp_path), capture().default_fps))
    (tmp_path / "c.pgm").write_bytes(b"garbage")
    with pytest.raises(InputError, match=r"cannot read image .*c.pgm"):
        list(open_dataset(str(tmp_path), capture().default_fps))

    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no images"):
        open_folder(str(empty), 30.0)
    with pytest.raises(InputError, match="dataset directory not found"):
        open_source(capture(), dataset=str(tmp_path / "nope"))


def write_tum(root, frames, stamps):
    (root / "rgb").mkdir()
    lines = ["# color images", "# timestamp filename"]
    for f, t in zip(frames, stamps):
        name = f"rgb/{t:.6f}.png"
        cv2.imwrite(str(root / name), f)
        lines.append(f"{t:.6f} {name}")
    (root / "rgb.txt").write_text("\n".join(lines) + "\n")


def test_tum_dataset(tmp_path):
    frames = colour_frames(5, seed=3)
    stamps = 1305031102.175304 + np.array([0.0, 0.033, 0.066, 0.1, 0.133])
    write_tum(tmp_path, frames, stamps)
    (tmp_path / "camera.yaml").write_text("model: pinhole\n")
    assert dataset_kind(str(tmp_path)) == "tum"
    assert find_calibration(str(tmp_path)) == os.path.join(str(tmp_path), "camera.yaml")
    src = open_source(capture(), dataset=str(tmp_path))
    assert len(src) == 5 and src.size == (W, H)
    assert src.fps == pytest.approx(1 / 0.033, rel=1e-6)
    got = list(src)
    np.testing.assert_allclose([f.timestamp for f in got], [float(f"{t:.6f}") for t in stamps], rtol=0, atol=0)
    for f, ref in zip(got, frames):
        np.testing.assert_array_equal(f.colour, ref)


def test_tum_corrupt_and_missing(tmp_path):
    write_tum(tmp_path, colour_frames(2), [1.0, 2.0])
    text = (tmp_path / "rgb.txt").read_text()
    (tmp_path / "rgb.txt").write_text(text + "3.0\n")
    with pytest.raises(InputError, match=r"rgb.txt:5: expected 'timestamp path'"):
        open_dataset(str(tmp_path), capture().default_fps)
    (tmp_path / "rgb.txt").write_text(text + "abc rgb/x.png\n")
    with pytest.raises(InputError, match=r"rgb.txt:5:"):
        open_dataset(str(tmp_path), capture().default_fps)
    (tmp_path / "rgb.txt").write_text(text + "3.0 rgb/missing.png\n")
    with pytest.raises(InputError, match=r"image file not found: .*missing.png"):
        open_dataset(str(tmp_path), capture().default_fps)
    (tmp_path / "rgb.txt").write_text("# only comments\n")
    with pytest.raises(InputError, match="lists no images"):
        open_dataset(str(tmp_path), capture().default_fps)
    assert find_calibration(str(tmp_path)) is None


def test_euroc_dataset_from_root_mav0_or_cam0(tmp_path):
    cam0 = tmp_path / "mav0" / "cam0"
    (cam0 / "data").mkdir(parents=True)
    rng = np.random.default_rng(4)
    images = [rng.integers(0, 256, (H, W), dtype=np.uint8) for _ in range(4)]
    ns = 1403636579763555584 + np.arange(4, dtype=np.int64) * 50_000_000
    rows = ["#timestamp [ns],filename"]
    for img, t in zip(images, ns):
        cv2.imwrite(str(cam0 / "data" / f"{t}.png"), img)
        rows.append(f"{t},{t}.png")
    (cam0 / "data.csv").write_text("\n".join(rows) + "\n")
    for d in (tmp_path, tmp_path / "mav0", cam0):
        assert dataset_kind(str(d)) == "euroc"
        src = open_dataset(str(d), capture().default_fps)
        assert len(src) == 4 and src.fps == pytest.approx(20.0)
        got = list(src)
        assert got[0].timestamp == pytest.approx(1403636579.763555584, abs=1e-6)
        np.testing.assert_allclose(np.diff([f.timestamp for f in got]), 0.05, atol=1e-6)
        for f, ref in zip(got, images):
            assert f.colour is None
            np.testing.assert_array_equal(f.image, ref)
    (cam0 / "data.csv").write_text("\n".join(rows) + "\n12x,a.png\n")
    with pytest.raises(InputError, match=r"data.csv:6: expected 'timestamp_ns,filename'"):
        open_dataset(str(tmp_path), capture().default_fps)


# MH_01_easy's mav0/cam0/sensor.yaml as EuRoC ships it (Kalibr's fields), the extrinsics shortened.
EUROC_SENSOR_YAML = """# General sensor definitions.
sensor_type: camera
comment: VI-Sensor cam0 (MT9M034)
T_BS:
  cols: 4
  rows: 4
  data: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375] #fu, fv, cu, cv
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
"""


def test_a_euroc_dataset_brings_its_calibration(tmp_path):
    """``ptam run --dataset`` on a EuRoC sequence needs no camera.yaml: cam0/sensor.yaml is the camera, the same
    as the camera.yaml a user would have written from it."""
    cam0 = tmp_path / "mav0" / "cam0"
    (cam0 / "data").mkdir(parents=True)
    (cam0 / "data.csv").write_text("#timestamp [ns],filename\n")
    (cam0 / "sensor.yaml").write_text(EUROC_SENSOR_YAML)
    for d in (tmp_path, tmp_path / "mav0", cam0):
        assert find_calibration(str(d)) == str(cam0 / "sensor.yaml")
    cam = load_camera(cam0 / "sensor.yaml")
    by_hand = camera_from_dict(
        {
            "model": "radtan",
            "width": 752,
            "height": 480,
            "fx": 458.654,
            "fy": 457.296,
            "cx": 367.215,
            "cy": 248.375,
            "k1": -0.28340811,
            "k2": 0.07395907,
            "p1": 0.00019359,
            "p2": 1.76187114e-05,
        }
    )
    assert cam.to_dict() == by_hand.to_dict()
    X = np.random.default_rng(5).uniform([-1.0, -0.7, 1.0], [1.0, 0.7, 3.0], (50, 3))
    np.testing.assert_allclose(cam.project(X), by_hand.project(X), rtol=0, atol=1e-12)  # px
    (tmp_path / "camera.yaml").write_text("model: pinhole\n")
    assert find_calibration(str(tmp_path)) == str(tmp_path / "camera.yaml")  # the user's own file comes first
    fisheye = EUROC_SENSOR_YAML.replace("radial-tangential", "equidistant")
    with pytest.raises(InputError, match="distortion_model 'equidistant' is not supported"):
        camera_from_dict(yaml.safe_load(fisheye))
    with pytest.raises(InputError, match="'intrinsics' must be a list of 4 numbers"):
        camera_from_dict(yaml.safe_load(EUROC_SENSOR_YAML.replace(", 248.375]", "]")))


def test_a_euroc_dataset_brings_its_ground_truth(tmp_path, capsys):
    """The body poses of ``state_groundtruth_estimate0/data.csv`` (quaternion w first, nanoseconds) taken to the
    camera by cam0's ``T_BS``: the camera-to-world poses ``ptam run`` is scored against."""
    from ptam.capture import find_groundtruth
    from ptam.geometry import se3, so3

    rng = np.random.default_rng(6)
    T_BS = se3.exp(np.r_[-0.02, -0.06, 0.01, 0.0, 0.0, 1.55])  # about EuRoC's: a quarter turn, centimetres off
    T_WC = se3.exp(np.c_[rng.normal(scale=0.5, size=(30, 3)), rng.normal(scale=0.8, size=(30, 3))])
    T_WB = T_WC @ se3.inv(T_BS)
    ns = 1403636579758555392 + np.arange(30, dtype=np.int64) * 5_000_000
    q = so3.to_quaternion(T_WB[:, :3, :3])  # (x, y, z, w)
    rows = ["#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], ..."]
    for t, T, qi in zip(ns, T_WB, q):
        values = [*T[:3, 3], qi[3], *qi[:3], *rng.normal(size=9)]  # velocities and biases follow the pose
        rows.append(f"{t}," + ",".join(repr(float(v)) for v in values))
    mav0 = tmp_path / "mav0"
    (mav0 / "cam0" / "data").mkdir(parents=True)
    (mav0 / "cam0" / "data.csv").write_text("#timestamp [ns],filename\n")
    (mav0 / "state_groundtruth_estimate0").mkdir()
    (mav0 / "state_groundtruth_estimate0" / "data.csv").write_text("\n".join(rows) + "\n")
    sensor = yaml.safe_load(EUROC_SENSOR_YAML)
    sensor["T_BS"]["data"] = T_BS.reshape(-1).tolist()
    (mav0 / "cam0" / "sensor.yaml").write_text(yaml.safe_dump(sensor))
    for d in (tmp_path, mav0, mav0 / "cam0"):
        path, t, T = find_groundtruth(str(d))
        assert path.endswith("state_groundtruth_estimate0/data.csv")
        assert np.abs(t - (1403636579.758555392 + 0.005 * np.arange(30))).max() < 1e-6
        assert np.abs(T - T_WC).max() < 1e-12
    # ptam eval takes the same file, and the camera's trajectory scores as the truth (T_BS ignored: about 89°).
    est = tmp_path / "est.txt"
    t = 1403636579.758555392 + 0.005 * np.arange(30)
    write_trajectory(est, t, T_WC)
    gt_csv = str(mav0 / "state_groundtruth_estimate0" / "data.csv")
    assert cli_main(["eval", gt_csv, str(est)]) == 0
    fields = dict(kv.split("=") for kv in capsys.readouterr().out.strip().splitlines()[-1].split())
    assert float(fields["ate_rmse_m"]) < 1e-9 and float(fields["rot_rmse_deg"]) < 1e-6
    (mav0 / "cam0" / "sensor.yaml").unlink()
    assert cli_main(["eval", gt_csv, str(est)]) == 0
    out = capsys.readouterr().out
    assert "comparing with the body poses" in out
    assert float(dict(kv.split("=") for kv in out.strip().splitlines()[-1].split())["rot_rmse_deg"]) > 80.0
    (mav0 / "state_groundtruth_estimate0" / "data.csv").write_text(rows[0] + "\n1,2,3\n")
    with pytest.raises(InputError, match=r"data.csv:2: expected 'timestamp_ns,px,py,pz,qw,qx,qy,qz"):
        find_groundtruth(str(tmp_path))
    assert find_groundtruth(str(tmp_path / "mav0" / "cam0" / "data")) is None  # no dataset there


def test_parse_size_and_source_choice():
    assert parse_size("640x480") == (640, 480)
    assert parse_size([320, 240]) == (320, 240)
    with pytest.raises(InputError, match="WIDTHxHEIGHT"):
        parse_size("640by480")
    with pytest.raises(InputError, match="exactly one frame source"):
        open_source(capture())
    with pytest.raises(InputError, match="exactly one frame source"):
        open_source(capture(), video="a.avi", dataset="b")


class ClocklessCapture:
    """A container with no frame rate and no timestamps: 4 frames, POS_MSEC stuck at 0."""

    def __init__(self, path):
        self.left = 4

    def isOpened(self):
        return True

    def get(self, prop):
        return {
            cv2.CAP_PROP_FRAME_WIDTH: W,
            cv2.CAP_PROP_FRAME_HEIGHT: H,
            cv2.CAP_PROP_FPS: 0.0,
            cv2.CAP_PROP_FRAME_COUNT: 4,
            cv2.CAP_PROP_POS_MSEC: 0.0,
        }[prop]

    def read(self):
        self.left -= 1
        return (True, np.zeros((H, W, 3), np.uint8)) if self.left >= 0 else (False, None)

    def release(self):
        pass


def test_video_without_container_clock_falls_back_to_index_over_fps(tmp_path, monkeypatch):
    from ptam.capture import video as video_module

    monkeypatch.setattr(video_module.cv2, "VideoCapture", ClocklessCapture)
    (tmp_path / "v.avi").write_bytes(b"stub")
    src = open_source(capture(), video=str(tmp_path / "v.avi"))
    fps = default_config().capture.default_fps
    assert src.fps == fps and len(src) == 4
    np.testing.assert_allclose([f.timestamp for f in src], np.arange(4) / fps, atol=1e-12)
