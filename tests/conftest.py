"""Shared test setup: the synthetic-sequence cache lives in a temporary directory for the session, so the suite
leaves nothing in the user's home (set ``PTAM_TEST_CACHE_DIR`` to keep renders between sessions). Run two at a time
(pytest-xdist), the workers share the main process's directory: each rendering its own, they rendered a sequence
two tests on different workers use twice (desk_blur: 65 s each)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import tempfile
from collections.abc import Iterator

import pytest

from ptam.synthetic.sequence import CACHE_ENV

_created: list[str] = []


_SESSION_CACHE_ENV = "PTAM_TEST_SESSION_CACHE_DIR"  # the main process's directory, inherited by the workers


def pytest_configure(config: pytest.Config) -> None:
    cache = os.environ.get("PTAM_TEST_CACHE_DIR") or os.environ.get(_SESSION_CACHE_ENV)
    if not cache:
        cache = tempfile.mkdtemp(prefix="ptam-test-cache-")
        _created.append(cache)
        os.environ[_SESSION_CACHE_ENV] = cache
    os.environ[CACHE_ENV] = cache


@contextlib.contextmanager
def _cores(alone: bool) -> Iterator[None]:
    """A readers-writer lock over the machine's cores, shared by the xdist workers through the session directory:
    every test holds it shared, a test marked ``alone`` holds it exclusively. The turnstile (taken by both, held by
    a waiting ``alone`` test) lets the ``alone`` test in once the test already running ends, instead of after every
    test the other worker starts meanwhile."""
    directory = os.environ[CACHE_ENV]
    with (
        open(os.path.join(directory, ".cores-turnstile.lock"), "a") as turnstile,
        open(os.path.join(directory, ".cores.lock"), "a") as cores,
    ):
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            fcntl.flock(cores, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(cores, fcntl.LOCK_UN)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # ``alone`` tests last: one waits for the other worker's current test to end, which early in the run may be a
    # long render; at the end that worker's tail is the run's anyway.
    items.sort(key=lambda item: item.get_closest_marker("alone") is not None)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    # Realtime runs race the wall clock: beside another test on a two-core machine they dropped seconds of frames.
    with _cores(alone=item.get_closest_marker("alone") is not None):
        return (yield)


def pytest_unconfigure(config: pytest.Config) -> None:
    for path in _created:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(scope="session")
def cfg():
    """The default configuration (tests that change it use ``cfg.replace``)."""
    from tests.support import config

    return config()


@pytest.fixture
def tiny(tmp_path, monkeypatch):
    """The six-frame 80x60 scene file, with ``PTAM_CACHE_DIR`` unset so a test's own cache setting decides."""
    from ptam.synthetic.sequence import CACHE_ENV as cache_env
    from tests.support import TINY

    monkeypatch.delenv(cache_env, raising=False)
    path = tmp_path / "tiny.yaml"
    path.write_text(TINY)
    return path
