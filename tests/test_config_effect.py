"""Every ``--set`` reaches the code it configures: library functions take their config from the caller and
never fall back to the defaults (the three settings that used to be ignored, each through the command line)."""

from __future__ import annotations

import pytest

import ptam.synthetic.sequence as sequence
from ptam.cli import main as cli_main
from ptam.commands.bench import BENCHMARKS
from ptam.system import core as system


def test_render_threads_and_cache_dir_reach_the_renderer(tiny, tmp_path, monkeypatch):
    used = []
    real = sequence.write_sequence

    def spy(scene, out, video=False, threads=2, progress=True):
        used.append(threads)
        return real(scene, out, video=video, threads=threads, progress=progress)

    monkeypatch.setattr(sequence, "write_sequence", spy)
    cache = tmp_path / "my-cache"
    args = ["synth", str(tiny), str(tmp_path / "out"), "--set", "synthetic.render_threads=3"]
    assert cli_main([*args, "--set", f"synthetic.cache_dir={cache}"]) == 0
    assert used == [3]
    assert len(list((cache / "synthetic").iterdir())) == 1  # rendered into the configured cache


class _Stop(Exception):
    pass


@pytest.mark.parametrize("name", sorted(BENCHMARKS))
def test_benchmarks_render_into_the_configured_cache(name, tmp_path, monkeypatch):
    import importlib

    module = importlib.import_module(f"ptam.bench.{BENCHMARKS[name][0]}")
    seen = []

    def fake_ensure(scene, cfg, video=False):
        seen.append(cfg.cache_dir)
        raise _Stop

    monkeypatch.setattr(module, "ensure_sequence", fake_ensure)
    with pytest.raises(_Stop):
        cli_main(["bench", name, "two_wall", "--set", f"synthetic.cache_dir={tmp_path}"])
    assert seen == [str(tmp_path)]


def test_run_dataset_stamps_frames_at_the_configured_rate(tmp_path, monkeypatch, cfg):
    rates = []

    def fake_open(path, fps):
        rates.append(fps)
        raise _Stop

    monkeypatch.setattr(system, "open_dataset", fake_open)
    monkeypatch.setattr(system, "load_camera", lambda path: None)
    with pytest.raises(_Stop):
        system.run_dataset(tmp_path, cfg.replace(**{"capture.default_fps": 12.5}))
    assert rates == [12.5]
