"""An hour of viewing: the recording grows linearly with the frames (the trajectory is logged incrementally,
not re-logged whole every frame), and the native viewer ptam starts listens on 127.0.0.1 only."""

from __future__ import annotations

import socket
import uuid
from types import SimpleNamespace

import numpy as np
import rerun as rr
from rerun.chunk import RrdReader

from ptam.camera import camera_from_dict
from ptam.config import load_config
from ptam.viz import sinks
from ptam.viz.sinks import LOCALHOST, NativeViewer, native_viewer_command
from ptam.viz.viewer import Viewer
from ptam.vocabulary import TrackingState
from tests.test_viz_sinks import CAMERA, _listening_addresses

N = 400  # frames of the shorter recording; the longer one has 2N


class _System:
    """What the viewer reads from a System: a trajectory that grows by one pose per frame, no map."""

    def __init__(self):
        self.trajectory: list = []
        self.trails = None
        self.init_started = False
        self.mapper = SimpleNamespace(snapshot=None, stats={}, queue_size=lambda: 0)
        self.track_id = 0  # one track, never merged (Gauglitz §4.4)
        self.stats = SimpleNamespace(tracks_merged=0)


def _record(path, frames: int) -> tuple[int, Viewer]:
    """Size of an .rrd holding ``frames`` tracked frames (trajectory, camera pose, state, plots; no images).

    The batcher makes one chunk of every row and never flushes on a timer, so the file is the same on every run,
    and compression cannot hide repeated data (a live recording flushes a chunk every few frames)."""
    cfg = load_config(overrides=[f"viewer.queue_size={2 * N + 1}"])
    batching = rr.ChunkBatcherConfig(flush_tick=3600.0, flush_num_bytes=2**40, flush_num_rows=1)
    stream = rr.RecordingStream("ptam-test", recording_id=uuid.uuid4(), batcher_config=batching)
    stream.set_sinks(rr.FileSink(str(path)))
    viewer = Viewer(stream, camera_from_dict(CAMERA), cfg)
    system = _System()
    rng = np.random.default_rng(0)
    position = np.zeros(3)
    for i in range(frames):
        position = position + 0.01 * rng.standard_normal(3)
        T_wc = np.eye(4)
        T_wc[:3, 3] = position
        system.trajectory.append((i / 30.0, T_wc))
        outcome = SimpleNamespace(
            state=TrackingState.GOOD, index=i, timestamp=i / 30.0, frame=None, T_cw=np.linalg.inv(T_wc), result=None
        )
        viewer(outcome, system)
    viewer.close(system)
    stream.flush()
    stream.disconnect()
    assert viewer.error is None and viewer.dropped == 0
    return path.stat().st_size, viewer


def test_recording_grows_linearly_with_the_frames(tmp_path):
    s0, _ = _record(tmp_path / "0.rrd", 0)
    s1, _ = _record(tmp_path / "1.rrd", N)
    s2, _ = _record(tmp_path / "2.rrd", 2 * N)
    ratio = (s2 - s1) / (s1 - s0)
    print(f"rrd sizes: {s0} B empty, {s1} B at {N} frames, {s2} B at {2 * N}: increment ratio {ratio:.2f}")
    # Linear: the second N frames cost what the first N did (ratio 1.02 measured). Re-logging the whole path every
    # frame is quadratic: 1.30 here (the chunks' fixed overhead dilutes it), tending to 3 as N grows.
    assert 0.95 < ratio < 1.1


def test_the_whole_path_is_in_the_recording(tmp_path):
    """During the run the path is in strips (consecutive strips share a vertex); at the end it is one strip."""
    frames = 250
    _, viewer = _record(tmp_path / "run.rrd", frames)
    last: dict[str, list] = {}
    for chunk in RrdReader(tmp_path / "run.rrd").stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path.startswith("/world/trajectory") and "LineStrips3D:strips" in batch.schema.names:
            strips = [s for s in batch.column("LineStrips3D:strips").to_pylist() if s is not None]
            if strips:
                last[chunk.entity_path] = strips[-1]
    (final,) = last.pop("/world/trajectory")
    assert len(final) == frames
    pieces = [np.array(last[k][0]) for k in sorted(last)]
    assert len(pieces) == 3  # 100 vertices a strip: 0-100, 100-200, 200-249
    joined = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
    np.testing.assert_allclose(joined, np.array(final), atol=0)


def test_native_viewer_command_binds_localhost():
    cfg = load_config().viewer
    cmd = native_viewer_command(cfg)
    assert cmd[cmd.index("--bind") + 1] == LOCALHOST == "127.0.0.1"
    assert cmd[cmd.index("--port") + 1] == str(cfg.grpc_port)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_native_viewer_listens_on_localhost_only(tmp_path, monkeypatch):
    """The viewer process ptam starts, run without a window (``--serve-grpc``: the test machine has no display),
    hosts its gRPC server on 127.0.0.1 only. Its home is a temporary directory (rerun writes settings there)."""
    for var in ("HOME", "XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME"):
        monkeypatch.setenv(var, str(tmp_path))
    command = native_viewer_command
    monkeypatch.setattr(sinks, "native_viewer_command", lambda cfg: [*command(cfg), "--serve-grpc"])
    port = _free_port()
    cfg = load_config(overrides=[f"viewer.grpc_port={port}"]).viewer
    viewer = NativeViewer.start(cfg)
    try:
        assert viewer.process is not None
        assert _listening_addresses(port) == {"127.0.0.1"}
        assert viewer.grpc_url == f"rerun+http://127.0.0.1:{port}/proxy"
        again = NativeViewer.start(cfg)  # a viewer already listening is used, not started twice
        assert again.process is None and again.grpc_url == viewer.grpc_url
    finally:
        viewer.process.terminate()
        viewer.process.wait(timeout=10)
    assert not _listening_addresses(port)
