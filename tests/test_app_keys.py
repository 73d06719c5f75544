"""Live-camera controls: key-driven stereo initialisation (PTAM §6.1), reset (followed by the viewer), terminal keys
and the status line (through a pseudo-terminal, so no real terminal is needed)."""

import io
import os
import termios
import uuid

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from ptam.camera import load_camera
from ptam.capture import open_dataset
from ptam.capture.keys import TerminalKeys
from ptam.commands.run_progress import CLEAR_LINE, Display
from ptam.config import load_config
from ptam.geometry import se3
from ptam.system import INITIALISING, System
from ptam.viz.viewer import Viewer
from tests.support import capture, sequence

pytestmark = pytest.mark.slow  # replays a whole synthetic sequence

FIRST, SECOND = 5, 45


def test_space_presses_take_the_two_stereo_keyframes_and_reset_starts_over(tmp_path):
    d = sequence("two_wall_short")
    camera = load_camera(d / "camera.yaml")
    with open_dataset(d, capture().default_fps) as src:
        frames = [f for f, _ in zip(src, range(SECOND + 3))]
    # The viewer drops frames when its logging thread falls behind (niced, on a loaded machine); this test reads
    # back what it logged, so its queue holds every frame.
    cfg = load_config(overrides=[f"viewer.queue_size={4 * len(frames)}"])
    system = System(camera, cfg, mode="sync", init_mode="key")
    stream = rr.RecordingStream("ptam-test", recording_id=uuid.uuid4())
    memory = stream.memory_recording()
    viewer = Viewer(stream, camera, cfg)
    system.observers.append(viewer)
    states = []
    for f in frames:
        if f.index in (FIRST, SECOND):
            system.request_keyframe()
        states.append(system.process(f).state)
    # Nothing happens before the first press; the map is built exactly at the second (auto mode would have
    # taken its second keyframe on disparity alone, at frame ~40 after starting at frame 0).
    assert not system.init_started and system.mapper.initialised
    assert states[:SECOND] == [INITIALISING] * SECOND and [s.is_tracking for s in states[SECOND:]] == [True] * 3
    snap = system.mapper.snapshot
    assert [kf.timestamp for kf in snap.keyframes] == [frames[FIRST].timestamp, frames[SECOND].timestamp]
    # Both keyframes, the frames between, three after, and (initialisation-free, Gauglitz §6) the frames before
    # the first press, tracked rotation-only in a panorama about the first keyframe's centre.
    assert len(system.trajectory) == SECOND + 3
    centre = se3.inv(snap.kf_T_cw[0])[:3, 3]
    assert all(np.allclose(T_wc[:3, 3], centre) for _, T_wc in system.trajectory[:FIRST])
    system.request_keyframe()  # ignored once a map exists
    assert system.process(frames[-1]).state.is_tracking and system.mapper.snapshot.n_keyframes == 2

    system.reset()
    assert system.state == INITIALISING and not system.mapper.initialised and system.trajectory == []
    assert system.mapper.snapshot is None
    for f in frames[:3]:  # waits for a key again
        assert system.process(f).state == INITIALISING and not system.init_started
    viewer.close(system)
    assert viewer.dropped == 0
    # The viewer follows the reset: the old map's keyframes and points are cleared, the trajectory restarts.
    (tmp_path / "run.rrd").write_bytes(memory.drain_as_bytes())
    chunks = RrdReader(tmp_path / "run.rrd").stream().to_chunks()

    def logged(entity, component):  # in logging order (row ids grow with time; frame numbers restart after reset)
        rows = [
            r
            for c in chunks
            if c.entity_path == entity and component in c.to_record_batch().schema.names
            for r in zip(
                c.to_record_batch().column("rerun.controls.RowId").to_pylist(),
                c.to_record_batch().column(component).to_pylist(),
            )
        ]
        return [v for _, v in sorted(rows)]

    assert logged("/world/keyframes", "Clear:is_recursive") == [[True]]
    points = [len(p) for p in logged("/world/points", "Points3D:positions")]
    # The path is logged in strips under world/trajectory/NNNNN; the reset clears them all, and the final path
    # (logged at close as one strip at world/trajectory) is empty.
    strips = [len(s[0]) for s in logged("/world/trajectory/00000", "LineStrips3D:strips")]
    final = [len(s[0]) for s in logged("/world/trajectory", "LineStrips3D:strips")]
    assert max(points) == snap.n_points and points[-1] == 0
    # With the frame tracked after the ignored key, and the frames tracked before the first press.
    assert max(strips) == SECOND + 4 and final == [0]
    assert logged("/world/trajectory", "Clear:is_recursive") == [[True]]


def test_terminal_keys_in_cbreak_mode_and_restored():
    master, slave = os.openpty()
    with os.fdopen(slave, "r") as tty:
        before = termios.tcgetattr(slave)
        with TerminalKeys(tty) as keys:
            assert keys.active
            assert not termios.tcgetattr(slave)[3] & (termios.ICANON | termios.ECHO)
            assert keys.read() == ""
            os.write(master, b" rq")
            assert keys.read() == " rq"
        assert termios.tcgetattr(slave) == before
    os.close(master)
    assert not TerminalKeys(io.StringIO()).active and TerminalKeys(None).read() == ""


def test_status_line_only_on_a_terminal():
    quiet = io.StringIO()
    with Display(None, 0.0, stream=quiet) as display:
        display.frame_done(lambda fps: "good")
    assert quiet.getvalue() == ""
    master, slave = os.openpty()
    with os.fdopen(slave, "w") as tty, Display(None, 0.0, stream=tty) as display:
        display.frame_done(lambda fps: f"good {fps:.0f} fps")
        display.write("ptam: a log line")
    text = b""
    while True:  # everything written, up to the terminal's end (EIO once the other side is closed)
        try:
            chunk = os.read(master, 4096)
        except OSError:
            break
        if not chunk:
            break
        text += chunk
    text = text.decode()
    os.close(master)
    assert text.startswith(CLEAR_LINE + "good") and "ptam: a log line\r\n" in text
    assert text.endswith(CLEAR_LINE)  # cleared when the run ends
    assert np.isfinite(display.fps)
