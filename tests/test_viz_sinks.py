"""Where the viewer's data goes: an .rrd file, and the web viewer served on 127.0.0.1 only."""

import socket
import warnings

import pytest
from rerun.chunk import RrdReader

from ptam.camera import camera_from_dict
from ptam.config import load_config
from ptam.errors import InputError
from ptam.viz.sinks import WebServer, open_recording, rrd_footer
from ptam.viz.viewer import Viewer
from ptam.vocabulary import RrdFooter

CAMERA = {"model": "pinhole", "width": 640, "height": 480, "fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening_addresses(port: int) -> set[str]:
    """Local addresses of TCP sockets listening on ``port`` (IPv4, from /proc/net/tcp)."""
    found = set()
    with open("/proc/net/tcp") as f:
        lines = f.read().splitlines()[1:]
    for line in lines:
        local, state = line.split()[1], line.split()[3]
        addr, p = local.split(":")
        if int(p, 16) == port and state == "0A":
            found.add(socket.inet_ntoa(bytes.fromhex(addr)[::-1]))
    return found


def test_rrd_recording_holds_the_static_layout(tmp_path):
    cfg = load_config()
    recording = open_recording(cfg.viewer, rrd=str(tmp_path / "run.rrd"))
    Viewer(recording.stream, camera_from_dict(CAMERA), cfg).close()
    recording.close()
    entities = {c.entity_path for c in RrdReader(tmp_path / "run.rrd").stream().to_chunks()}
    assert {"/world", "/world/camera/image", "/state"} <= entities
    with pytest.raises(InputError, match="does not exist"):
        open_recording(cfg.viewer, rrd=str(tmp_path / "no" / "run.rrd"))


def test_web_viewer_listens_on_localhost_only_and_reports_a_busy_port():
    grpc, web = _free_port(), _free_port()
    cfg = load_config(overrides=[f"viewer.grpc_port={grpc}", f"viewer.web_port={web}"]).viewer
    server = WebServer.start(cfg)
    try:
        assert _listening_addresses(grpc) == {"127.0.0.1"} and _listening_addresses(web) == {"127.0.0.1"}
        assert server.url.startswith(f"http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{grpc}")
        with pytest.raises(InputError, match=f"port {grpc} on 127.0.0.1 is in use"):
            WebServer.start(cfg)
    finally:
        server.close()
    assert server.process.returncode is not None and not _listening_addresses(web)


def test_a_live_recording_leaves_out_the_chunk_manifest(tmp_path):
    """rerun's footer, a manifest of every chunk, stays in the sink's memory until the file closes (measured:
    12–16 MB a minute of ptam's logging at 30 Hz): written for videos and datasets, whose length bounds it, left out for
    a live camera, whose session has no end. Both files hold the data."""
    cfg = load_config()
    readers = {}
    for name, live in (("file.rrd", False), ("live.rrd", True)):
        recording = open_recording(cfg.viewer, rrd=str(tmp_path / name), live=live)
        assert recording.targets[0].endswith("adds one)") == live
        Viewer(recording.stream, camera_from_dict(CAMERA), cfg).close()
        recording.close()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            readers[live] = RrdReader(tmp_path / name)
        assert any("no footer" in str(w.message) for w in caught) == live
        entities = {c.entity_path for c in readers[live].stream().to_chunks()}
        assert {"/world", "/world/camera/image", "/state"} <= entities
    assert readers[False].store().summary()
    with pytest.raises(RuntimeError, match="without footer"):
        readers[True].store()
    assert [rrd_footer(c, live) for c in RrdFooter for live in (False, True)] == [True, False, True, True, False, False]
