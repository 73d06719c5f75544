"""Bad input gets one line on stderr and exit code 2, never a traceback: YAML files that are not UTF-8, config
values outside their field's range (through ``--set`` and ``--config`` alike), a ground truth that never moves,
timestamps that do not increase (rgb.txt, EuRoC data.csv, TUM trajectories)."""

from __future__ import annotations

import math
import re
import typing

import cv2
import numpy as np
import pytest

from ptam.camera import load_camera
from ptam.cli import main as cli_main
from ptam.config import Config, load_config
from ptam.config.sections import Range
from ptam.errors import ConfigError, InputError
from ptam.eval import ate, read_tum, write_tum
from ptam.geometry import se3, so3
from tests.support import capture

NOT_UTF8 = "model: pinhole  # calibrated at the caf\u00e9\n".encode("latin-1")  # é as one byte 0xe9
W, H = 96, 64
CAMERA_YAML = f"model: pinhole\nwidth: {W}\nheight: {H}\nfx: 80.0\nfy: 80.0\ncx: 47.5\ncy: 31.5\n"


def run_cli(capsys, *argv) -> tuple[int, str]:
    """Exit code and the one stderr line of ``ptam ARGV`` (asserts there is exactly one, and no traceback)."""
    code = cli_main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert "Traceback" not in err and len(lines) == 1, err
    return code, lines[0]


def tum_dataset(root, stamps, camera: bytes | str = CAMERA_YAML):
    """A TUM-layout dataset of small random frames at ``stamps`` (written in the given order)."""
    (root / "rgb").mkdir(parents=True)
    rng = np.random.default_rng(1)
    lines = ["# timestamp filename"]
    for i, t in enumerate(stamps):
        cv2.imwrite(str(root / "rgb" / f"{i}.png"), rng.integers(0, 256, (H, W), dtype=np.uint8))
        lines.append(f"{t:.6f} rgb/{i}.png")
    (root / "rgb.txt").write_text("\n".join(lines) + "\n")
    (root / "camera.yaml").write_bytes(camera if isinstance(camera, bytes) else camera.encode())
    return root


# -- YAML that is not UTF-8 ---------------------------------------------------------------------------------------


def test_camera_yaml_not_utf8(tmp_path, capsys):
    d = tum_dataset(tmp_path / "d", [1.0, 1.1], camera=NOT_UTF8)
    with pytest.raises(InputError, match=rf"^cannot read calibration {d / 'camera.yaml'}: 'utf-8' codec can't decode"):
        load_camera(d / "camera.yaml")
    code, line = run_cli(capsys, "run", "--dataset", d, "--no-viewer")
    assert code == 2 and line.startswith(f"ptam: error: cannot read calibration {d / 'camera.yaml'}: 'utf-8'")


def test_config_file_not_utf8(tmp_path, capsys):
    bad = tmp_path / "mine.yaml"
    bad.write_bytes(b"tracker:\n  max_patches: 500  # \xff\n")
    with pytest.raises(ConfigError, match=rf"^cannot read config {bad}: 'utf-8' codec can't decode byte 0xff"):
        load_config([str(bad)])
    code, line = run_cli(capsys, "eval", tmp_path / "gt.txt", tmp_path / "est.txt", "--config", bad)
    assert code == 2 and line.startswith(f"ptam: error: cannot read config {bad}: 'utf-8' codec")


def test_scene_file_not_utf8(tmp_path):
    from ptam.synthetic.spec import resolve_scene

    scene = tmp_path / "scene.yaml"
    scene.write_bytes(NOT_UTF8)
    with pytest.raises(InputError, match=rf"^cannot read scene {scene}: 'utf-8' codec"):
        resolve_scene(scene)


# -- config ranges ------------------------------------------------------------------------------------------------


def _numeric_fields():
    """(section.key, Annotated type hint) of every int / float / list-of-number field of every section."""
    for sec, sec_type in typing.get_type_hints(Config).items():
        for key, hint in typing.get_type_hints(sec_type, include_extras=True).items():
            base = typing.get_args(hint)[0] if typing.get_origin(hint) is typing.Annotated else hint
            inner = typing.get_args(base)[0] if typing.get_origin(base) is list else base
            if inner in (int, float):
                yield f"{sec}.{key}", hint


def test_every_numeric_field_has_a_range_and_its_default_lies_in_it():
    cfg = load_config()
    fields = list(_numeric_fields())
    assert len(fields) > 200
    missing = [
        name for name, hint in fields if not any(isinstance(m, Range) for m in getattr(hint, "__metadata__", ()))
    ]
    assert missing == [], f"numeric config fields without a Range: {', '.join(missing)}"
    for name, hint in fields:
        (rng,) = [m for m in hint.__metadata__ if isinstance(m, Range)]
        sec, key = name.split(".")
        value = getattr(getattr(cfg, sec), key)
        values = value if isinstance(value, list) else [value]
        assert all(v in rng for v in values), f"default {name} = {value} outside {rng}"
        assert rng.length is None or len(values) == rng.length, name


def test_range_notation():
    r = Range("(0, inf)")
    assert 1e-300 in r and 0 not in r and math.inf not in r and math.nan not in r and -1 not in r
    assert 1 in Range("[0, 1]") and 0 in Range("[0, 1]") and 1.0000001 not in Range("[0, 1]")
    assert math.inf in Range("[0, inf]") and 3.2 not in Range("(0, pi)") and 3.1 in Range("(0, pi)")
    assert str(Range("[1, 65535]")) == "[1, 65535]"
    for bad in ("0, 1", "[1, 0]", "[0; 1]", "[a, 1]"):
        with pytest.raises(ValueError):
            Range(bad)


@pytest.mark.parametrize(
    "override, message",
    [
        ("system.mapper_idle_wait_s=-1", "config: system.mapper_idle_wait_s must be in (0, inf), got -1"),
        ("system.mapper_idle_wait_s=.nan", "config: system.mapper_idle_wait_s must be in (0, inf), got nan"),
        ("system.mapper_idle_wait_s=.inf", "config: system.mapper_idle_wait_s must be in (0, inf), got inf"),
        ("tracker.max_patches=-5", "config: tracker.max_patches must be in [1, inf), got -5"),
        ("viewer.queue_size=0", "config: viewer.queue_size must be in [1, inf), got 0"),
        ("tracker.quality_good=1.5", "config: tracker.quality_good must be in [0, 1], got 1.5"),
        ("image.fast_thresholds=[10, 15, 300, 10]", "config: image.fast_thresholds[2] must be in [0, 255], got 300"),
        ("capture.camera_size=[640]", "config: capture.camera_size must have 2 elements, got 1"),
        ("viewer.grpc_port=70000", "config: viewer.grpc_port must be in [1, 65535], got 70000"),
    ],
)
def test_out_of_range_set_exits_2_with_one_line(tmp_path, capsys, override, message):
    with pytest.raises(ConfigError, match=f"^{re.escape(message)}$"):
        load_config(overrides=[override])
    code, line = run_cli(capsys, "eval", tmp_path / "gt.txt", tmp_path / "est.txt", "--set", override)
    assert code == 2 and line == f"ptam: error: {message}"


def test_a_config_file_is_checked_like_set(tmp_path, capsys):
    f = tmp_path / "mine.yaml"
    f.write_text("system:\n  mapper_idle_wait_s: -1\n")
    code, line = run_cli(capsys, "eval", tmp_path / "gt.txt", tmp_path / "est.txt", "--config", f)
    assert code == 2 and line == f"ptam: error: config: system.mapper_idle_wait_s must be in (0, inf), got -1 ({f})"


# -- ptam eval: a ground truth without motion ---------------------------------------------------------------------


def _trajectory(n=30):
    t = 100.0 + np.arange(n) / 30.0
    s = np.linspace(0.0, 1.0, n)
    return t, se3.from_Rt(so3.exp(np.outer(s, [0.0, 0.3, 0.0])), np.stack([s, 0.5 * s**2, 0.1 * s], axis=1))


def test_eval_refuses_a_ground_truth_that_never_moves(tmp_path, capsys):
    t, T = _trajectory()
    still = T.copy()
    still[:, :3, 3] = [1.0, 2.0, 3.0]  # turning on the spot: the positions never change
    with pytest.raises(InputError, match=r"^ground truth never moves: ATE after Sim\(3\) is undefined$"):
        ate(still[:, :3, 3], T[:, :3, 3])
    assert ate(still[:, :3, 3], T[:, :3, 3], with_scale=False).rmse > 0  # SE(3): defined
    write_tum(tmp_path / "gt.txt", t, still)
    write_tum(tmp_path / "est.txt", t, T)
    code, line = run_cli(capsys, "eval", tmp_path / "gt.txt", tmp_path / "est.txt")
    assert code == 2 and line == "ptam: error: ground truth never moves: ATE after Sim(3) is undefined"


# -- timestamps that do not increase strictly ----------------------------------------------------------------------


@pytest.mark.parametrize("stamps, line", [([1.0, 1.1, 1.05, 1.2], 4), ([1.0, 1.1, 1.1, 1.2], 4)])
def test_rgb_txt_timestamps_must_increase(tmp_path, capsys, stamps, line):
    from ptam.capture import open_dataset

    d = tum_dataset(tmp_path / "d", stamps)
    # rgb.txt line 1 is the comment, so frame i is on line i + 2.
    message = rf"^{d / 'rgb.txt'}:{line}: timestamp {stamps[2]} is not after the previous image's 1.1 "
    with pytest.raises(InputError, match=message):
        open_dataset(str(d), capture().default_fps)
    code, err = run_cli(capsys, "run", "--dataset", d, "--no-viewer")
    assert code == 2 and err.startswith(f"ptam: error: {d / 'rgb.txt'}:{line}: timestamp")


def test_euroc_data_csv_timestamps_must_increase(tmp_path):
    from ptam.capture import open_dataset

    cam0 = tmp_path / "mav0" / "cam0"
    (cam0 / "data").mkdir(parents=True)
    ns = [1403636579763555584, 1403636579813555584, 1403636579813555584]
    for t in ns:
        cv2.imwrite(str(cam0 / "data" / f"{t}.png"), np.zeros((H, W), np.uint8))
    (cam0 / "data.csv").write_text("#timestamp [ns],filename\n" + "".join(f"{t},{t}.png\n" for t in ns))
    with pytest.raises(InputError, match=rf"^{cam0 / 'data.csv'}:4: timestamp {ns[2]} is not after"):
        open_dataset(str(tmp_path), capture().default_fps)
    (cam0 / "data.csv").write_text("#timestamp [ns],filename\n" + "".join(f"{t},{t}.png\n" for t in ns[::-1]))
    with pytest.raises(InputError, match=rf"^{cam0 / 'data.csv'}:3: timestamp {ns[1]} is not after"):
        open_dataset(str(tmp_path), capture().default_fps)
    (cam0 / "data.csv").write_text("#timestamp [ns],filename\n99999999999999999999,a.png\n")
    with pytest.raises(InputError, match=r"data.csv:2: expected 'timestamp_ns,filename'"):
        open_dataset(str(tmp_path), capture().default_fps)


def test_trajectory_timestamps_must_increase(tmp_path, capsys):
    t, T = _trajectory(10)
    write_tum(tmp_path / "gt.txt", t, T)
    read_tum(tmp_path / "gt.txt")  # ptam's own files are sorted
    order = np.r_[0:5, 6, 5, 7:10]
    write_tum(tmp_path / "est.txt", t[order], T[order], header="swapped")
    # Two header lines, then poses: pose i is on line i + 3; the swap makes pose 6 (line 9) go back in time.
    with pytest.raises(InputError, match=rf"^{tmp_path / 'est.txt'}:9: timestamp {t[5]:.9f} is not after"):
        read_tum(tmp_path / "est.txt")
    code, line = run_cli(capsys, "eval", tmp_path / "gt.txt", tmp_path / "est.txt")
    assert code == 2 and line.startswith(f"ptam: error: {tmp_path / 'est.txt'}:9: timestamp")
    write_tum(tmp_path / "dup.txt", np.r_[t[:3], t[2:]], np.r_[T[:3], T[2:]])
    with pytest.raises(InputError, match=rf"dup.txt:5: timestamp {t[2]:.9f} is not after the previous pose's"):
        read_tum(tmp_path / "dup.txt")


def test_a_frame_of_another_size_than_the_camera_is_refused(tmp_path):
    """The library's ``System.process`` (the command line checks the source's size against the calibration first):
    a frame of another size would be tracked through the wrong intrinsics."""
    from ptam.capture.frame import Frame
    from ptam.system import System

    (tmp_path / "camera.yaml").write_text(CAMERA_YAML)
    camera = load_camera(tmp_path / "camera.yaml")
    image = np.random.default_rng(0).integers(0, 256, (2 * H, 2 * W), dtype=np.uint8)
    with System(camera, load_config(), mode="sync") as system:
        with pytest.raises(InputError, match=rf"^frame 7 is {2 * W}x{2 * H} but the camera is {W}x{H}$"):
            system.process(Frame(7, 0.25, image))
        assert system.process(Frame(8, 0.3, image[:H, :W].copy())).state.name == "INITIALISING"
