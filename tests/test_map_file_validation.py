"""Map files are checked before use: a corrupt member (wrong dtype, ndim or shape, NaN, an index or level out of
range, a pixel outside the image, a duplicate measurement, a header claiming more data than the file holds) is
refused with one InputError line naming the file and the field; ``ptam run --load-map`` exits 2 with that line.

Each corrupt file is a small valid map (built by hand, saved by ``save_map``) with one member rewritten."""

from __future__ import annotations

import io
import zipfile

import cv2
import numpy as np
import pytest

from ptam.camera import camera_from_dict
from ptam.camera.camera_file import save_camera
from ptam.cli import main as cli_main
from ptam.errors import InputError
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import Map
from ptam.map.map_file import load_map, save_map
from tests.support import config

W, H = 96, 64  # the smallest frames a 4-level pyramid takes (64 >> 3 = 8)
CAMERA = {"model": "pinhole", "width": W, "height": H, "fx": 80.0, "fy": 80.0, "cx": 47.5, "cy": 31.5}
N_KF, N_PT = 3, 40


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    """A valid map file: 3 keyframes, 40 points (one bad), a root and a second measurement per good point."""
    cfg = config()
    rng = np.random.default_rng(0)
    m = Map()
    for i in range(N_KF):
        T = np.eye(4)
        T[0, 3] = -0.1 * i
        img = rng.integers(0, 256, (H, W), dtype=np.uint8)
        m.add_keyframe(KeyFrame(i, Pyramid.build(img, cfg.image), 2.0, 0.2, 0.5 * i), T)
    X = np.c_[rng.uniform(-0.5, 0.5, (N_PT, 2)), rng.uniform(1.5, 2.5, N_PT)]
    kf = rng.integers(0, N_KF, N_PT)
    level = rng.integers(0, cfg.image.levels, N_PT)
    xy = rng.uniform([5, 5], [W - 6, H - 6], (N_PT, 2))
    m.add_points(X, np.tile([0.0, 0.0, -1.0], (N_PT, 1)), kf, level, xy)
    pts = np.r_[np.arange(N_PT), np.arange(N_PT)]
    source = np.r_[np.zeros(N_PT, int), np.ones(N_PT, int)]
    m.add_measurements(np.r_[kf, (kf + 1) % N_KF], pts, np.r_[xy, xy], np.r_[level, level], source)
    m.mark_bad([3])
    path = tmp_path_factory.mktemp("maps") / "good.npz"
    save_map(path, m.snapshot(), camera_from_dict(CAMERA), cfg.image.levels)
    return path


def arrays(path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def rewritten(good, tmp_path, change) -> str:
    """A copy of the good map with ``change(arrays)`` applied (it edits the dict in place)."""
    a = arrays(good)
    change(a)
    path = tmp_path / "bad.npz"
    np.savez_compressed(path, **a)
    return str(path)


def _set(name, value):
    return lambda a: a.__setitem__(name, value)


def _poke(name, index, value):
    def change(a):
        a[name] = a[name].copy()
        a[name][index] = value

    return change


def _duplicate_measurement(a):
    for k in ("meas_kf", "meas_pt", "meas_xy", "meas_level", "meas_source"):
        a[k] = np.concatenate([a[k], a[k][:1]])


def _short(name):
    return lambda a: a.__setitem__(name, a[name][:-1])


def _scaled_pose(a):
    a["kf_T_cw"] = a["kf_T_cw"].copy()
    a["kf_T_cw"][2, :3, :3] *= 1.5


# (case, change, what the one line says besides the file name)
ROW_TRACEBACKS = [
    ("levels [4,4]", _set("levels", np.array([4, 4])), r"'levels' must be a single integer, got int64 of shape \(2,\)"),
    (
        "2-D timestamps",
        lambda a: a.__setitem__("kf_timestamp", np.c_[a["kf_timestamp"], a["kf_timestamp"]]),
        r"'kf_timestamp' must be 1-D, got shape \(3, 2\)",
    ),
    ("depth mean 0", _poke("kf_depth_mean", 1, 0.0), r"'kf_depth_mean\[1\]' = 0.0 must be positive"),
    ("source level 9", _poke("source_level", 7, 9), r"'source_level' holds pyramid level 9; .* levels 0..3"),
    ("negative level", _poke("meas_level", 0, -1), r"'meas_level' holds pyramid level -1"),
]
ROW_SILENT = [
    ("NaN pose", _poke("kf_T_cw", (1, 0, 3), np.nan), r"'kf_T_cw\[1, 0, 3\]' is nan: every value must be finite"),
    ("NaN point", _poke("X", (5, 2), np.nan), r"'X\[5, 2\]' is nan"),
    ("inf normal", _poke("normal", (0, 0), np.inf), r"'normal\[0, 0\]' is inf"),
    (
        "source_xy 1e9",
        _poke("source_xy", (4, 0), 1e9),
        rf"'source_xy\[4\]' = \[1000000000.0, .*\] lies outside the {W}x{H}",
    ),
    (
        "float indices",
        lambda a: a.__setitem__("meas_pt", a["meas_pt"].astype(np.float64)),
        r"'meas_pt' must be an integer array, got dtype float64",
    ),
    ("duplicate measurement", _duplicate_measurement, r"keyframe \d+ measures point 0 more than once"),
    (
        "point index",
        _poke("meas_pt", 2, N_PT),
        rf"inconsistent: map: point index out of range \[0, {N_PT}\) in 'meas_pt'",
    ),
    ("keyframe index", _poke("source_kf", 2, -1), rf"keyframe index out of range \[0, {N_KF}\) in 'source_kf'"),
    ("short column", _short("normal"), rf"'normal' has shape \({N_PT - 1}, 3\), expected \({N_PT}, 3\)"),
    ("not rigid", _scaled_pose, r"'kf_T_cw\[2\]' is not a rigid transform"),
    ("not a unit normal", _poke("normal", (6, 2), -2.0), r"'normal\[6\]' = \[0.0, 0.0, -2.0\] must be a unit vector"),
    ("measurement source", _poke("meas_source", 0, 7), r"'meas_source' must be 0..3, got 0..7"),
    ("bool as int", lambda a: a.__setitem__("bad", a["bad"].astype(np.int8)), r"'bad' must be a bool array"),
    (
        "image size",
        lambda a: a.__setitem__("kf_image0", a["kf_image0"][:, :, :-1]),
        rf"'kf_image0' has shape \(3, {H}, {W - 1}\), expected \(3, {H}, {W}\)",
    ),
    (
        "float images",
        lambda a: a.__setitem__("kf_image0", a["kf_image0"].astype(np.float32)),
        r"'kf_image0' must be uint8 images, got dtype float32",
    ),
    ("no keyframes", lambda a: a.update({k: a[k][:0] for k in a if k.startswith("kf_")}), r"no keyframes"),
    ("camera", _set("camera", np.array(3)), r"'camera' must be a single string"),
]


def test_the_good_map_loads(good):
    snap = load_map(good, config().image).map.snapshot()
    assert snap.n_keyframes == N_KF and snap.n_points == N_PT - 1 and len(snap.meas_kf) == 2 * (N_PT - 1)


@pytest.mark.parametrize("case, change, message", ROW_TRACEBACKS, ids=[c[0] for c in ROW_TRACEBACKS])
def test_members_that_raised_tracebacks_are_refused(good, tmp_path, case, change, message):
    path = rewritten(good, tmp_path, change)
    with pytest.raises(InputError, match=rf"^map file {path}: {message}") as e:
        load_map(path, config().image)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("case, change, message", ROW_SILENT, ids=[c[0] for c in ROW_SILENT])
def test_members_that_were_accepted_silently_are_refused(good, tmp_path, case, change, message):
    path = rewritten(good, tmp_path, change)
    with pytest.raises(InputError, match=rf"^map file {path}:? .*{message}") as e:
        load_map(path, config().image)
    assert "\n" not in str(e.value)


def _npz_with_claim(path, a: dict, name: str, shape: tuple) -> None:
    """An archive whose member ``name`` has a header claiming ``shape`` but holds its real (small) data."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for k, v in a.items():
            buf = io.BytesIO()
            if k == name:
                header = {"descr": np.lib.format.dtype_to_descr(v.dtype), "fortran_order": False, "shape": shape}
                np.lib.format.write_array_header_1_0(buf, header)
                buf.write(np.ascontiguousarray(v).tobytes())
            else:
                np.lib.format.write_array(buf, v, allow_pickle=False)
            zf.writestr(f"{k}.npy", buf.getvalue())


@pytest.mark.parametrize("name, shape", [("X", (10**12, 3)), ("kf_image0", (10**6, H, W)), ("meas_pt", (2**40,))])
def test_a_header_claiming_a_huge_shape_allocates_nothing(good, tmp_path, name, shape):
    path = tmp_path / "claim.npz"
    _npz_with_claim(path, arrays(good), name, shape)
    with pytest.raises(InputError, match=rf"^map file {path}: '{name}' claims shape \({shape[0]},.*bytes\) but holds"):
        load_map(path, config().image)


def test_a_zip_member_claiming_more_than_deflate_can_hold_is_refused(good, tmp_path):
    path = tmp_path / "ratio.npz"
    _npz_with_claim(path, arrays(good), "X", (N_PT, 3))
    data = bytearray(path.read_bytes())
    # Patch the central directory's uncompressed size of X.npy to 2 GB (its local header is left alone).
    entry = data.rfind(b"PK\x01\x02", 0, data.rfind(b"X.npy"))
    data[entry + 24 : entry + 28] = (2**31).to_bytes(4, "little")
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=rf"^map file {path}: 'X' claims 2147483648 bytes from \d+ stored bytes"):
        load_map(path, config().image)


def test_run_with_a_corrupt_map_exits_2_with_one_line(good, tmp_path, capsys):
    path = rewritten(good, tmp_path, _poke("source_level", 7, 9))
    dataset = tmp_path / "dataset"
    dataset.mkdir()
    code = cli_main(["run", "--dataset", str(dataset), "--no-viewer", "--load-map", path])
    err = capsys.readouterr().err
    assert code == 2
    assert err.splitlines() == [
        f"ptam: error: map file {path}: 'source_level' holds pyramid level 9; the map's pyramid has levels 0..3"
    ]
    assert "Traceback" not in err


def test_run_with_a_map_from_another_image_size_exits_2_with_one_line(good, tmp_path, capsys):
    """The keyframes' images, patches and relocalisation descriptors are at the map's size: a camera with other
    frames cannot track against them (it once failed inside the relocaliser with a traceback)."""
    dataset = tmp_path / "dataset"
    dataset.mkdir()
    rng = np.random.default_rng(1)
    for i in range(3):
        cv2.imwrite(str(dataset / f"{i:06d}.png"), rng.integers(0, 256, (2 * H, 2 * W), dtype=np.uint8))
    big = dict(CAMERA, width=2 * W, height=2 * H, fx=160.0, fy=160.0, cx=95.5, cy=63.5)
    save_camera(camera_from_dict(big), dataset / "camera.yaml")
    code = cli_main(["run", "--dataset", str(dataset), "--no-viewer", "--fps", "30", "--load-map", str(good)])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    assert err.splitlines()[-1].startswith(f"ptam: error: the map was built from {W}x{H} images but ")
    assert err.splitlines()[-1].endswith(f"delivers {2 * W}x{2 * H}; build a new map for this camera")
