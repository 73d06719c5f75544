"""The rerun viewer: a run of two_wall_short recorded into rerun's in-memory sink, read back and counted.

No display needed. The recording is parsed with rerun's own RRD reader, so the test checks what a viewer would
receive: one frustum per keyframe, the map's point count, one trajectory vertex per tracked frame.
"""

import uuid

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from ptam.camera import load_camera
from ptam.capture import open_dataset
from ptam.config import load_config
from ptam.system import System
from ptam.viz import map_entities as scene
from ptam.viz.viewer import Viewer
from tests.support import capture, sequence

pytestmark = pytest.mark.slow  # replays a whole synthetic sequence

FRAMES = 120


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = sequence("two_wall_short")
    cfg = load_config()
    camera = load_camera(d / "camera.yaml")
    stream = rr.RecordingStream("ptam-test", recording_id=uuid.uuid4())
    memory = stream.memory_recording()
    viewer = Viewer(stream, camera, cfg)
    found = []
    with open_dataset(d, capture().default_fps) as src, System(camera, cfg, mode="sync") as system:
        system.observers.append(viewer)
        for frame in src:
            out = system.process(frame)
            found.append(int(out.result.measurements.found.sum()) if out.result is not None else 0)
            if frame.index + 1 == FRAMES:
                break
    viewer.close(system)
    path = tmp_path_factory.mktemp("rrd") / "run.rrd"
    path.write_bytes(memory.drain_as_bytes())
    rows: dict[tuple[str, str], list] = {}  # (entity, component) -> [(frame, value)] in logging order
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        row_ids = batch.column("rerun.controls.RowId").to_pylist()  # grow with logging time
        frames = batch.column("frame").to_pylist() if "frame" in batch.schema.names else [None] * len(batch)
        for name in batch.schema.names:
            if ":" in name:
                rows.setdefault((chunk.entity_path, name), []).extend(
                    zip(row_ids, frames, batch.column(name).to_pylist())
                )
    rows = {k: [(f, v) for _, f, v in sorted(r)] for k, r in rows.items()}
    return system, viewer, rows, np.array(found)


def last(rows, entity, component):
    return rows[(entity, component)][-1][1]


def test_recording_matches_the_map_keyframes_and_trajectory(recorded):
    system, viewer, rows, _ = recorded
    snap = system.mapper.snapshot
    print(
        f"viewer: {snap.n_points} points, {snap.n_keyframes} keyframes, {len(system.trajectory)} poses; "
        f"observer in the tracker's thread: median {np.median(viewer.observe_ms) * 1e3:.0f} us, "
        f"max {np.max(viewer.observe_ms) * 1e3:.0f} us; dropped {viewer.dropped}"
    )
    assert viewer.error is None
    assert len(last(rows, "/world/points", "Points3D:positions")) == snap.n_points > 1000
    frusta = {e for (e, c) in rows if c == "Pinhole:image_from_camera" and e.startswith("/world/keyframes/")}
    assert len(frusta) == snap.n_keyframes >= 3
    thumbs = {e for (e, c) in rows if c == "Image:buffer" and e.startswith("/world/keyframes/")}
    assert thumbs == frusta
    (strip,) = last(rows, "/world/trajectory", "LineStrips3D:strips")
    assert len(strip) == len(system.trajectory) == system.stats.tracked == FRAMES
    np.testing.assert_allclose(strip[-1], system.trajectory[-1][1][:3, 3], atol=1e-6)


def test_frames_measurements_state_and_plots(recorded):
    system, viewer, rows, found = recorded
    logged = FRAMES - viewer.dropped
    assert len(rows[("/world/camera/image", "EncodedImage:blob")]) == logged
    by_frame = dict(rows[("/world/camera/image/found", "Points2D:positions")])
    for frame, n in enumerate(found):  # every logged frame shows exactly the tracker's found measurements
        if frame in by_frame:
            assert len(by_frame[frame]) == n
    assert found.max() > 500
    states = [s[0] for _, s in rows[("/state", "StateChange:state")]]
    assert states[0] == "initialising" and "good" in states
    # PTAM Fig. 4: tracking time per tracked frame, map size and keyframes per frame.
    assert len(rows[("/plots/tracking/tracking_ms", "Scalars:scalars")]) > 0.5 * logged
    assert last(rows, "/plots/map/points", "Scalars:scalars") == [system.mapper.snapshot.n_points]
    assert last(rows, "/plots/keyframes/keyframes", "Scalars:scalars") == [system.mapper.snapshot.n_keyframes]
    (grid,) = {len(v[-1][1]) for (e, c), v in rows.items() if e == "/world/grid" and c == "LineStrips3D:strips"}
    assert grid == 2 * (2 * load_config().viewer.grid_half_cells + 1)


def test_grid_and_thumbnail_intrinsics():
    lines, axis = scene.grid_lines(0.1, 10)
    assert lines.shape == (42, 2, 3) and axis.sum() == 2
    assert np.all(lines[..., 2] == 0) and np.isclose(np.abs(lines[..., :2]).max(), 1.0)
    np.testing.assert_allclose(lines[axis][:, :, :2].sum(axis=1), 0.0)  # the axis lines pass through the origin
    camera = load_camera(sequence("two_wall_short") / "camera.yaml")
    f, pp, size = scene.level_intrinsics(camera, 2)
    assert size == (camera.width // 4, camera.height // 4)
    assert np.isclose(f[0], camera.fx / 4)
    assert np.isclose(pp[0], (camera.cx + 0.5) / 4)  # level-2 pixel edges at integers in rerun's convention
