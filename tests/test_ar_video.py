"""Acceptance: the AR video of a two-wall run has one augmented frame per tracked frame and opens with OpenCV."""

import numpy as np
import pytest

from ptam.ar import ArLayer, attach
from ptam.camera import FovCamera, load_camera
from ptam.capture import open_dataset
from ptam.config import load_config
from ptam.errors import InputError
from ptam.system import System
from tests.support import capture, read_video, sequence

pytestmark = pytest.mark.slow  # replays a whole synthetic sequence


def test_sync_run_writes_one_augmented_frame_per_tracked_frame(tmp_path):
    d = sequence("two_wall_short")
    cfg = load_config()
    camera = load_camera(d / "camera.yaml")
    tracked, images = [], {}
    video = tmp_path / "ar.avi"
    with open_dataset(d, capture().default_fps) as src, System(camera, cfg, mode="sync") as system:
        layer = attach(system, "game", video, fps=src.fps)
        system.observers.append(lambda out, s: tracked.append(out.index) if out.T_cw is not None else None)
        for frame in src:
            images[frame.index] = frame.image
            system.process(frame)
        layer.close()
    frames = read_video(video)
    poses = len(system.trajectory)
    print(
        f"{poses} tracked frames ({len(tracked)} reported live, the others tracked once the stereo map existed), "
        f"{len(frames)} video frames; render median {np.median(layer.render_ms):.2f} ms"
    )
    assert poses >= 190 and len(frames) == poses == layer.frames_written and layer.dropped == 0
    assert frames[0].shape == (camera.height, camera.width, 3)
    # The overlay is there: the eyes are colour on a grey frame, and the video differs from the frame.
    first = frames[0].astype(np.int16)
    grey = images[0].astype(np.int16)  # the first keyframe is the first frame
    colour = np.abs(first[..., 0] - first[..., 2]) > 60
    assert colour.mean() > 0.01 and np.abs(first.mean(axis=2) - grey).mean() > 5
    assert layer.latest[0] == tracked[-1]


@pytest.mark.parametrize("suffix", [".avi", ".mp4"])
def test_layer_is_drop_free_when_writing_a_video(tmp_path, suffix):
    cfg = load_config().replace(**{"ar.queue_frames": 1})
    camera = FovCamera(320, 240, 192.0, 192.0, 159.5, 119.5, 0.9)
    path = tmp_path / f"ar{suffix}"
    T_cw = np.eye(4)
    T_cw[2, 3] = 1.0  # one map unit in front of the plane, facing it
    T_cw[1, 1] = T_cw[2, 2] = -1.0
    with ArLayer(camera, cfg, "eyes", path, fps=30.0) as layer:
        for i in range(12):  # far faster than the worker renders and encodes
            layer.submit(np.full((240, 320), 8 * i, np.uint8), T_cw, i, i / 30.0)
    frames = read_video(path)
    assert len(frames) == 12 and layer.dropped == 0
    assert frames[0].shape == (240, 320, 3)


def test_bad_video_paths_are_clear_errors(tmp_path):
    cfg = load_config()
    camera = FovCamera(320, 240, 192.0, 192.0, 159.5, 119.5, 0.9)
    with pytest.raises(InputError, match=r"\.avi \(Motion-JPEG\) or \.mp4"):
        ArLayer(camera, cfg, "grid", tmp_path / "ar.mkv")
    with pytest.raises(InputError, match="does not exist"):
        ArLayer(camera, cfg, "grid", tmp_path / "missing" / "ar.avi")
