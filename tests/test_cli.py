"""Bad input on the command line: one line on stderr, exit code 2, never a traceback."""

import os
import subprocess
import sys

import cv2
import numpy as np
import yaml

from ptam.cli import main as cli_main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def ptam(*argv):
    return subprocess.run([sys.executable, "-m", "ptam", *argv], cwd=ROOT, capture_output=True, text=True, timeout=120)


def assert_one_line_error(proc, text):
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("ptam: error: ")
    assert text in proc.stderr


def test_run_missing_dataset_subprocess():
    assert_one_line_error(ptam("run", "--dataset", "/no/such/dir"), "dataset directory not found: /no/such/dir")


def test_run_unknown_config_key_subprocess():
    assert_one_line_error(ptam("run", "--set", "tracker.no_such_key=1"), "unknown config key 'tracker.no_such_key'")


def test_eval_missing_file_subprocess(tmp_path):
    assert_one_line_error(
        ptam("eval", str(tmp_path / "gt.txt"), str(tmp_path / "est.txt")), "trajectory file not found"
    )


def run_in_process(capsys, *argv):
    code = cli_main(["run", *argv])
    _, err = capsys.readouterr()
    assert err.count("\n") == 1
    return code, err.strip()


def test_run_checks_calibration(tmp_path, capsys):
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), np.full((48, 64), 40 * i, np.uint8))
    code, err = run_in_process(capsys, "--dataset", str(tmp_path))
    assert code == 2 and err == "ptam: error: no calibration: pass --calibration camera.yaml"

    calib = {"model": "pinhole", "width": 640, "height": 480, "fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5}
    (tmp_path / "wrong.yaml").write_text(yaml.safe_dump(calib))
    code, err = run_in_process(capsys, "--dataset", str(tmp_path), "--calibration", str(tmp_path / "wrong.yaml"))
    assert code == 2 and "is for 640x480 images" in err and "delivers 64x48" in err

    # The dataset's own camera.yaml is used when --calibration is absent.
    calib.update(width=64, height=48, cx=31.5, cy=23.5)
    (tmp_path / "camera.yaml").write_text(yaml.safe_dump(calib))
    code, err = run_in_process(capsys, "--dataset", str(tmp_path))
    assert code == 2 and err == "ptam: error: image of shape (48, 64) is too small for a 4-level pyramid"

    code, err = run_in_process(capsys, "--dataset", str(tmp_path), "--calibration", str(tmp_path / "none.yaml"))
    assert code == 2 and "calibration file not found" in err


def test_run_unopenable_camera(capsys):
    code, err = run_in_process(capsys, "--camera", "v4l2:/dev/video99")
    assert code == 2 and err == "ptam: error: cannot open camera v4l2:/dev/video99"


def test_run_without_texture_ends_cleanly_with_an_empty_trajectory(tmp_path, capsys):
    """PTAM §6.1 needs texture and motion: black frames, or too few frames, cannot initialise."""
    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i:04d}.png"), np.zeros((480, 640), np.uint8))
    calib = {
        "model": "fov",
        "width": 640,
        "height": 480,
        "fx": 384.0,
        "fy": 384.0,
        "cx": 319.5,
        "cy": 239.5,
        "omega": 0.9,
    }
    (tmp_path / "camera.yaml").write_text(yaml.safe_dump(calib))
    traj = tmp_path / "traj.txt"
    code = cli_main(["run", "--dataset", str(tmp_path), "--no-viewer", "--mode", "sync", "--trajectory", str(traj)])
    out = capsys.readouterr().out
    assert code == 0
    assert "initialisation did not succeed: too few corners" in out
    assert [line for line in traj.read_text().splitlines() if not line.startswith("#")] == []
