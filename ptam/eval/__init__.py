"""Trajectory evaluation: TUM trajectory files, timestamp association, ATE and RPE, rotation error, correct
fraction and glitch frames."""

from .associate import associate
from .ate import AteResult, ate
from .correctness import Correctness, Criteria, correctness
from .rpe import RpeResult, pairs_by_frames, pairs_by_time, rpe
from .tum_io import read_tum, write_tum

__all__ = [
    "read_tum",
    "write_tum",
    "associate",
    "ate",
    "AteResult",
    "Criteria",
    "Correctness",
    "correctness",
    "rpe",
    "RpeResult",
    "pairs_by_frames",
    "pairs_by_time",
]
