"""`ptam calibrate`: parameters recovered from rendered chessboard sequences, robust refits, view choice, bad input."""

import shutil

import cv2
import numpy as np
import pytest
import yaml

from ptam.camera import FovCamera, PinholeCamera, load_camera
from ptam.camera.calibrator import calibrate, jacobian, project_views
from ptam.camera.chessboard import Board, View, ViewCollector, missing_cells, parse_board, select_views
from ptam.cli import main as cli_main
from ptam.config import default_config
from ptam.errors import InputError
from ptam.synthetic.sequence import write_video

CFG = default_config().calibrate
RADTAN = {
    "model": "radtan",
    "width": 640,
    "height": 480,
    "fx": 500.0,
    "fy": 502.0,
    "cx": 322.0,
    "cy": 236.5,
    "k1": -0.28,
    "k2": 0.09,
    "p1": 0.0008,
    "p2": -0.0005,
    "k3": 0.0,
}


def run(capsys, *argv):
    code = cli_main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def fov_sequence(tmp_path_factory):
    """The default calibration scene: 30 views of a 9x6 board through fov fx = fy = 0.6·W, omega 0.9."""
    out = tmp_path_factory.mktemp("calib_fov")
    assert cli_main(["synth", "calibration", str(out)]) == 0
    return out


def test_fov_camera_recovered_from_rendered_sequence(fov_sequence, tmp_path, capsys):
    code, out, err = run(
        capsys,
        "calibrate",
        "--images",
        fov_sequence,
        "--board",
        "9x6",
        "--square",
        "0.04",
        "--model",
        "fov",
        "-o",
        tmp_path / "camera.yaml",
    )
    assert code == 0, err
    true = load_camera(fov_sequence / "camera.yaml")
    fit = load_camera(tmp_path / "camera.yaml")
    assert isinstance(fit, FovCamera) and true.fx == true.fy == 0.6 * 640 and true.omega == 0.9
    assert abs(fit.fx / true.fx - 1) < 0.005 and abs(fit.fy / true.fy - 1) < 0.005
    assert abs(fit.cx - true.cx) < 1.0 and abs(fit.cy - true.cy) < 1.0
    assert abs(fit.omega - true.omega) < 0.01
    rms = float(out.split("RMS reprojection error: ")[1].split()[0])
    assert rms < 0.3
    assert "PTAM's normalised 5-vector" in out and " ".join(f"{v:.6f}" for v in fit.ptam_vector()) in out
    assert "warning" not in err  # the scene covers every cell of the image and tilts the board


def test_detected_corners_match_the_rendered_truth(fov_sequence):
    truth = np.loadtxt(fov_sequence / "corners.txt").reshape(-1, 54, 2)
    board = Board(9, 6, 0.04)
    errors = []
    for i, truth_i in enumerate(truth):
        img = cv2.imread(str(fov_sequence / "rgb" / f"{i:06d}.png"), cv2.IMREAD_GRAYSCALE)
        collector = ViewCollector(board, (640, 480), CFG)
        if collector.add(i, 0.0, img):
            c = collector.views[0].corners
            errors.append(
                min(
                    np.sqrt(np.mean(np.sum((c - truth_i) ** 2, 1))),
                    np.sqrt(np.mean(np.sum((c[::-1] - truth_i) ** 2, 1))),
                )
            )
    assert len(errors) >= 27  # of 30 rendered views
    assert np.sqrt(np.mean(np.square(errors))) < 0.08 and max(errors) < 0.15  # px


def test_radtan_camera_recovered_from_scene_file_video(tmp_path, capsys):
    scene = tmp_path / "radtan_scene.yaml"
    scene.write_text(yaml.safe_dump({"calibration": {"views": 24, "seed": 3}, "camera": RADTAN}))
    code, out, err = run(capsys, "synth", scene, tmp_path / "seq", "--video")
    assert code == 0, err
    code, out, err = run(
        capsys,
        "calibrate",
        "--video",
        tmp_path / "seq" / "video.avi",
        "--model",
        "radtan",
        "-o",
        tmp_path / "camera.yaml",
    )
    assert code == 0, err
    fit = load_camera(tmp_path / "camera.yaml")
    assert fit.model == "radtan"
    assert abs(fit.fx / RADTAN["fx"] - 1) < 0.005 and abs(fit.fy / RADTAN["fy"] - 1) < 0.005
    assert abs(fit.cx - RADTAN["cx"]) < 1.0 and abs(fit.cy - RADTAN["cy"]) < 1.0
    assert abs(fit.k1 - RADTAN["k1"]) < 0.01
    assert float(out.split("RMS reprojection error: ")[1].split()[0]) < 0.3


def synthetic_observations(camera, n_views, seed):
    """Board corners projected from poses spread over the image (no images, no detector)."""
    rng = np.random.default_rng(seed)
    board = Board(9, 6, 0.04)
    pts = board.points() - board.points().mean(0)
    obs = []
    while len(obs) < n_views:
        R = cv2.Rodrigues(np.append(rng.uniform(-0.6, 0.6, 2), rng.uniform(-0.5, 0.5)))[0]
        t = np.array([*rng.uniform(-0.35, 0.35, 2), rng.uniform(0.5, 0.8)])
        uv = camera.project(pts @ R.T + t)
        if np.all(camera.in_image(uv, 5.0)):
            obs.append(uv)
    return board.points() - board.points().mean(0), np.array(obs)


@pytest.mark.parametrize(
    "camera",
    [FovCamera(640, 480, 384.0, 380.0, 325.0, 236.0, 0.9), PinholeCamera(640, 480, 520.0, 518.0, 315.0, 245.0)],
)
def test_bad_views_are_dropped_and_the_fit_repeated(camera):
    points, obs = synthetic_observations(camera, 16, seed=1)
    rng = np.random.default_rng(2)
    obs = obs + rng.normal(0.0, 0.05, obs.shape)
    obs[[3, 11]] += rng.normal(0.0, 3.0, obs[[3, 11]].shape)  # two views with wrongly placed corners
    res = calibrate(camera.model, camera.size, points, obs, CFG)
    assert list(np.nonzero(~res.used)[0]) == [3, 11]
    assert res.view_rms[3] > 2.0 and res.view_rms[11] > 2.0
    assert res.rms < 0.1
    fit, true = res.camera, camera
    assert abs(fit.fx / true.fx - 1) < 0.002 and abs(fit.fy / true.fy - 1) < 0.002
    assert abs(fit.cx - true.cx) < 0.5 and abs(fit.cy - true.cy) < 0.5
    if camera.model == "fov":
        assert abs(fit.omega - true.omega) < 0.005


def test_view_selection_covers_the_image_then_spreads():
    camera = PinholeCamera(640, 480, 500.0, 500.0, 319.5, 239.5)
    board = Board(9, 6, 0.04)
    _, obs = synthetic_observations(camera, 12, seed=4)
    # 100 near-copies of view 0 (a video lingering on one pose) and the 11 others once each.
    views = [View(i, 0.0, obs[0] + 0.01 * i) for i in range(100)] + [
        View(100 + i, 0.0, o) for i, o in enumerate(obs[1:])
    ]
    cfg = default_config().replace(**{"calibrate.max_views": 12}).calibrate
    chosen = select_views(views, board, (640, 480), cfg)
    frames = [v.frame for v in chosen]
    assert len(chosen) == 12 and set(range(100, 111)) <= set(frames) and sum(f < 100 for f in frames) == 1


def test_missing_cells_are_named():
    centre = np.array([[300.0, 200.0], [340.0, 260.0], [320.0, 240.0]])
    assert missing_cells(centre, (640, 480), 3) == [
        "top-left",
        "top",
        "top-right",
        "left",
        "right",
        "bottom-left",
        "bottom",
        "bottom-right",
    ]
    everywhere = np.stack(np.meshgrid(np.linspace(0, 639, 5), np.linspace(0, 479, 5)), -1).reshape(-1, 2)
    assert missing_cells(everywhere, (640, 480), 3) == []


def test_parse_board():
    assert parse_board("9x6", 0.04) == Board(9, 6, 0.04)
    for bad, sq in (("9by6", 0.04), ("2x6", 0.04), ("7x7", 0.04), ("9x6", 0.0), ("9x6", float("nan"))):
        with pytest.raises(InputError):
            parse_board(bad, sq)


def assert_one_line_error(code, err, text):
    assert code == 2 and err.count("\n") == 1 and err.startswith("ptam: error: ") and text in err, err


def test_video_without_chessboard_exits_2(tmp_path, capsys):
    rng = np.random.default_rng(0)
    frames = [cv2.GaussianBlur(rng.integers(0, 255, (120, 160), dtype=np.uint8), (0, 0), 2) for _ in range(12)]
    write_video(tmp_path / "noise.avi", frames, 30.0, (160, 120))
    code, _, err = run(capsys, "calibrate", "--video", tmp_path / "noise.avi", "-o", tmp_path / "c.yaml")
    assert_one_line_error(code, err, "no 9x6 chessboard found in 12 frames of")
    assert not (tmp_path / "c.yaml").exists()


def test_too_few_views_exits_2(fov_sequence, tmp_path, capsys):
    (tmp_path / "few").mkdir()
    for i in (0, 5, 10, 15):
        shutil.copy(fov_sequence / "rgb" / f"{i:06d}.png", tmp_path / "few")
    code, _, err = run(capsys, "calibrate", "--images", tmp_path / "few", "-o", tmp_path / "c.yaml")
    assert_one_line_error(code, err, f"only 4 usable chessboard views, need at least {CFG.min_views}")


def test_bad_input_exits_2(tmp_path, capsys):
    (tmp_path / "broken.avi").write_bytes(b"not a video at all" * 100)
    code, _, err = run(capsys, "calibrate", "--video", tmp_path / "broken.avi")
    assert_one_line_error(code, err, "cannot open video")
    code, _, err = run(capsys, "calibrate", "--video", tmp_path / "broken.avi", "--board", "nine")
    assert_one_line_error(code, err, "--board must be COLSxROWS")
    code, _, err = run(capsys, "calibrate")
    assert_one_line_error(code, err, "give --video FILE, --camera v4l2[:DEVICE] | dc1394[:N|GUID] or --images DIR")
    code, _, err = run(capsys, "calibrate", "--images", tmp_path / "nowhere")
    assert_one_line_error(code, err, "not found")


def test_coverage_warning_names_the_empty_cells(fov_sequence, tmp_path, capsys):
    corners = np.loadtxt(fov_sequence / "corners.txt").reshape(-1, 54, 2)
    top_left = np.any((corners[..., 0] < 640 / 3) & (corners[..., 1] < 480 / 3), axis=1)
    (tmp_path / "part").mkdir()
    for i in np.nonzero(~top_left)[0]:
        shutil.copy(fov_sequence / "rgb" / f"{i:06d}.png", tmp_path / "part")
    code, _, err = run(capsys, "calibrate", "--images", tmp_path / "part", "-o", tmp_path / "c.yaml")
    assert code == 0
    assert "ptam: warning: no detected corner in the image's top-left (3x3 grid)" in err


@pytest.mark.parametrize(
    "model,intr",
    [
        ("fov", [384.0, 380.0, 325.0, 236.0, 0.9]),
        ("radtan", [500.0, 502.0, 322.0, 236.5, -0.28, 0.09, 0.0008, -0.0005, 0.01]),
    ],
)
def test_jacobian_matches_finite_differences(model, intr):
    rng = np.random.default_rng(5)
    points = Board(9, 6, 0.04).points()
    poses = np.concatenate([rng.uniform(-0.5, 0.5, (3, 3)), rng.uniform(-0.2, 0.2, (3, 3)) + [0, 0, 0.6]], axis=1)
    intr = np.array(intr)
    J_intr, J_pose = jacobian(model, (640, 480), intr, poses, points)
    h = 1e-6
    for k in range(len(intr)):
        d = np.zeros_like(intr)
        d[k] = h * max(1.0, abs(intr[k]))
        num = (
            project_views(model, (640, 480), intr + d, poses, points)
            - project_views(model, (640, 480), intr - d, poses, points)
        ) / (2 * d[k])
        assert np.allclose(J_intr[..., k], num, rtol=1e-5, atol=1e-4)
    for k in range(6):
        d = np.zeros_like(poses)
        d[:, k] = h
        num = (
            project_views(model, (640, 480), intr, poses + d, points)
            - project_views(model, (640, 480), intr, poses - d, points)
        ) / (2 * h)
        assert np.allclose(J_pose[..., k], num, rtol=1e-5, atol=1e-3)


def test_synth_lists_the_calibration_scene(capsys):
    code, out, _ = run(capsys, "synth", "--list")
    assert code == 0 and "calibration" in out.split()
