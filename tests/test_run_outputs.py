"""``ptam run``'s outputs survive a bad end: the trajectory is streamed, keyframes and map are checkpointed
atomically, SIGHUP stops a run like SIGTERM, output paths are checked before the first frame, and one output that
fails at the end does not stop the others (``ptam.commands.run_outputs``)."""

import errno
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ptam.cli import main as cli_main
from ptam.commands import run_outputs
from ptam.commands.run import STOP_SIGNALS, _StopRequest
from ptam.commands.run_outputs import TrajectoryStream, atomic_write
from ptam.eval import read_tum
from ptam.map.map_file import load_map
from tests.support import config, sequence

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = {**os.environ, "DISPLAY": "", "WAYLAND_DISPLAY": ""}
FPS = 30.0  # two_wall_short's frame rate
FLUSH_S = 1.0  # system.output_flush_s


def _pose(x: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, 2 * x, -x)
    return T


def _two_wall_short_frames() -> tuple[Path, list[tuple[str, str]]]:
    """two_wall_short's folder and its (timestamp, image path) rows."""
    src = sequence("two_wall_short")
    rows = [line.split() for line in (src / "rgb.txt").read_text().splitlines() if not line.startswith("#")]
    return src, [(t, p) for t, p in rows]


def _tum_folder(tmp_path, name: str, src: Path, rows) -> Path:
    """A TUM folder of ``src``'s images: rgb.txt of ``rows`` with absolute paths, and its camera."""
    d = tmp_path / name
    d.mkdir()
    (d / "rgb.txt").write_text("".join(f"{t} {src / p}\n" for t, p in rows))
    (d / "camera.yaml").write_text((src / "camera.yaml").read_text())
    return d


def _truncated(tmp_path, frames: int):
    """The first ``frames`` frames of two_wall_short as a TUM folder."""
    src, rows = _two_wall_short_frames()
    return _tum_folder(tmp_path, "short", src, rows[:frames])


def _there_and_back(tmp_path) -> tuple[Path, int]:
    """two_wall_short forward then backward (frame rate kept, timestamps increasing), as a TUM folder, and its frame
    count: 13.3 s of continuous motion, so a signal test on a loaded machine, where the map comes late, still has
    sequence left to interrupt (two_wall_short alone once ended before the kill)."""
    src, rows = _two_wall_short_frames()
    paths = [p for _, p in rows]
    paths = paths + paths[-2:0:-1]
    rows = [(f"{i / FPS:.6f}", p) for i, p in enumerate(paths)]
    return _tum_folder(tmp_path, "there_and_back", src, rows), len(rows)


def _outputs(tmp_path) -> dict:
    return {k: tmp_path / name for k, name in (("trajectory", "traj.txt"), ("map", "map.npz"), ("keyframes", "kf.txt"))}


def _argv(out: dict) -> list[str]:
    return [a for k, p in out.items() for a in (f"--{k}", str(p))]


def _summary(stdout: str) -> dict:
    words = stdout.split()
    return {k: int(words[words.index(k) + 1]) for k in ("frames", "tracked", "keyframes")}


def _poses_so_far(path) -> list[float]:
    """Timestamps of the complete lines in a file being written (tolerates a missing file)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return []
    lines = [line for line in text.split("\n")[:-1] if line and not line.startswith("#")]
    return [float(line.split()[0]) for line in lines]


# -- the stream and atomic writes, in isolation -------------------------------------------------------------
def test_stream_appends_in_time_order_and_rewrites_on_an_insertion_or_a_reset(tmp_path):
    path = tmp_path / "traj.txt"
    system = SimpleNamespace(trajectory=[])
    stream = TrajectoryStream(str(path), system.trajectory)
    system.trajectory += [(0.1 * i, _pose(i)) for i in (3, 4, 5)]
    stream(None, system)
    stream.flush()
    t, T = read_tum(path)
    assert np.allclose(t, [0.3, 0.4, 0.5]) and np.allclose(T[0, :3, 3], (3, 6, -3)) and stream.rewrites == 0
    # poses of frames seen while initialising, inserted late (as System does with bisect.insort), and a new one
    system.trajectory[:0] = [(0.1 * i, _pose(i)) for i in (0, 1, 2)]
    system.trajectory.append((0.6, _pose(6)))
    stream(None, system)
    system.trajectory.append((0.7, _pose(7)))
    stream(None, system)
    stream.flush()
    t, T = read_tum(path)
    assert np.allclose(t, 0.1 * np.arange(8)) and np.allclose(T[:, 0, 3], np.arange(8))
    assert stream.rewrites == 1 and stream.written == 8
    system.trajectory = [(2.0, _pose(7)), (1.5, _pose(8))]  # a reset, then an entry older than its predecessor
    stream(None, system)
    stream.flush()
    t, T = read_tum(path)
    assert list(t) == [1.5, 2.0] and np.allclose(T[0, :3, 3], (8, 16, -8)) and stream.rewrites == 2
    system.trajectory.append((2.5, _pose(9)))
    stream.close(system.trajectory)  # entries the observer never saw (System.close poses the last ones)
    assert list(read_tum(path)[0]) == [1.5, 2.0, 2.5]
    assert sorted(os.listdir(tmp_path)) == ["traj.txt"]


def test_atomic_write_leaves_the_previous_file_when_a_write_fails(tmp_path):
    path = tmp_path / "kf.txt"
    path.write_text("previous\n")

    def half_then_fail(tmp):
        with open(tmp, "w") as f:
            f.write("half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError):
        atomic_write(str(path), half_then_fail)
    assert path.read_text() == "previous\n" and os.listdir(tmp_path) == ["kf.txt"]
    atomic_write(str(path), lambda tmp: Path(tmp).write_text("new\n"))
    assert path.read_text() == "new\n" and os.listdir(tmp_path) == ["kf.txt"]
    assert os.stat(path).st_mode & 0o777 == 0o644


def test_sighup_is_handled_like_sigterm():
    before = signal.getsignal(signal.SIGHUP)  # SIG_DFL, or SIG_IGN under nohup: whatever it was comes back
    with _StopRequest() as stop:
        assert signal.SIGHUP in STOP_SIGNALS
        assert signal.getsignal(signal.SIGHUP) == signal.getsignal(signal.SIGTERM) == stop._handle
    assert signal.getsignal(signal.SIGHUP) == before


# -- paths checked before the first frame -------------------------------------------------------------------
def _bad_trajectory_dir(tmp_path, monkeypatch):
    (tmp_path / "here").mkdir()
    return str(tmp_path / "here"), "is a directory (give a file name)"


def _missing_folder(tmp_path, monkeypatch):
    return str(tmp_path / "nowhere" / "traj.txt"), f"directory {tmp_path / 'nowhere'} does not exist"


def _read_only_folder(tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    real = os.access
    monkeypatch.setattr(run_outputs.os, "access", lambda p, mode: False if str(p) == str(ro) else real(p, mode))
    return str(ro / "traj.txt"), f"directory {ro} is not writable"


@pytest.mark.parametrize("case", [_bad_trajectory_dir, _missing_folder, _read_only_folder], ids=lambda f: f.__name__)
def test_an_unwritable_output_ends_the_run_before_the_first_frame(case, tmp_path, monkeypatch, capsys):
    path, reason = case(tmp_path, monkeypatch)
    others = {"--map": tmp_path / "map.npz", "--keyframes": tmp_path / "kf.txt", "--ar-video": tmp_path / "ar.avi"}
    argv = ["run", "--dataset", str(tmp_path / "no-dataset"), "--no-viewer", "--trajectory", path]
    code = cli_main(argv + [a for k, p in others.items() for a in (k, str(p))])
    out, err = capsys.readouterr()
    # one line naming the option and the path; the dataset (which does not exist) was never opened
    assert code == 2 and out == "" and err == f"ptam: error: --trajectory {path}: {reason}\n"
    assert not any(p.exists() for p in others.values())


# -- a failure at the end ------------------------------------------------------------------------------------
@pytest.mark.slow
def test_an_output_failing_at_the_end_does_not_stop_the_others(tmp_path, monkeypatch, capsys):
    def refuse(path, *a):
        raise OSError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(run_outputs, "save_map", refuse)
    out = _outputs(tmp_path)
    video = tmp_path / "ar.avi"
    argv = ["run", "--dataset", str(_truncated(tmp_path, 60)), "--mode", "sync", "--no-viewer", "--ar", "grid"]
    code = cli_main(argv + _argv(out) + ["--ar-video", str(video), "--set", "system.map_checkpoint_keyframes=2"])
    stdout, err = capsys.readouterr()
    s = _summary(stdout)
    print(stdout, err)
    assert code == 2 and err.splitlines()[-1] == f"ptam: error: --map {out['map']}: cannot write: Permission denied"
    assert err.count("ptam: error") == 1
    assert s["frames"] == 60 and s["tracked"] >= 40 and s["keyframes"] >= 2
    t, _ = read_tum(out["trajectory"])
    assert len(t) == s["tracked"] and np.all(np.diff(t) > 0)
    assert len(read_tum(out["keyframes"])[0]) == s["keyframes"]
    assert video.stat().st_size > 0 and not out["map"].exists()
    assert sorted(os.listdir(tmp_path)) == sorted(["short", "traj.txt", "kf.txt", "ar.avi"])  # no temporaries


# -- signals (subprocesses) ----------------------------------------------------------------------------------
def _start(tmp_path, out: dict, *extra):
    dataset, frames = _there_and_back(tmp_path)
    argv = [sys.executable, "-m", "ptam", "run", "--dataset", str(dataset), "--mode", "realtime"]
    log = open(tmp_path / "stderr.txt", "w+")  # noqa: SIM115 (closed by the caller through proc.log)
    proc = subprocess.Popen(
        argv + ["--no-viewer", *_argv(out), *extra],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=log,
        text=True,
        env=ENV,
    )
    proc.log = log
    proc.frames = frames
    return proc


def _wait_for(condition, proc, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert proc.poll() is None, "the run ended early"
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.02)


@pytest.mark.slow
@pytest.mark.alone
def test_sigkill_leaves_the_trajectory_up_to_a_second_before_and_the_last_checkpoint(tmp_path):
    out = _outputs(tmp_path)
    # A checkpoint at every keyframe: with one every two, on a loaded machine (the tests run two at a time) the first
    # came late.
    proc = _start(tmp_path, out, "--set", "system.map_checkpoint_keyframes=1")
    try:
        _wait_for(lambda: len(_poses_so_far(out["trajectory"])) > 0 and out["map"].exists(), proc)
        w1, s1 = time.monotonic(), _poses_so_far(out["trajectory"])[-1]
        time.sleep(2.5)
        proc.kill()
        w2 = time.monotonic()
        proc.wait(timeout=30)
    finally:
        proc.kill()
        proc.log.close()
    assert proc.returncode == -signal.SIGKILL
    t, T = read_tum(out["trajectory"])  # whole lines only
    # realtime: sequence time runs with the clock, so at the kill it was at least s1 + (w2 - w1); the file holds
    # every frame tracked up to one flush interval (and a frame's processing) before that
    expected = s1 + (w2 - w1)
    print(f"{len(t)} poses up to t={t[-1]:.3f} s; at the kill the sequence was at >= {expected:.3f} s")
    assert np.all(np.diff(t) > 0) and np.all(np.isfinite(T))
    assert t[-1] >= expected - 1.5
    assert len(t) >= 0.5 * FPS * (t[-1] - t[0])  # realtime drops a few frames, not half of them
    loaded = load_map(out["map"], config().image)  # the last checkpoint, complete
    assert loaded.map.n_keyframes >= 2
    assert len(read_tum(out["keyframes"])[0]) >= 2


@pytest.mark.slow
@pytest.mark.alone
def test_sighup_ends_a_run_like_sigterm_and_writes_every_output(tmp_path):
    out = _outputs(tmp_path)
    proc = _start(tmp_path, out)
    try:
        # Until 40 poses are written (flushed each second), not a fixed time after the map: realtime drops frames
        # while the tracker is busy, and on a loaded machine (the tests run two at a time) 0.5 s gave 38.
        _wait_for(lambda: len(_poses_so_far(out["trajectory"])) >= 40, proc)
        proc.send_signal(signal.SIGHUP)
        stdout, _ = proc.communicate(timeout=60)
    finally:
        proc.kill()
        proc.log.close()
    err = (tmp_path / "stderr.txt").read_text()
    assert proc.returncode == 130, err  # as for SIGTERM and Ctrl-C
    assert "interrupted; wrote what was computed" in err and "Traceback" not in err
    s = _summary(stdout)
    assert 40 <= s["tracked"] <= s["frames"] < proc.frames
    assert len(read_tum(out["trajectory"])[0]) == s["tracked"]
    assert len(read_tum(out["keyframes"])[0]) == s["keyframes"]
    assert load_map(out["map"], config().image).map.n_keyframes == s["keyframes"]
