"""Where the recording goes: the native rerun viewer (spawned), an ``.rrd`` file, or a web viewer served on
127.0.0.1 only.

Every server ptam starts listens on 127.0.0.1. rerun's Python ``serve_web_viewer`` binds every interface, so
``--serve`` runs the rerun command-line server (``rerun --serve-web --bind 127.0.0.1``) as a child process and
streams to it; the child ends with the run. ``rr.spawn`` passes no bind address to the native viewer, whose gRPC
server then listens on every interface (rerun's default ``--bind 0.0.0.0``), so the native viewer is started
here, as ``rr.spawn`` would start it but with ``--bind 127.0.0.1``; it stays open after the run, like a spawned one.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import time
import uuid
from dataclasses import dataclass
from urllib.parse import quote

import rerun as rr

from ..errors import InputError
from ..vocabulary import RrdFooter

APPLICATION_ID = "ptam"
LOCALHOST = "127.0.0.1"
SPAWN_MEMORY_LIMIT = "75%"  # rr.spawn's default memory limit for the native viewer (rerun drops the oldest data)


def has_display() -> bool:
    """An X11 or Wayland session to open the native viewer in."""
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _rerun_executable(purpose: str = "--serve") -> str:
    import rerun_cli

    bundled = os.path.join(os.path.dirname(rerun_cli.__file__), "rerun")
    path = bundled if os.path.isfile(bundled) else shutil.which("rerun")
    if path is None:
        raise InputError(f"{purpose} needs the rerun command-line viewer (pip install rerun-sdk)")
    return path


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((LOCALHOST, port))
        except OSError:
            return False
    return True


def _listening(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(0.2)
        return s.connect_ex((LOCALHOST, port)) == 0


@dataclass
class WebServer:
    """A ``rerun --serve-web`` child process bound to 127.0.0.1: a gRPC proxy plus the web viewer's files."""

    process: subprocess.Popen
    grpc_url: str
    url: str

    @classmethod
    def start(cls, viewer_cfg) -> WebServer:
        grpc, web = viewer_cfg.grpc_port, viewer_cfg.web_port
        for name, port in (("viewer.grpc_port", grpc), ("viewer.web_port", web)):
            if not _port_free(port):
                raise InputError(
                    f"cannot serve the web viewer: port {port} on {LOCALHOST} is in use "
                    f"(choose another with --set {name}=PORT)"
                )
        cmd = [
            _rerun_executable(),
            "--serve-web",
            "--bind",
            LOCALHOST,
            "--port",
            str(grpc),
            "--web-viewer-port",
            str(web),
            "--server-memory-limit",
            viewer_cfg.server_memory_limit,
        ]
        # Own session: a Ctrl-C meant for the run must not stop the server before the outputs are written.
        process = subprocess.Popen(
            cmd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            env={**os.environ, "RERUN_APP_ONLY": "true"},
        )
        deadline = time.monotonic() + viewer_cfg.serve_start_timeout_s
        while not (_listening(grpc) and _listening(web)):
            if process.poll() is not None or time.monotonic() > deadline:
                process.kill()
                process.wait()
                raise InputError(f"the rerun web viewer did not start on {LOCALHOST}:{web}")
            time.sleep(0.1)
        grpc_url = f"rerun+http://{LOCALHOST}:{grpc}/proxy"
        return cls(process, grpc_url, f"http://{LOCALHOST}:{web}/?url={quote(grpc_url, safe='')}")

    def close(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def native_viewer_command(viewer_cfg) -> list[str]:
    """The command ``rr.spawn`` runs for the native viewer (its memory limits, no welcome screen, data expected
    soon), plus ``--bind 127.0.0.1``."""
    return [
        _rerun_executable("the native viewer"),
        "--bind",
        LOCALHOST,
        "--port",
        str(viewer_cfg.grpc_port),
        "--memory-limit",
        SPAWN_MEMORY_LIMIT,
        "--server-memory-limit",
        viewer_cfg.server_memory_limit,
        "--hide-welcome-screen",
        "--expect-data-soon",
    ]


@dataclass
class NativeViewer:
    """The native rerun viewer listening on 127.0.0.1:``viewer.grpc_port`` (``process`` None: one was already
    listening there, and is used as ``rr.spawn`` would use it)."""

    process: subprocess.Popen | None
    grpc_url: str

    @classmethod
    def start(cls, viewer_cfg) -> NativeViewer:
        """Start the viewer (detached: it outlives the run) and wait until it listens. A viewer that cannot start
        (no display, no GPU) raises RuntimeError: the run goes on without it."""
        port = viewer_cfg.grpc_port
        url = f"rerun+http://{LOCALHOST}:{port}/proxy"
        if _listening(port):
            return cls(None, url)
        process = subprocess.Popen(
            native_viewer_command(viewer_cfg),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
            env={**os.environ, "RERUN_APP_ONLY": "true"},  # as rr.spawn: an app launch, no analytics prompt
        )
        deadline = time.monotonic() + viewer_cfg.serve_start_timeout_s
        while not _listening(port):
            if process.poll() is not None:
                raise RuntimeError(f"the rerun viewer exited with code {process.returncode} before listening")
            if time.monotonic() > deadline:
                process.kill()
                process.wait()
                raise RuntimeError(f"the rerun viewer did not listen on {LOCALHOST}:{port} in time")
            time.sleep(0.05)
        return cls(process, url)


@dataclass
class Recording:
    """The open recording stream, the web server behind ``--serve`` if any, and where the data goes (for humans)."""

    stream: rr.RecordingStream
    server: WebServer | None
    targets: list[str]

    def close(self) -> None:
        self.stream.flush()
        self.stream.disconnect()
        if self.server is not None:
            self.server.close()


def rrd_footer(choice: RrdFooter, live: bool) -> bool:
    """Whether the ``.rrd`` ends with rerun's chunk manifest, which its sink keeps in memory until the file closes:
    bounded by a video's or a dataset's length, not by a ``live`` camera's (:class:`ptam.vocabulary.RrdFooter`)."""
    return choice == RrdFooter.ALWAYS or (choice == RrdFooter.AUTO and not live)


def open_recording(
    viewer_cfg, spawn: bool = False, rrd: str | None = None, serve: bool = False, live: bool = False
) -> Recording:
    """A recording stream sent to any combination of a spawned native viewer, an ``.rrd`` file (with a footer as
    :func:`rrd_footer` decides from ``viewer.rrd_footer`` and whether the source is ``live``) and a web viewer
    served on 127.0.0.1."""
    stream = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4())
    sinks, targets, server = [], [], None
    if rrd:
        directory = os.path.dirname(os.path.abspath(rrd))
        if not os.path.isdir(directory):
            raise InputError(f"cannot write recording {rrd}: directory {directory} does not exist")
        footer = rrd_footer(viewer_cfg.rrd_footer, live)
        sinks.append(rr.FileSink(rrd, write_footer=footer))
        note = "" if footer else f" (no chunk manifest: `rerun rrd optimize {rrd} -o OUT.rrd` adds one)"
        targets.append(f"recording to {rrd}{note}")
    if serve:
        server = WebServer.start(viewer_cfg)
        sinks.append(rr.GrpcSink(server.grpc_url))
        targets.append(f"web viewer at {server.url}")
    if spawn:
        sinks.append(rr.GrpcSink(NativeViewer.start(viewer_cfg).grpc_url))
        targets.append("native viewer")
    stream.set_sinks(*sinks)
    return Recording(stream, server, targets)
