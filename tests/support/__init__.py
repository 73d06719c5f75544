"""Builders shared by tests: cameras, synthetic problems. Not part of the ptam package."""

from __future__ import annotations

import functools
from pathlib import Path

from ptam.config import CaptureConfig, Config, load_config
from ptam.synthetic import ensure_sequence


@functools.cache
def config() -> Config:
    """The default configuration, loaded once per test session (not at import)."""
    return load_config()


def capture() -> CaptureConfig:
    return config().capture


def sequence(name: str, video: bool = False) -> Path:
    """A bundled synthetic sequence, rendered into the session's cache (``conftest.py`` points it at a temporary
    directory)."""
    return ensure_sequence(name, config().synthetic, video=video)
