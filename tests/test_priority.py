"""Background threads lower their own priority and nobody else's (``system.background_nice``)."""

import os
import sys
import threading

from ptam.system.priority import lower_priority


def test_lower_priority_applies_to_the_calling_thread_only():
    """Linux gives each thread its own niceness; elsewhere the call leaves everything as it was."""
    seen = {}

    def worker():
        tid = threading.get_native_id()
        before = os.getpriority(os.PRIO_PROCESS, tid)
        lower_priority(10)
        seen["worker"] = (before, os.getpriority(os.PRIO_PROCESS, tid))

    main_tid = threading.get_native_id()
    main_before = os.getpriority(os.PRIO_PROCESS, main_tid)
    t = threading.Thread(target=worker)
    t.start()
    t.join()
    before, after = seen["worker"]
    assert after == (min(before + 10, 19) if sys.platform.startswith("linux") else before)
    assert os.getpriority(os.PRIO_PROCESS, main_tid) == main_before
