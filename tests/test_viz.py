"""The rerun viewer: a run of two_wall_short recorded into rerun's in-memory sink, read back and counted.

No display needed. The recording is parsed with rerun's own RRD reader, so the test checks what a viewer would
receive: one frustum per keyframe, the map's point count and edgelets, one trajectory vertex per tracked frame.
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
    found, edges = [], []  # per frame: points found; edgelets (found, searched)
    with open_dataset(d, capture().default_fps) as src, System(camera, cfg, mode="sync") as system:
        system.observers.append(viewer)
        for frame in src:
            out = system.process(frame)
            found.append(int(out.result.measurements.found.sum()) if out.result is not None else 0)
            r = out.result
            edges.append((r.n_edgelets_found, r.n_edgelets_attempted) if r is not None else (0, 0))
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
    return system, viewer, rows, np.array(found), np.array(edges)


def last(rows, entity, component):
    return rows[(entity, component)][-1][1]


def test_recording_matches_the_map_keyframes_and_trajectory(recorded):
    system, viewer, rows, *_ = recorded
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
    system, viewer, rows, found, _ = recorded
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


def test_map_edgelets_and_the_frames_edgelet_searches(recorded):
    """Agility §4: every good edgelet drawn in 3-D about its centre, as long as it was made (``edgelets.length_px``
    in its source keyframe); in each logged frame, the edgelets the tracker found and those it did not."""
    system, viewer, rows, _, edges = recorded
    snap, camera, cfg = system.mapper.snapshot, system.camera, load_config()
    good = snap.good_edgelet_indices
    seg = np.asarray(last(rows, "/world/edgelets", "LineStrips3D:strips"))
    assert seg.shape == (len(good), 2, 3) and len(good) > 20
    np.testing.assert_allclose(seg.mean(axis=1), snap.edgelet_centre[good], rtol=1e-6)  # float32 in the recording
    T = snap.kf_T_cw[snap.edgelet_source_kf[good]]
    ends = [camera.project(np.einsum("nij,nj->ni", T[:, :3, :3], seg[:, s]) + T[:, :3, 3]) for s in (0, 1)]
    np.testing.assert_allclose(np.linalg.norm(ends[1] - ends[0], axis=1), cfg.edgelets.length_px, rtol=0.01)
    found = dict(rows[("/world/camera/image/edgelets_found", "LineStrips2D:strips")])
    failed = dict(rows[("/world/camera/image/edgelets_failed", "LineStrips2D:strips")])
    assert np.count_nonzero(edges[:, 1]) > 20 and edges[:, 0].max() > 20  # frames that searched edgelets
    shown = [f for f in found if edges[f, 1] > 0]  # of those, the logged ones (a loaded logger drops frames)
    assert len(shown) >= 1 and set(found) == set(failed)
    for f in shown:  # every logged frame shows exactly the tracker's edgelet searches, each 18 px long
        assert len(found[f]) == edges[f, 0] and len(failed[f]) == edges[f, 1] - edges[f, 0]
        lengths = np.linalg.norm(np.diff(np.asarray(found[f] or np.zeros((0, 2, 2))), axis=1), axis=-1)
        np.testing.assert_allclose(lengths, cfg.edgelets.length_px, rtol=1e-5)  # rerun stores float32


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
