"""The v4l2 camera source: device names, a device that does not exist, and a camera that stops mid-run
(OpenCV's VideoCapture replaced by a scripted fake, as no camera is attached in CI)."""

import cv2
import numpy as np
import pytest

from ptam.capture import open_source
from ptam.capture import v4l2 as v4l2_module
from ptam.capture.v4l2 import parse_camera
from ptam.errors import InputError
from tests.support import capture


def test_parse_camera():
    assert parse_camera("v4l2") == 0
    assert parse_camera("v4l2:1") == 1
    assert parse_camera("v4l2:/dev/video1") == "/dev/video1"
    with pytest.raises(InputError, match="unknown camera 'usb'"):
        parse_camera("usb")
    with pytest.raises(InputError, match="unknown camera device"):
        parse_camera("v4l2:front")


def test_missing_camera_cannot_be_opened():
    with pytest.raises(InputError, match=r"^cannot open camera v4l2:/dev/video99$"):
        open_source(capture(), camera="v4l2:/dev/video99")


class FakeCapture:
    """Grants 320x240 at 15 Hz whatever is asked, delivers ``frames`` BGR frames, then fails."""

    frames = 3

    def __init__(self, device, api):
        self.device, self.api = device, api
        self.requested = {}
        self.delivered = 0
        self.released = False

    def isOpened(self):
        return True

    def set(self, prop, value):
        self.requested[prop] = value
        return True

    def get(self, prop):
        return {
            cv2.CAP_PROP_FRAME_WIDTH: 320.0,
            cv2.CAP_PROP_FRAME_HEIGHT: 240.0,
            cv2.CAP_PROP_FPS: 15.0,
            cv2.CAP_PROP_POS_MSEC: 1000.0 + 66.0 * self.delivered,
        }[prop]

    def read(self):
        if self.delivered >= self.frames:
            return False, None
        self.delivered += 1
        return True, np.full((240, 320, 3), 10 * self.delivered, np.uint8)

    def release(self):
        self.released = True


def test_camera_requests_mode_and_reports_stop(monkeypatch):
    monkeypatch.setattr(v4l2_module.cv2, "VideoCapture", FakeCapture)
    src = open_source(capture(), camera="v4l2:2", size="640x480", fps=30.0)
    cap = src._cap
    assert cap.device == 2 and cap.api == cv2.CAP_V4L2
    assert cap.requested == {cv2.CAP_PROP_FRAME_WIDTH: 640, cv2.CAP_PROP_FRAME_HEIGHT: 480, cv2.CAP_PROP_FPS: 30.0}
    assert src.size == (320, 240) and src.fps == 15.0 and src.length is None
    got = []
    with pytest.raises(InputError, match=r"^camera v4l2:2 stopped delivering frames$"):
        for frame in src:
            got.append(frame)
    assert [f.index for f in got] == [0, 1, 2]
    # Driver buffer times, read after each frame arrives.
    np.testing.assert_allclose([f.timestamp for f in got], [1.066, 1.132, 1.198])
    assert [int(f.image[0, 0]) for f in got] == [10, 20, 30]
    src.close()
    assert cap.released
