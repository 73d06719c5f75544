"""What ``ptam run`` shows on the terminal while it runs: a tqdm progress bar for sources of known length, a
status line redrawn in place otherwise (live cameras); both on stderr and only when stderr is a terminal.

The status (tracking state, frame rate, keyframes, points) rides in the bar's postfix when there is a bar, so the
two never compete for the line. While the display is open, log messages of the ``ptam`` loggers are written
through it, so they never tear the bar or the status line.
"""

from __future__ import annotations

import logging
import sys
import time

CLEAR_LINE = "\r\x1b[K"


class _Handler(logging.Handler):
    def __init__(self, display: Display, formatter):
        super().__init__()
        self.display = display
        self.setFormatter(formatter)

    def emit(self, record) -> None:
        self.display.write(self.format(record))


class Display:
    def __init__(self, length: int | None, interval_s: float, stream=None):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.length = length
        self.interval_s = interval_s
        self.bar = None
        self._line = ""
        self._last = 0.0
        self._frames = 0
        self._fps_mark = (time.perf_counter(), 0)
        self.fps = 0.0
        self._logger = logging.getLogger("ptam")
        self._saved = None

    def __enter__(self) -> Display:
        if not self.tty:
            return self
        if self.length:
            from tqdm import tqdm

            self.bar = tqdm(total=self.length, unit="frame", leave=False, dynamic_ncols=True, file=self.stream)
        root = logging.getLogger()
        formatter = root.handlers[0].formatter if root.handlers else None
        self._saved = self._logger.propagate
        self._handler = _Handler(self, formatter)
        self._logger.addHandler(self._handler)
        self._logger.propagate = False
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is not None:
            self._logger.removeHandler(self._handler)
            self._logger.propagate = self._saved
            self._saved = None
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self._line:
            self.stream.write(CLEAR_LINE)
            self.stream.flush()
            self._line = ""

    def frame_done(self, status) -> None:
        """Count one frame; ``status()`` gives the status text and is called only when the display is redrawn."""
        self._frames += 1
        if not self.tty:
            return
        if self.bar is not None:
            self.bar.update(1)
        now = time.perf_counter()
        if now - self._last < self.interval_s:
            return
        t0, n0 = self._fps_mark
        self.fps = (self._frames - n0) / max(now - t0, 1e-9)
        self._fps_mark = (now, self._frames)
        self._last = now
        text = status(self.fps)
        if self.bar is not None:
            self.bar.set_postfix_str(text, refresh=False)
        else:
            self._line = text
            self.stream.write(CLEAR_LINE + text)
            self.stream.flush()

    def write(self, message: str) -> None:
        """A whole line of text above the bar or status line."""
        if self.bar is not None:
            self.bar.write(message, file=self.stream)
            return
        self.stream.write(CLEAR_LINE + message + "\n" + self._line)
        self.stream.flush()
