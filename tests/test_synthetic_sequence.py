"""Rendered sequences on disk: TUM layout, cache behaviour, lossless video, and ``ptam synth``."""

import dataclasses
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np
import pytest

import ptam.synthetic.sequence as sequence
from ptam.camera import load_camera
from ptam.cli import main as cli_main
from ptam.eval.tum_io import read_tum
from ptam.synthetic import ensure_sequence, load_scene
from ptam.synthetic.scene import Scene
from tests.support import TINY, config


def _synth(cache_dir):
    return dataclasses.replace(config().synthetic, cache_dir=str(cache_dir))


def _frames(d, n):
    return [cv2.imread(str(d / f"rgb/{i:06d}.png"), cv2.IMREAD_UNCHANGED) for i in range(n)]


def test_sequence_layout_and_contents(tiny, tmp_path):
    d = ensure_sequence(tiny, _synth(tmp_path / "cache"), video=True)
    assert d.parent == tmp_path / "cache" / "synthetic"
    scene = load_scene(tiny)
    frames = _frames(d, 6)
    for i, f in enumerate(frames):
        assert f.dtype == np.uint8 and f.shape == (60, 80)
        assert np.array_equal(f, scene.render_frame(i))
    lines = [ln.split() for ln in (d / "rgb.txt").read_text().splitlines() if not ln.startswith("#")]
    assert [name for _, name in lines] == [f"rgb/{i:06d}.png" for i in range(6)]
    assert np.allclose([float(t) for t, _ in lines], scene.timestamps, atol=1e-9)
    t, T = read_tum(d / "groundtruth.txt")
    assert np.allclose(t, scene.timestamps, atol=1e-9) and np.abs(T - scene.poses_T_wc).max() < 1e-12
    assert load_camera(d / "camera.yaml").to_dict() == scene.camera.to_dict()
    again = load_scene(d / "scene.yaml")  # the written description renders the same sequence
    assert again.hash == scene.hash and np.array_equal(again.render_frame(3), frames[3])
    cap = cv2.VideoCapture(str(d / "video.avi"))
    for f in frames:  # FFV1 is lossless
        ok, img = cap.read()
        assert ok and np.array_equal(img[..., 0], f)
    assert not cap.read()[0]
    assert [p.name for p in d.parent.iterdir()] == [d.name]  # no temporary directory left behind


def test_cache_hit_does_not_render(tiny, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    d = ensure_sequence(tiny, _synth(cache))
    assert not (d / "video.avi").exists()

    def fail(*a, **k):
        raise AssertionError("rendered again")

    with monkeypatch.context() as m:  # undoes only this patch, not the fixture's removal of PTAM_CACHE_DIR
        m.setattr(Scene, "render_frame", fail)
        assert ensure_sequence(tiny, _synth(cache)) == d
    assert ensure_sequence(tiny, _synth(cache), video=True) == d  # the video is added from the PNGs
    cap = cv2.VideoCapture(str(d / "video.avi"))
    assert int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) == 6
    tiny.write_text(TINY.replace("seed: 2", "seed: 3"))  # another scene content, another entry
    assert ensure_sequence(tiny, _synth(cache)) != d


def test_interrupted_render_leaves_no_cache_entry(tiny, tmp_path, monkeypatch):
    real = Scene.render_frame

    def flaky(self, i):
        if i == 3:
            raise KeyboardInterrupt
        return real(self, i)

    monkeypatch.setattr(Scene, "render_frame", flaky)
    with pytest.raises(KeyboardInterrupt):
        ensure_sequence(tiny, _synth(tmp_path / "cache"))
    assert list((tmp_path / "cache" / "synthetic").iterdir()) == []


def test_cache_dir_from_environment(tiny, tmp_path, monkeypatch):
    monkeypatch.setenv(sequence.CACHE_ENV, str(tmp_path / "env"))
    assert ensure_sequence(tiny, _synth(tmp_path / "ignored")).parent == tmp_path / "env" / "synthetic"


def test_cli_synth_then_eval_reports_zero_error(tiny, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv(sequence.CACHE_ENV, str(tmp_path / "cache"))
    assert cli_main(["synth", "--list"]) == 0
    assert "two_wall_short" in capsys.readouterr().out.split()
    out = tmp_path / "out"
    assert cli_main(["synth", str(tiny), str(out), "--video"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "camera.yaml",
        "groundtruth.txt",
        "rgb",
        "rgb.txt",
        "scene.yaml",
        "video.avi",
    ]
    capsys.readouterr()
    gt = str(out / "groundtruth.txt")
    assert cli_main(["eval", gt, gt]) == 0
    last = dict(kv.split("=") for kv in capsys.readouterr().out.strip().splitlines()[-1].split())
    assert float(last["ate_rmse_m"]) < 1e-9 and abs(float(last["scale"]) - 1.0) < 1e-9
    assert cli_main(["synth", str(tiny), str(out)]) == 2  # not empty
    assert "exists and is not empty" in capsys.readouterr().err
    assert cli_main(["synth", "no_such_scene", str(tmp_path / "o2")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
    assert cli_main(["synth", str(tiny)]) == 2


def test_a_scene_wanted_by_two_runs_at_once_is_rendered_once(tiny, tmp_path, monkeypatch):
    """Two runs (or the suite's two workers) asking for the same scene: the second waits for the first's render."""
    real = sequence.write_sequence
    calls = []
    started = threading.Event()

    def slow(*a, **k):
        calls.append(1)
        started.set()
        time.sleep(0.5)  # the second caller arrives while this render is under way
        return real(*a, **k)

    monkeypatch.setattr(sequence, "write_sequence", slow)
    with ThreadPoolExecutor(2) as pool:
        first = pool.submit(ensure_sequence, tiny, _synth(tmp_path / "cache"))
        started.wait()
        second = pool.submit(ensure_sequence, tiny, _synth(tmp_path / "cache"))
        assert first.result() == second.result()
    assert len(calls) == 1
    assert [p.name for p in (tmp_path / "cache" / "synthetic").iterdir()] == [first.result().name]


def test_a_cache_on_a_file_system_without_locks_still_renders(tiny, tmp_path, monkeypatch):
    def no_locks(*a):
        raise OSError(37, "No locks available")

    monkeypatch.setattr(sequence.fcntl, "flock", no_locks)
    d = ensure_sequence(tiny, _synth(tmp_path / "cache"))
    assert np.array_equal(_frames(d, 6)[2], load_scene(tiny).render_frame(2))
