"""Real-time delivery of a recorded source (DESIGN.md ``realtime`` mode).

A reader thread releases frames at the source's frame rate into a one-frame slot; the consumer always
takes the newest frame, so frames that arrive while the tracker is still busy are dropped and counted —
how a live camera behaves, and how real-time claims are measured on recorded footage.
"""

from __future__ import annotations

import threading
import time


class RealtimeFeed:
    def __init__(self, source):
        self.source = source
        self.dropped = 0
        self._slot = None
        self._done = False
        self._error: BaseException | None = None
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._pump, name="ptam-realtime", daemon=True)

    def _pump(self) -> None:
        period = 1.0 / self.source.fps
        start = time.perf_counter()
        try:
            for i, frame in enumerate(self.source):
                if self._stop.is_set():
                    break
                delay = start + i * period - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
                with self._cond:
                    if self._slot is not None:
                        self.dropped += 1
                    self._slot = frame
                    self._cond.notify()
        except BaseException as e:  # re-raised in the consumer
            self._error = e
        with self._cond:
            self._done = True
            self._cond.notify()

    def __iter__(self):
        self._thread.start()
        try:
            while True:
                with self._cond:
                    while self._slot is None and not self._done:
                        self._cond.wait()
                    frame, self._slot = self._slot, None
                    done = self._done
                if frame is not None:
                    yield frame
                elif done:
                    break
            if self._error is not None:
                raise self._error
        finally:
            self._stop.set()

    def close(self, timeout_s: float = 2.0) -> None:
        """Stop the reader and wait for it, so the source is never closed under a read in progress."""
        self._stop.set()
        with self._cond:
            self._slot = None
        if self._thread.is_alive():
            self._thread.join(timeout_s)
