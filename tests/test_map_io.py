"""Map files: a two_wall_short map saved by ``ptam run --map`` reloads exactly, relocalises the same sequence with
``--localize-only`` (no keyframes added), and broken files are refused with one clear error."""

import os

import cv2
import numpy as np
import pytest

from ptam.cli import main as cli_main
from ptam.config import load_config
from ptam.errors import InputError
from ptam.eval import associate, ate, read_tum
from ptam.map.map_file import VERSION, load_map, save_map
from tests.support import sequence

pytestmark = pytest.mark.slow  # replays a whole synthetic sequence

COLUMNS = (
    "X",
    "normal",
    "source_kf",
    "source_level",
    "source_xy",
    "bad",
    "meas_kf",
    "meas_pt",
    "meas_xy",
    "meas_level",
    "meas_source",
    "kf_T_cw",
    "good_point_indices",
)


def _rows(path):
    return [line for line in open(path).read().splitlines() if line and not line.startswith("#")]


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    d = sequence("two_wall_short")
    out = tmp_path_factory.mktemp("map")
    code = cli_main(
        [
            "run",
            "--dataset",
            str(d),
            "--mode",
            "sync",
            "--no-viewer",
            "--map",
            str(out / "map.npz"),
            "--keyframes",
            str(out / "kf.txt"),
        ]
    )
    assert code == 0
    return d, out


def test_saved_map_reloads_exactly(saved):
    d, out = saved
    cfg = load_config()
    loaded = load_map(out / "map.npz", cfg.image)
    snap = loaded.map.snapshot()
    assert snap.n_keyframes == len(_rows(out / "kf.txt")) >= 4 and snap.n_points > 1000
    # Keyframe images are the sequence's frames at the keyframes' timestamps, pyramids rebuilt from them.
    t_kf = np.array([kf.timestamp for kf in snap.keyframes])
    rgb = dict(line.split() for line in _rows(d / "rgb.txt"))
    for kf, t in zip(snap.keyframes, t_kf):
        frame = cv2.imread(str(d / rgb[f"{t:.9f}"]), cv2.IMREAD_GRAYSCALE)
        assert np.array_equal(kf.pyramid.levels[0], frame)
        assert len(kf.pyramid.corners[0]) > 1000 and kf.pyramid.n_levels == cfg.image.levels
    # Saving the loaded map and loading it again changes nothing.
    save_map(out / "again.npz", snap, loaded.camera, cfg.image.levels)
    again = load_map(out / "again.npz", cfg.image).map.snapshot()
    for name in COLUMNS:
        a, b = getattr(snap, name), getattr(again, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert loaded.camera.to_dict() == load_map(out / "again.npz", cfg.image).camera.to_dict()
    assert [f for f in os.listdir(out) if f.endswith(".tmp")] == []  # written atomically: no temporary left


def test_localize_only_tracks_the_same_sequence_without_adding_keyframes(saved, capsys):
    d, out = saved
    code = cli_main(
        [
            "run",
            "--dataset",
            str(d),
            "--mode",
            "sync",
            "--no-viewer",
            "--load-map",
            str(out / "map.npz"),
            "--localize-only",
            "--trajectory",
            str(out / "traj.txt"),
            "--keyframes",
            str(out / "kf2.txt"),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0
    t_gt, T_gt = read_tum(d / "groundtruth.txt")
    t, T = read_tum(out / "traj.txt")
    ig, ie = associate(t_gt, t, 0.01)
    rmse = ate(T_gt[ig, :3, 3], T[ie, :3, 3]).rmse
    print(f"localize-only: tracked {len(t)}/{len(t_gt)}, ATE {1e3 * rmse:.2f} mm")
    assert len(t) >= 0.95 * len(t_gt)
    assert _rows(out / "kf2.txt") == _rows(out / "kf.txt")  # the map's keyframes, none added
    assert "BA runs 0" in text
    assert rmse < 0.005


def test_broken_map_files_are_refused(saved, tmp_path):
    _, out = saved
    image_cfg = load_config().image
    data = (out / "map.npz").read_bytes()
    cases = {
        "missing.npz": None,
        "text.npz": b"not a map\n",
        "truncated.npz": data[: len(data) // 2],
        "flipped.npz": data[:1000] + bytes(b ^ 0x5A for b in data[1000:1100]) + data[1100:],
    }
    for name, content in cases.items():
        if content is not None:
            (tmp_path / name).write_bytes(content)
        with pytest.raises(InputError, match=str(tmp_path / name)):
            load_map(tmp_path / name, image_cfg)
    arrays = dict(np.load(out / "map.npz"))
    np.savez(tmp_path / "future.npz", **{**arrays, "version": np.array(VERSION + 1)})
    with pytest.raises(InputError, match=f"format version {VERSION + 1}; this ptam reads version {VERSION}"):
        load_map(tmp_path / "future.npz", image_cfg)
    v1 = {k: v for k, v in arrays.items() if k not in ("ray", "kf_panorama")}
    np.savez(tmp_path / "v1.npz", **{**v1, "version": np.array(1)})  # before panoramas: no rays, no panorama kfs
    old = load_map(tmp_path / "v1.npz", image_cfg).map.snapshot()
    assert old.n_points == load_map(out / "map.npz", image_cfg).map.snapshot().n_points and not old.ray.any()
    np.savez(tmp_path / "v2_without_rays.npz", **{**v1, "version": np.array(VERSION)})
    with pytest.raises(InputError, match="incomplete: no 'kf_panorama'"):
        load_map(tmp_path / "v2_without_rays.npz", image_cfg)
    np.savez(tmp_path / "bad_index.npz", **{**arrays, "meas_pt": arrays["meas_pt"] + len(arrays["X"])})
    with pytest.raises(InputError, match="inconsistent: map: point index out of range"):
        load_map(tmp_path / "bad_index.npz", image_cfg)
    with pytest.raises(InputError, match="pyramid levels"):
        load_map(out / "map.npz", load_config(overrides=["image.levels=3", "image.fast_thresholds=[10,15,15]"]).image)
    with pytest.raises(InputError, match="cannot write map file"):
        loaded = load_map(out / "map.npz", image_cfg)
        save_map(tmp_path / "no" / "dir.npz", loaded.map.snapshot(), loaded.camera, image_cfg.levels)
