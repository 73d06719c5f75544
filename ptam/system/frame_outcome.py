"""What happened to one frame, as :meth:`System.process` reports it to the caller and to observers."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..vocabulary import TrackingState

INITIALISING = TrackingState.INITIALISING


@dataclass
class FrameOutcome:
    """What happened to one frame: the state, the pose if tracked (T_cw), and the tracker's result if any.
    ``panorama_T_cw``: before any map exists, the pose tracked rotation-only in the panorama that precedes it
    (Gauglitz et al. §6), in that panorama's frame (its first keyframe at the identity), not the map's; the
    trajectory holds it moved into the map's frame once the map exists."""

    index: int
    timestamp: float
    state: TrackingState
    T_cw: np.ndarray | None
    result: object = None
    keyframe_added: bool = False
    process_ms: float = 0.0
    frame: object = None  # the capture Frame, for observers that show the image
    panorama_T_cw: np.ndarray | None = None
