"""The viewer shows the augmented camera image (PTAM §7.5): ``ptam run --ar grid --rrd`` on the first frames of
two_wall_short, read back with rerun's own RRD reader and compared with the ``--ar-video`` of the same run.

Both sides are lossless here, so the comparison is exact: the viewer logs the exact BGR pixels
(``viewer.ar_image_lossless``; by default it logs JPEG like the camera image), and the video is written by
``--ar-video``'s own writer with its .avi codec swapped from Motion-JPEG (lossy: up to ~26 grey levels off at the
grid's sharp edges) to FFV1, which the same OpenCV build writes and reads back bit-exactly.
"""

import argparse
import io
import shutil
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from ptam.ar import ArLayer, video_writer
from ptam.camera import FovCamera, load_camera
from ptam.cli import main as cli_main
from ptam.commands.run import _attach_observers, _close_observers, _keys
from ptam.commands.run_progress import Display
from ptam.config import load_config
from ptam.system import System
from ptam.viz.blueprint import AUGMENTED_IMAGE, CAMERA_IMAGE
from tests.support import read_video, sequence

FRAMES = 90  # stereo initialisation completes at frame 39; every frame from the first keyframe on is tracked


def _short_sequence(directory):
    """The first FRAMES frames of two_wall_short as a TUM dataset of its own (the images are not copied)."""
    src = sequence("two_wall_short")
    shutil.copy(src / "camera.yaml", directory / "camera.yaml")
    lines = [x for x in (src / "rgb.txt").read_text().splitlines() if not x.startswith("#")][:FRAMES]
    (directory / "rgb.txt").write_text("\n".join(lines) + "\n")
    (directory / "rgb").symlink_to(src / "rgb")
    return {round(float(x.split()[0]), 6): i for i, x in enumerate(lines)}, [x.split()[1] for x in lines]


def _entity_rows(path, entity, component):
    """{frame: (time in ns, bytes of the image as a uint8 array)} of ``entity``, read back with rerun's RRD reader."""
    rows = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path != f"/{entity}" or component not in batch.schema.names:
            continue
        frames, times = batch.column("frame").to_pylist(), batch.column("time").cast("int64").to_pylist()
        cells = batch.column(component)
        for i, (f, t) in enumerate(zip(frames, times)):
            if cells[i].is_valid:
                rows[f] = (t, cells[i].values.flatten().to_numpy(zero_copy_only=False))
    return rows


@pytest.fixture(scope="module")
def ar_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ar_view")
    data = tmp / "data"
    data.mkdir()
    index_of, names = _short_sequence(data)
    rrd, video, traj = tmp / "run.rrd", tmp / "ar.avi", tmp / "traj.txt"
    argv = ["run", "--dataset", str(data), "--mode", "sync", "--ar", "grid", "--rrd", str(rrd)]
    argv += ["--ar-video", str(video), "--trajectory", str(traj), "--set", "viewer.ar_image_lossless=true"]
    # Room for every frame: the ~40 frames tracked retroactively when stereo initialisation succeeds reach the
    # viewer in one burst, which a busy machine's viewer may skip by design; this test checks content, not speed.
    argv += ["--set", f"viewer.queue_size={4 * FRAMES}"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(video_writer.FOURCC, ".avi", "FFV1")  # lossless, so the two sides compare exactly
        assert cli_main(argv) == 0
    stamps = [float(x.split()[0]) for x in traj.read_text().splitlines() if not x.startswith("#")]
    tracked = [index_of[round(t, 6)] for t in stamps]  # the video's frames, in order
    grey = {i: cv2.imread(str(data / names[i]), cv2.IMREAD_GRAYSCALE) for i in tracked}
    return dict(
        tracked=tracked,
        video=read_video(video),
        augmented=_entity_rows(rrd, AUGMENTED_IMAGE, "Image:buffer"),
        camera=_entity_rows(rrd, CAMERA_IMAGE, "EncodedImage:blob"),
        grey=grey,
    )


def test_augmented_image_is_logged_for_tracked_frames_on_the_camera_timelines(ar_run):
    tracked, augmented, camera = ar_run["tracked"], ar_run["augmented"], ar_run["camera"]
    shown = [f for f in tracked if f in augmented]
    print(f"{len(tracked)} tracked frames, {len(shown)} augmented images, {len(camera)} camera images")
    assert len(tracked) >= 0.9 * FRAMES and tracked == sorted(tracked)
    assert len(shown) >= 0.9 * len(tracked)
    assert len(camera) >= 0.9 * FRAMES  # the raw image stays, with its own entity
    both = [f for f in shown if f in camera]
    assert len(both) >= 0.5 * len(shown)
    for f in both:  # the same place on both timelines: frame index and time
        assert augmented[f][0] == camera[f][0]


def test_augmented_grid_pixels_equal_the_ar_video_frame(ar_run):
    tracked, video, augmented, grey = ar_run["tracked"], ar_run["video"], ar_run["augmented"], ar_run["grey"]
    assert len(video) == len(tracked)  # one video frame per trajectory pose
    grid_fraction = []
    for k, f in enumerate(tracked):
        if f not in augmented:
            continue
        logged = augmented[f][1].reshape(video[k].shape)  # logged as BGR
        assert video[k].shape == (*grey[f].shape, 3)
        grid = np.any(video[k] != cv2.cvtColor(grey[f], cv2.COLOR_GRAY2BGR), axis=2)  # what the overlay drew
        grid_fraction.append(grid.mean())
        assert np.array_equal(logged[grid], video[k][grid])
        assert np.array_equal(logged, video[k])
    grid_fraction = np.array(grid_fraction)
    print(
        f"grid pixels per frame: median {100 * np.median(grid_fraction):.1f} %, min {100 * grid_fraction.min():.1f} %"
    )
    assert len(grid_fraction) >= 0.9 * len(tracked)
    assert np.median(grid_fraction) > 0.02  # the grid is there, not a plain frame compared with itself


def _args(**kw):
    return argparse.Namespace(**{"ar": None, "ar_video": None, **kw})


def test_a_viewer_shows_the_configured_scene_and_ar_off_attaches_none(tmp_path):
    d = sequence("two_wall_short")
    camera = load_camera(d / "camera.yaml")
    for scene in ("eyes", "grid"):
        cfg = load_config().replace(**{"ar.scene": scene})
        recording = SimpleNamespace(stream=rr.RecordingStream("ptam-test"))
        memory = recording.stream.memory_recording()  # kept until the end: nothing is sent anywhere
        with System(camera, cfg, mode="sync") as system:
            for args, rec in ((_args(), recording), (_args(ar="off"), recording), (_args(), None)):
                viewer, ar = _attach_observers(args, cfg, system, camera, rec, 30.0)
                try:
                    if rec is not None and args.ar is None:
                        assert ar is not None and ar.scene.name == scene == ar.scene_name
                        assert ar.listeners == [viewer.augmented] and viewer.show_augmented
                    else:  # --ar off with a viewer, or no viewer and no --ar-video: no AR worker at all
                        assert ar is None
                        assert viewer is None or not viewer.show_augmented
                    assert system.observers == [o for o in (viewer, ar) if o is not None]
                finally:
                    _close_observers(system, viewer, ar)
                    system.observers.clear()
        assert len(memory.drain_as_bytes()) > 0


class _Keys:
    def __init__(self, text):
        self.text = text

    def read(self):
        text, self.text = self.text, ""
        return text


def test_live_keys_fire_in_the_game_and_switch_scenes():
    cfg = load_config()
    camera = FovCamera(320, 240, 192.0, 192.0, 159.5, 119.5, 0.9)
    T_cw = np.diag([1.0, -1.0, -1.0, 1.0])
    T_cw[2, 3] = 1.0  # one map unit above the plane, looking down at it
    display = Display(None, 0.0, stream=io.StringIO())
    layer = ArLayer(camera, cfg, "game")
    fired = []
    layer.augmenter.scene.fire = lambda: fired.append(layer.frames_rendered)
    assert _keys(_Keys("f"), None, display, layer) is False
    layer.submit(np.zeros((240, 320), np.uint8), T_cw, 0, 0.0)
    assert _keys(_Keys("aa"), None, display, layer) is False  # game -> off -> grid
    assert layer.scene_name == "grid"
    layer.submit(np.zeros((240, 320), np.uint8), T_cw, 1, 1 / 30)
    layer.close()
    assert fired == [0]  # applied by the worker before the next frame
    assert layer.scene.name == "grid" and layer.frames_rendered == 2
    assert _keys(_Keys("q"), None, display, layer) is True
