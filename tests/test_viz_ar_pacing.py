"""The AR view draws only what the viewer shows (issue 19: tracking time unchanged with the AR view on).

Without ``--ar-video`` the AR worker draws a frame only when the viewer wants it — at most ``viewer.ar_max_fps``
frames a second of the source's time, and none while the viewer's queue is full — while the scene still advances
every frame; with a video every frame is drawn, written and shown. The viewer's side encodes the frame in the AR
worker's thread, so its logging thread only logs it.
"""

import queue

import cv2
import numpy as np
import pytest
import rerun as rr

from ptam.ar import ArLayer
from ptam.camera import FovCamera, load_camera
from ptam.cli import main as cli_main
from ptam.config import load_config
from ptam.viz.augmented import ArFrame, AugmentedView, FramePacer
from ptam.viz.blueprint import AUGMENTED_IMAGE
from tests.test_viz_ar import FRAMES, _entity_rows, _short_sequence


def _paced(pacer, times):
    shown = []
    for i, t in enumerate(times):
        if pacer.due(t):
            pacer.take(t)
            shown.append(i)
    return shown


def test_pacer_keeps_every_other_frame_of_a_jittery_30hz_source_at_15():
    rng = np.random.default_rng(0)
    times = 100.0 + np.arange(90) / 30.0 + rng.uniform(-0.003, 0.003, 90)  # a live camera's clock jitter
    assert _paced(FramePacer(15.0), times) == list(range(0, 90, 2))
    assert _paced(FramePacer(0.0), times) == list(range(90))  # 0: every frame
    assert _paced(FramePacer(30.0), times) == list(range(90))


def test_pacer_never_exceeds_its_rate_and_restarts_after_a_gap_or_a_jump_back():
    times = np.arange(400) / 40.0  # 10 s at 40 Hz, shown at most 30 times a second
    shown = times[_paced(FramePacer(30.0), times)]
    per_second = np.histogram(shown, bins=np.arange(11))[0]
    assert np.all(per_second <= 31) and per_second.sum() >= 295
    pacer = FramePacer(15.0)
    assert _paced(pacer, [0.0, 1 / 30, 2 / 30]) == [0, 2]
    assert _paced(pacer, [5.0, 5.0 + 1 / 30, 5.0 + 2 / 30]) == [0, 2]  # after lost frames: at once, then paced
    assert pacer.due(1.0)  # time ran backwards (a new source): shown at once
    pacer.take(1.0)
    assert not pacer.due(1.0 + 1 / 30)


class _View:
    """An ArView that wants the frames in ``wanted``."""

    def __init__(self, wanted):
        self.wanted, self.asked, self.shown = set(wanted), [], []

    def wants(self, index, timestamp):
        self.asked.append(index)
        return index in self.wanted

    def show(self, index, timestamp, bgr):
        assert bgr.dtype == np.uint8 and bgr.shape == (240, 320, 3)
        self.shown.append(index)


def _layer_run(video=None, views=()):
    cfg = load_config()
    camera = FovCamera(320, 240, 192.0, 192.0, 159.5, 119.5, 0.9)
    T_cw = np.diag([1.0, -1.0, -1.0, 1.0])
    T_cw[2, 3] = 1.0  # one map unit above the plane, looking down at it
    layer = ArLayer(camera, cfg, "eyes", video, fps=30.0)
    layer.listeners.extend(views)
    with layer:
        for i in range(8):
            layer.submit(np.full((240, 320), 90, np.uint8), T_cw, i, i / 30)
    return layer


def test_without_a_video_only_the_frames_a_view_wants_are_drawn_but_the_scene_advances_every_frame():
    view = _View({0, 3, 6})
    layer = _layer_run(views=[view])
    assert view.asked == list(range(8)) and view.shown == [0, 3, 6]
    assert layer.frames_rendered == 3 and layer.undrawn == 5 and layer.latest[0] == 6
    assert layer.scene.frames == 8  # the eyes turned and the grid faded on every frame
    bare = _layer_run()  # no view: every frame is drawn, for ``latest``
    assert bare.frames_rendered == 8 and bare.undrawn == 0


def test_with_a_video_every_frame_is_drawn_written_and_shown(tmp_path):
    view = _View(())
    layer = _layer_run(tmp_path / "ar.avi", [view])
    assert view.asked == [] and view.shown == list(range(8))
    assert layer.frames_rendered == layer.frames_written == 8 and layer.undrawn == 0


def _view(out, **settings):
    cfg = load_config().replace(**{f"viewer.{k}": v for k, v in settings.items()})
    return AugmentedView(cfg.viewer, out, lambda: True)


def test_the_view_encodes_in_the_callers_thread_and_wants_nothing_while_the_queue_is_full():
    out = queue.Queue(maxsize=2)
    view = _view(out, ar_max_fps=15.0)
    bgr = np.zeros((48, 64, 3), np.uint8)
    bgr[10:20, 10:40] = (0, 0, 255)
    assert view.wants(0, 0.0) and not view.wants(1, 1 / 30)
    view.show(0, 0.0, bgr)
    frame = out.get_nowait()
    assert isinstance(frame, ArFrame) and (frame.index, frame.timestamp) == (0, 0.0)
    jpeg = frame.image.blob.as_arrow_array()[0].values.to_numpy()
    decoded = cv2.imdecode(jpeg, cv2.IMREAD_COLOR)
    assert decoded.shape == bgr.shape and np.abs(decoded.astype(int) - bgr).mean() < 3
    out.put_nowait("frame 1")
    out.put_nowait("frame 2")
    assert not view.wants(2, 2 / 30) and view.dropped == 1  # due, but there is no room: not drawn
    out.get_nowait()
    assert view.wants(3, 3 / 30)  # the frame after gets the slot
    view.show(3, 3 / 30, bgr)
    view.show(4, 4 / 30, bgr)  # drawn for a video: shown if there is room
    assert view.dropped == 2 and out.qsize() == 2


def test_a_lossless_view_logs_the_exact_pixels():
    out = queue.Queue()
    bgr = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
    _view(out, ar_image_lossless=True).show(7, 0.5, bgr)
    image = out.get_nowait().image
    assert isinstance(image, rr.Image)
    assert np.array_equal(image.buffer.as_arrow_array()[0].values.to_numpy(), bgr.reshape(-1))


def test_a_grey_frame_is_logged_as_a_grey_jpeg_or_as_its_exact_bgr_pixels():
    grey = np.zeros((48, 64), np.uint8)
    grey[10:20, 10:40] = 200
    out = queue.Queue()
    _view(out).show(0, 0.0, grey)
    jpeg = out.get_nowait().image.blob.as_arrow_array()[0].values.to_numpy()
    decoded = cv2.imdecode(jpeg, cv2.IMREAD_UNCHANGED)
    assert decoded.shape == grey.shape and np.abs(decoded.astype(int) - grey).mean() < 3
    _view(out, ar_image_lossless=True).show(1, 0.1, grey)
    image = out.get_nowait().image
    assert np.array_equal(image.buffer.as_arrow_array()[0].values.to_numpy(), np.repeat(grey, 3).reshape(-1))


@pytest.fixture(scope="module")
def paced_run(tmp_path_factory):
    """``ptam run --rrd --ar grid`` without --ar-video on the first frames of two_wall_short, sync."""
    data = tmp_path_factory.mktemp("ar_paced")
    _short_sequence(data)
    rrd, traj = data / "run.rrd", data / "traj.txt"
    argv = ["run", "--dataset", str(data), "--mode", "sync", "--ar", "grid", "--rrd", str(rrd)]
    argv += ["--trajectory", str(traj), "--set", f"viewer.queue_size={4 * FRAMES}"]  # room for the init burst
    assert cli_main(argv) == 0
    stamps = [float(x.split()[0]) for x in traj.read_text().splitlines() if not x.startswith("#")]
    return stamps, _entity_rows(rrd, AUGMENTED_IMAGE, "EncodedImage:blob"), load_camera(data / "camera.yaml").size


def test_a_recording_without_a_video_shows_the_ar_view_at_ar_max_fps(paced_run):
    stamps, augmented, (width, height) = paced_run
    rate = load_config().viewer.ar_max_fps
    span = stamps[-1] - stamps[0]
    print(f"{len(stamps)} tracked frames over {span:.2f} s, {len(augmented)} augmented images at most {rate:g} Hz")
    assert len(stamps) >= 0.9 * FRAMES
    assert 0.9 * rate * span <= len(augmented) <= rate * span + 1
    for _, jpeg in augmented.values():
        assert cv2.imdecode(jpeg, cv2.IMREAD_COLOR).shape == (height, width, 3)
