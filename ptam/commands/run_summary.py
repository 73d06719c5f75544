"""The end-of-run summary of ``ptam run``: what a user checks first after a run."""

from __future__ import annotations

import numpy as np


def print_summary(system, mode: str, dropped: int | None) -> None:
    s = system.stats
    snap = system.mapper.snapshot
    kfs = snap.n_keyframes if snap is not None else 0
    pts = snap.n_points if snap is not None else 0
    ms = np.asarray(s.track_ms) if s.track_ms else np.zeros(1)
    ba = system.mapper.stats
    tracked = 100.0 * s.tracked / max(s.frames, 1)
    print(f"frames {s.frames}  tracked {s.tracked} ({tracked:.1f}%)  lost events {s.lost_events}  "
          f"keyframes {kfs}  points {pts}")
    print(f"tracking ms median {np.median(ms):.1f}  p95 {np.percentile(ms, 95):.1f}  "
          f"local BA runs {len(ba['local_ba'])}  global BA runs {len(ba['global_ba'])}  mode {mode}"
          + (f"  dropped frames {dropped}" if dropped is not None else ""))
