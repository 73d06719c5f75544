"""Realtime delivery (DESIGN.md ``realtime`` mode): frames at the source's rate, late ones dropped and counted."""

import time

import numpy as np

from ptam.capture.frame import Frame
from ptam.capture.realtime import RealtimeFeed


class _Source:
    name = "fake"
    size = (8, 8)

    def __init__(self, n, fps):
        self.length, self.fps = n, fps

    def __iter__(self):
        for i in range(self.length):
            yield Frame(i, i / self.fps, np.zeros((8, 8), np.uint8))

    def close(self):
        pass


def test_a_fast_consumer_gets_every_frame_at_the_source_rate():
    # A camera's rate: at 200 fps a 5 ms scheduling delay (the suite's other worker busy on both cores) dropped
    # frames the consumer would have taken in time.
    feed = RealtimeFeed(_Source(20, 30.0))
    t0 = time.perf_counter()
    got = [f.index for f in feed]
    elapsed = time.perf_counter() - t0
    assert got == list(range(20)) and feed.dropped == 0
    assert elapsed >= 19 / 30.0 * 0.9  # paced, not read as fast as possible


def test_a_slow_consumer_sees_the_newest_frames_and_the_drops_are_counted():
    feed = RealtimeFeed(_Source(60, 300.0))
    got = []
    for f in feed:
        got.append(f.index)
        time.sleep(0.02)  # six frame periods per frame
    assert got == sorted(got) and got[-1] == 59
    assert feed.dropped == 60 - len(got) and feed.dropped > 30


def test_close_stops_the_reader():
    feed = RealtimeFeed(_Source(10_000, 1000.0))
    for f in feed:
        if f.index >= 3:
            break
    feed.close()
    assert not feed._thread.is_alive()
