"""Key presses from the terminal during a live run (PTAM's keyboard: space, r, q).

Only when standard input is a terminal: it is switched to cbreak mode (termios/tty; keys arrive one at a time,
unechoed, while Ctrl-C still interrupts and output keeps its line endings) and restored on exit. Reading never
waits. With any other standard input there are no keys.
"""

from __future__ import annotations

import os
import select
import termios
import tty


class TerminalKeys:
    def __init__(self, stream):
        """``stream``: normally ``sys.stdin``; ``None`` or a non-terminal gives no keys."""
        self.fd = stream.fileno() if stream is not None and stream.isatty() else None
        self._saved = None

    @property
    def active(self) -> bool:
        return self.fd is not None

    def __enter__(self) -> TerminalKeys:
        if self.fd is not None:
            self._saved = (self.fd, termios.tcgetattr(self.fd))
            tty.setcbreak(self.fd)
        return self

    def __exit__(self, *exc) -> None:
        if self._saved is not None:
            fd, attrs = self._saved
            termios.tcsetattr(fd, termios.TCSADRAIN, attrs)
            self._saved = None

    def read(self) -> str:
        """The keys pressed since the last call ('' if none), without waiting."""
        keys = []
        while self.fd is not None and select.select([self.fd], [], [], 0)[0]:
            data = os.read(self.fd, 64)
            if not data:  # end of input
                self.fd = None
                break
            keys.append(data.decode(errors="ignore"))
        return "".join(keys)
