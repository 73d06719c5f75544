"""Background threads yield the CPU to the tracker (PTAM §2: tracking is the time-critical task; mapping uses
the time left over).

On two cores the tracker shares the machine with the mapper, and in ``realtime`` with the source's reader,
the stereo start, the viewer and the AR worker. With equal priority the scheduler gives each runnable thread
its share, and the tracker's 95th percentile doubled while a bundle adjustment ran (two_wall realtime: 22 ms
against 11 ms in sync). A background thread therefore raises its own niceness (``system.background_nice``):
the tracker gets a core first whenever one is contended and the background work still gets every cycle the
tracker leaves idle. Linux only, where a thread's niceness is its own; elsewhere a no-op.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading


def lower_priority(nice: int) -> None:
    """Raise the calling thread's niceness by ``nice`` (0: leave it). An unprivileged thread may always lower its
    own priority; a refusal (a sandbox without the system call) leaves it unchanged."""
    if nice <= 0 or not sys.platform.startswith("linux"):
        return
    tid = threading.get_native_id()
    with contextlib.suppress(OSError):
        os.setpriority(os.PRIO_PROCESS, tid, min(os.getpriority(os.PRIO_PROCESS, tid) + nice, 19))
