"""The test suite, and a whole synth-then-run session, write nothing into the user's home directory."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from ptam.synthetic.sequence import CACHE_ENV, cache_root
from tests.support import TINY


def test_the_session_cache_is_outside_home(cfg):
    root = cache_root(cfg.synthetic.cache_dir).resolve()
    assert not root.is_relative_to(Path.home().resolve()) or os.environ.get("PTAM_TEST_CACHE_DIR")
    assert os.environ[CACHE_ENV] == str(cache_root(cfg.synthetic.cache_dir))


def test_synth_and_run_leave_home_empty(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    scene = tmp_path / "tiny.yaml"
    scene.write_text(TINY)
    env = {**os.environ, "HOME": str(home), CACHE_ENV: str(tmp_path / "cache"), "TMPDIR": tempfile.gettempdir()}
    env.pop("XDG_CACHE_HOME", None)
    run = [sys.executable, "-m", "ptam"]
    out = tmp_path / "seq"
    subprocess.run([*run, "synth", str(scene), str(out)], env=env, check=True, capture_output=True)
    small = ["--set", "image.levels=2", "--set", "image.fast_thresholds=[10,15]"]  # an 80x60 scene
    subprocess.run(
        [*run, "run", "--dataset", str(out), "--no-viewer", *small], env=env, check=True, capture_output=True
    )
    assert list(home.rglob("*")) == []
