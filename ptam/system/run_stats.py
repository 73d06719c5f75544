"""What a run counts, kept in bounded memory however long it lasts (an hour of live use is ~100k frames)."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

_BIN_MS = 0.05  # histogram resolution: medians and percentiles to 0.05 ms
_MAX_MS = 2000.0  # slower frames land in the last bin


class Latency:
    """Per-frame milliseconds: exact counts in a fixed histogram (median, percentiles over the whole run) and the
    most recent ``window`` values (``np.asarray`` gives them, for plots and benches)."""

    def __init__(self, window: int):
        self._hist = np.zeros(int(_MAX_MS / _BIN_MS) + 1, np.int64)
        self._recent: deque[float] = deque(maxlen=window)
        self.count = 0

    def append(self, ms: float) -> None:
        self._hist[min(int(ms / _BIN_MS), len(self._hist) - 1)] += 1
        self._recent.append(ms)
        self.count += 1

    def __len__(self) -> int:
        return self.count

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        return np.asarray(self._recent, dtype=dtype or np.float64)

    def quantile(self, q: float) -> float:
        """The q-quantile over every frame of the run (bin centre; 0 before the first frame)."""
        if self.count == 0:
            return 0.0
        k = int(np.searchsorted(np.cumsum(self._hist), q * self.count, side="left"))
        return (k + 0.5) * _BIN_MS

    def median(self) -> float:
        return self.quantile(0.5)


@dataclass
class RunStats:
    window: int = 10_000
    frames: int = 0
    tracked: int = 0
    lost_events: int = 0
    relocalisations: int = 0  # lost -> tracking through a relocalisation (Agility §7)
    reloc_attempts: int = 0
    keyframes_requested: int = 0
    init_attempts: int = 0
    tracks_created: int = 0  # maps built by initialisation: the first track and each new one (Gauglitz §4.4)
    tracks_merged: int = 0  # ... merged into another (§5.3)
    init_failures: deque = field(default_factory=lambda: deque(maxlen=100))  # the latest reasons
    track_ms: Latency = field(init=False)

    def __post_init__(self) -> None:
        self.track_ms = Latency(self.window)
