"""The ``System``: tracker and mapper as two threads (PTAM §2), stereo initialisation that never stalls the
tracker (``stereo_start``), and ``run_dataset`` for whole recorded sequences."""

from .core import INITIALISING, LOST, RELOCALISING, FrameOutcome, System, run_dataset
from .run_stats import Latency, RunStats

__all__ = ["INITIALISING", "LOST", "RELOCALISING", "FrameOutcome", "Latency", "RunStats", "System", "run_dataset"]
